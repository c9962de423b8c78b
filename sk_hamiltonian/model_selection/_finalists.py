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
from ._selection import pick_among

# At most this many distinct sets of terms are judged by their trajectory fits
# (the fewest terms first): each costs one fit on all the data.
MAX_JUDGED = 4
# The noise model of the judgement never falls below this fraction of each
# variable's root-mean-square: below it, exact data are matched to the
# precision of the integration, and a term that improves on that has nothing
# to do with the law.
JUDGEMENT_FLOOR = 1e-5


def smoothing(denoise):
    """Order of layouts from the smoothest: the de-noising degree, finite differences last."""
    return np.inf if denoise == "finite_difference" else float(denoise)


def support_key(regressor):
    """The readable terms a fitted regressor keeps, as a set of their names."""
    return frozenset(term.text for term in hamiltonian_terms(regressor, rtol=1e-10))


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
    judgement["terms"] = [sorted(key) for key, _ in candidates]
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
        failed), ``n_observations``, and ``best`` (index of the lowest
        criterion, the fewest terms on a tie; None if every fit failed).
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
            rss[i] = float(sum(np.sum(m) for m in result["misfit"]))
    n_terms = np.array([term.n_terms for term in terms])
    finite = np.isfinite(rss)
    if not finite.any():
        return dict(bic=rss, rss=rss, n_terms=n_terms, n_observations=n_obs, best=None)
    dof = np.maximum(n_obs - n_terms - n_initial, 1)
    scale = max(1.0, float(np.min(rss[finite] / dof[finite])))
    bic = np.where(finite, rss / scale + n_terms * np.log(n_obs), np.inf)
    best = int(np.lexsort((n_terms, bic))[0])
    return dict(bic=bic, rss=rss, n_terms=n_terms, n_observations=n_obs, best=best)
