"""Stage 3 of the search: the choice among the finalists.

The finalists (one per derivative layout and fit target) are compared by
their rollout scores against the held-out observations
(:func:`~._selection.pick_among`). Among those the data cannot tell from the
best score, several may keep different terms, say the exact law and its
Taylor series; the rollout score, over held-out trajectories of a fraction of
a second, rarely tells them apart. The trajectories themselves can
(:func:`judge_supports`): each distinct set of terms is fitted to all the raw
trajectories (output error, one fit weighted by the data's own noise model,
the same for every set), and the set with the lowest Bayesian information
criterion

    BIC = RSS / c + k log N

wins, ``RSS`` the weighted sum of squared residuals, ``k`` its number of
terms, ``N`` the number of observations and ``c >= 1`` the residual variance
of the best-fitting set in units of the noise model (so that a noise model
that is too small does not make every term look needed). No fold enters it:
the same data give the same verdict whatever the folds.
"""

import numpy as np

from .._trajectory_fit import KeptTerms, TrajectoryFitError, fit_trajectories, segmented, split_times
from ..inspection import hamiltonian_terms
from ._degrees import search_unit
from ._screen import PER_COORDINATE_DOF
from ._selection import pick_among

# At most this many distinct sets of terms are judged by their trajectory fits
# (the fewest terms first): each costs one fit on all the data.
MAX_JUDGED = 4
# The noise model of the judgement never falls below this fraction of each
# variable's root-mean-square: below it, exact data are matched to the
# precision of the integration, and a term that improves on that has nothing
# to do with the law.
JUDGEMENT_FLOOR = 1e-5
# The law offered in place of a Taylor series of cos q is taken only where it
# explains the trajectories better by this many standard errors of the
# difference (from its spread over the segments of the fit).
OFFER_Z = 2.0


def smoothing(denoise):
    """Order of layouts from the smoothest: the de-noising degree, finite differences last."""
    return np.inf if denoise == "finite_difference" else float(denoise)


def support_key(regressor):
    """The readable terms a fitted regressor keeps, as a set of their names."""
    return frozenset(term.text for term in hamiltonian_terms(regressor, rtol=1e-10))


def decide(records, finalists, selection, spaces, layouts, folds, trajectories, dt, noise,
           **search):
    """Stage 3: :func:`choose`, then with ``"simplest"`` :func:`offer_cosine_law`.

    Marks each finalist's record ``tied`` (the offered law never is).

    Returns
    -------
    choice : int
        Index into ``finalists`` (extended by the offer).
    judgement : dict or None
        The last verdict among sets of terms, its ``kind`` ``"tied
        finalists"`` or ``"cosine law"``; None when there was none.

    Raises
    ------
    ValueError
        When every finalist's score failed in some fold.
    """
    choice, tied, judgement = choose(records, finalists, selection, trajectories, dt, noise)
    if choice is None:
        raise ValueError(
            "Every finalist's score failed in some fold: no candidate can be "
            "chosen. Inspect cv_results_ or give more data; error_score='raise' shows "
            "the first failure."
        )
    for i, flag in zip(finalists, tied):
        records[i]["tied"] = bool(flag)
    if selection == "simplest" and noise is not None:
        choice, cosine = offer_cosine_law(records, finalists, choice, spaces, layouts, folds,
                                          trajectories, dt, noise, **search)
        judgement = judgement if cosine is None else cosine
    return choice, judgement


def choose(records, finalists, selection, trajectories, dt, noise):
    """The chosen finalist: the rollout scores' choice, then the trajectories' verdict.

    Parameters
    ----------
    records : list of dict
        Every candidate's record; the finalists' hold ``scores`` and ``fitted``.
    finalists : list of int
        Rows of the finalists in ``records``.
    selection : {"simplest", "best_score"}
    trajectories : list of ndarray
        The raw trajectories (time stamps first when ``dt`` is None).
    dt : float or None
    noise : ndarray of shape (n_states, 2) or None
        The data's own noise model (:func:`~sk_hamiltonian._trajectory_fit.difference_noise_model`).

    Returns
    -------
    choice : int or None
        Index into ``finalists``.
    tied : ndarray of bool
        The finalists the rollout scores cannot tell from the best.
    judgement : dict or None
        :func:`judge_supports`' verdict, when the tied finalists keep
        different terms.
    """
    scores = np.array([records[i]["scores"] for i in finalists])
    choice, tied = pick_among(
        scores, [records[i]["n_terms"] for i in finalists],
        [smoothing(records[i]["denoise"]) for i in finalists],
        [records[i]["fit_on"] for i in finalists], selection,
    )
    if choice is None or selection != "simplest" or noise is None:
        return choice, tied, None
    # The tied finalists in the rule's order of preference, the choice first.
    order = [choice] + [j for j in np.flatnonzero(tied) if j != choice]
    representatives = {}
    for j in order:
        key = support_key(records[finalists[j]]["fitted"])
        representatives.setdefault(key, j)
    if len(representatives) < 2:
        return choice, tied, None
    candidates = sorted(representatives.items(), key=lambda item: len(item[0]))[:MAX_JUDGED]
    models = [records[finalists[j]]["fitted"] for _, j in candidates]
    judgement = judge_supports(models, trajectories, dt, noise)
    if judgement["best"] is not None:
        choice = candidates[judgement["best"]][1]
    judgement.update(terms=[sorted(key) for key, _ in candidates], kind="tied finalists")
    return choice, tied, judgement


def judge_supports(models, trajectories, dt, noise):
    """The information criterion of each model's kept terms fitted to the trajectories.

    Parameters
    ----------
    models : list of HamiltonianRegressor
        Fitted by least squares on all the data, each keeping other terms.
    trajectories : list of ndarray
    dt : float or None
    noise : ndarray of shape (n_states, 2)
        The noise model that weighs every fit.

    Returns
    -------
    judgement : dict
        ``bic``, ``rss`` and ``n_terms`` per model (``inf`` where the fit
        failed), ``n_observations``, ``best`` (index of the lowest
        criterion, the fewest terms on a tie; None if every fit failed) and
        ``segment_rss`` (per model, the weighted residual sum of each
        segment of the fit, the same segments for all; None where the fit
        failed).
    """
    times, states = split_times(trajectories, dt)
    samples = np.concatenate(states)
    floor = (JUDGEMENT_FLOOR * np.sqrt(np.mean(samples**2, axis=0))) ** 2
    noise = np.column_stack([np.maximum(noise[:, 0], floor), noise[:, 1]])
    terms = [KeptTerms(model) for model in models]
    # One segmentation for every model (the first's: the rollout scores'
    # choice), so that their fits differ only by their terms.
    try:
        groups, _ = segmented(models[0], times, states)
    except TrajectoryFitError:
        return dict(bic=None, rss=None, n_terms=None, n_observations=0, best=None)
    n_obs = sum(int(mask.sum()) * Y.shape[2] for Y, _, mask in groups)
    n_initial = sum(Y.shape[0] * Y.shape[2] for Y, _, _ in groups)
    rss = np.full(len(models), np.inf)
    per_segment = [None] * len(models)
    for i, term in enumerate(terms):
        if term.reason is not None:
            continue
        try:
            with np.errstate(all="ignore"):
                result = fit_trajectories(term.model, term.start, groups, n_reweights=0,
                                          first_noise=noise)
        except TrajectoryFitError:
            continue
        if np.all(np.isfinite(result["theta"])):
            per_segment[i] = np.concatenate([np.ravel(m) for m in result["misfit"]])
            rss[i] = float(per_segment[i].sum())
    n_terms = np.array([term.n_terms for term in terms])
    finite = np.isfinite(rss)
    if not finite.any():
        return dict(bic=rss, rss=rss, n_terms=n_terms, n_observations=n_obs, best=None,
                    segment_rss=per_segment)
    dof = np.maximum(n_obs - n_terms - n_initial, 1)
    scale = max(1.0, float(np.min(rss[finite] / dof[finite])))
    bic = np.where(finite, rss / scale + n_terms * np.log(n_obs), np.inf)
    best = int(np.lexsort((n_terms, bic))[0])
    return dict(bic=bic, rss=rss, n_terms=n_terms, n_observations=n_obs, best=best,
                segment_rss=per_segment)


def cosine_terms(regressor):
    """The chosen terms with each position's Taylor series of ``-cos q`` summed back, or None.

    A position ``q_i`` that is neither periodic nor mixed and whose kept terms
    include ``q_i**4`` alone with a negative coefficient (a potential that
    softens, as ``-g cos q`` does) gets ``cos q_i`` in place of its even
    powers ``q_i**4, q_i**6, ...`` alone (and ``q_i**2``, if it was not kept):
    at small angles ``cos q``, ``q**2`` and ``q**4`` are nearly collinear, so a
    screen at a degree that holds ``q**4`` may keep the series where the law is
    ``cos q``. A hardening quartic (a Duffing spring's, a double well's) is
    left as it is: its cosine would be an inverted pendulum held up by a
    spring, which at 20 % noise the spring's records preferred on two seeds
    of ten.

    Returns
    -------
    substitute : tuple or None
        ``(mixed, terms)``: the flags of the mixed positions (those already
        mixed and the substituted ones) and the terms' multi-indices in the
        mixed space (:class:`~sk_hamiltonian.HamiltonianRegressor`'s
        ``terms``); None when no position qualifies.
    """
    kept = KeptTerms(regressor)
    powers, values = regressor.powers_[kept.terms], kept.theta0
    n_states = powers.shape[1]
    mixed = np.asarray(regressor.mixed_, dtype=bool)
    free = ~(mixed | np.asarray(regressor.periodic_, dtype=bool))
    swapped = np.zeros(n_states, dtype=bool)
    for i in range(n_states // 2, n_states):
        alone = np.count_nonzero(powers, axis=1) == 1
        quartic = alone & (powers[:, i] == 4)
        if not (free[i] and quartic.any() and values[quartic][0] < 0):
            continue
        swapped[i] = True
        keep = ~(alone & (powers[:, i] >= 4) & (powers[:, i] % 2 == 0))
        powers, values = powers[keep], values[keep]
        for code in (-1, 2):  # cos q_i (code -1 of a mixed variable), then q_i**2
            row = np.zeros(n_states, dtype=powers.dtype)
            row[i] = code
            if not np.any(np.all(powers == row, axis=1)):
                powers, values = np.vstack([powers, row]), np.append(values, 0.0)
    if not swapped.any():
        return None
    return (mixed | swapped).tolist(), powers.tolist()


def offer_cosine_law(records, finalists, choice, spaces, layouts, folds, trajectories, dt, noise,
                     **search):
    """The chosen finalist against its terms with ``cos q`` summed back (:func:`cosine_terms`).

    Up to two degrees of freedom (``PER_COORDINATE_DOF``), where every
    position is screened as polynomial, periodic and mixed. The substitute
    is fitted and scored as a finalist of the chosen layout, fit target and
    degree, in the chosen space with those positions mixed (appended to
    ``spaces``; its record, stage ``"cosine"``, to ``records`` and
    ``finalists``), then both are weighed by :func:`judge_supports`, and the
    substitute is chosen where the criterion prefers it and the choice's
    residual sum exceeds its own by ``OFFER_Z`` standard errors of the
    difference over the fit's segments (:func:`offered_gain`).

    Parameters
    ----------
    records, finalists : list
        As :func:`choose` takes them; extended in place.
    choice : int
        The chosen finalist (index into ``finalists``).
    spaces : list of dict
        The search's model spaces; extended in place.
    layouts : dict
        Each derivative layout's key to its transformed trajectories.
    folds, trajectories, dt, noise
        As the search has them.
    **search
        ``damping``, ``domain``, ``scorer`` and ``error_score`` of
        :func:`~._degrees.search_unit`.

    Returns
    -------
    choice : int
    judgement : dict or None
        :func:`judge_supports`' verdict, with ``terms`` of both, ``gain`` and
        ``gain_se`` (:func:`offered_gain`) and ``best`` the one chosen; None
        when nothing was offered.
    """
    chosen = records[finalists[choice]]
    if chosen["fitted"].n_features_in_ // 2 > PER_COORDINATE_DOF:
        # Beyond, the spaces are mixed only where the data look like angles,
        # and a chain's quartic springs (FPU) would cost an offer each search.
        return choice, None
    substitute = cosine_terms(chosen["fitted"])
    if substitute is None:
        return choice, None
    mixed, terms = substitute
    offered = {**spaces[chosen["space"]], "mixed": mixed, "terms": terms}
    found, finalist, _ = search_unit(layouts[chosen["denoise"]], folds, [offered],
                                     chosen["fit_on"], [chosen["degree"]], [0.0],
                                     denoise=chosen["denoise"], rollout=True, **search)
    if finalist is None or not np.all(np.isfinite(found[finalist]["scores"])):
        return choice, None
    record = found[finalist]
    spaces.append(offered)
    record.update(space=len(spaces) - 1, stage="cosine")
    models = [chosen["fitted"], record["fitted"]]
    judgement = judge_supports(models, trajectories, dt, noise)
    judgement.update(terms=[sorted(support_key(model)) for model in models], kind="cosine law")
    records.append(record)
    finalists.append(len(records) - 1)
    judgement["gain"], judgement["gain_se"] = offered_gain(judgement["segment_rss"])
    # Both laws have about as many terms: the criterion is their residual
    # sums, whose difference on one orbit can be chance (one record of the
    # coupled pendula: 2.4 of 16 000, with a standard error of 1.8 over its
    # segments). The offer is taken only where the segments show it.
    if judgement["best"] == 1 and judgement["gain"] > OFFER_Z * judgement["gain_se"]:
        return len(finalists) - 1, judgement
    judgement["best"] = 0
    return choice, judgement


def offered_gain(segment_rss):
    """The choice's weighted residual sum less the offer's, and its standard error over segments."""
    if any(values is None for values in segment_rss) or len(segment_rss[0]) < 2:
        return np.nan, np.nan
    difference = segment_rss[0] - segment_rss[1]
    return float(difference.sum()), float(np.sqrt(difference.size) * np.std(difference, ddof=1))
