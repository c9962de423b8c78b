"""Laws weighed against the search's choice: its terms pruned, or ``cos q`` for a Taylor series.

The finalists are the best candidate of each derivative layout and fit
target by their equation errors; the law the data need may be none of them.
Two alternatives are built from the choice itself, fitted and scored as one
more finalist each, and weighed against it by the trajectories
(:func:`~._judgement.judge_supports`):

* :func:`prune_terms`: where the tied finalists kept different terms and the
  trajectories chose a set larger than another, the terms they disagree on
  are dropped one at a time while the criterion improves (backward
  elimination); and so are the terms an offer taken kept from the choice
  (:func:`inherited_terms`). On one record of one orbit, terms such as
  ``p**2 q**2`` are nearly collinear with powers of ``q`` (``p**2`` is a
  function of ``q`` on the orbit), and a threshold can keep them and drop a
  term of the law.
* :func:`offer_cosine_law`: a position whose Taylor series of ``-cos q``
  was kept, or an angle that kept several cosine harmonics, gets ``cos q``
  in their place.
"""

import warnings

import numpy as np
from scipy.special import comb
from sklearn.base import clone

from .._trajectory_fit import KeptTerms, split_times
from ..inspection import hamiltonian_terms
from ._degrees import search_unit
from ._judgement import judge_supports, offered_gain, support_key
from ._screen import PER_COORDINATE_DOF

# The law offered in place of a Taylor series of cos q, with as many terms, is
# taken only where it explains the trajectories better by this many standard
# errors of the difference (from its spread over the segments of the fit):
# the one-standard-error tie of the search's other stages, within which the
# choice stays. Two standard errors kept a Taylor series the data could tell
# from the law (docs/default_search.rst has the runs).
OFFER_Z = 1.0
# At most this many terms are tried for dropping (each round costs one
# trajectory fit per term).
MAX_PRUNED = 6


def named_finalist(records, finalists, chosen, space, stage, spaces, layouts, folds, **search):
    """Fit and score the named ``terms`` of ``space`` as a finalist beside ``chosen``.

    The finalist has the chosen finalist's layout, fit target and degree; its
    space is appended to ``spaces``, its record (with ``stage``) to
    ``records``, its row to ``finalists``.

    Returns
    -------
    index : int or None
        The new finalist's index into ``finalists``; None where it could not
        be fitted or scored in every fold (nothing is appended then).
    """
    found, finalist, _ = search_unit(layouts[chosen["denoise"]], folds, [space],
                                     chosen["fit_on"], [chosen["degree"]], [0.0],
                                     denoise=chosen["denoise"], rollout=True, **search)
    if finalist is None or not np.all(np.isfinite(found[finalist]["scores"])):
        return None
    record = found[finalist]
    spaces.append(space)
    record.update(space=len(spaces) - 1, stage=stage)
    records.append(record)
    finalists.append(len(records) - 1)
    return len(finalists) - 1


def kept_powers(regressor):
    """The multi-indices of a fitted regressor's kept readable terms (``terms`` rows)."""
    return regressor.powers_[KeptTerms(regressor).terms]


def disputed_terms(model, judged):
    """The terms of ``model`` that some of the ``judged`` sets do not keep.

    Only a choice that bought terms over a smaller set has any: the smallest
    has no term the criterion took without a rival.

    Parameters
    ----------
    model : HamiltonianRegressor
        The chosen finalist's fitted regressor.
    judged : list of HamiltonianRegressor
        The sets of terms the trajectories weighed.

    Returns
    -------
    candidates : list of tuple
        Multi-indices of the terms :func:`prune_terms` may drop.
    """
    current = kept_powers(model)
    sets = [set(map(tuple, kept_powers(m))) for m in judged]
    common = set.intersection(*sets)
    if len(current) <= min(map(len, sets)):
        return []
    return [row for row in map(tuple, current) if row not in common]


def inherited_terms(offer, choice, substituted):
    """The terms an offer kept from the choice it replaces, to be pruned once it is taken.

    The offer's terms other than those it put in come from the choice, where
    a threshold on the derivatives kept them beside a Taylor series; some of
    them may have served that series only, or the noise. Those that hold a
    position are returned: on an orbit ``p**2`` is a function of ``q``, so
    ``p**2 q**2`` is nearly collinear with the position's own terms, and
    relative noise kept ``p**2 q**2`` beside a separable law (a pendulum with
    a spring, ``p^2/2 - 2 cos q + q^2/2``, 200 records at 2 %: up to
    ``0.0004 p^2*q^2`` on six seeds of ten), or an odd power beside a
    tilted pendulum's (``p^2/2 - cos q - 0.3 q``: up to ``1e-4 q^3`` on two
    runs of twelve). Not returned: the kinetic terms (momenta alone), without
    which a mechanical model is none, and the ``substituted`` terms, which
    the offers with and without them settled.

    Parameters
    ----------
    offer, choice : HamiltonianRegressor
        The offer's and the choice's fitted regressors.
    substituted : list of list of int
        Multi-indices of the terms the offer put in (:func:`offer_cosine_law`):
        ``cos q_i``, and the ``q_i**2`` of an even series, offered with and
        without.

    Returns
    -------
    candidates : list of tuple
        Multi-indices of the terms :func:`prune_terms` may drop.
    """
    current = kept_powers(offer)
    before = set(map(tuple, kept_powers(choice))) - set(map(tuple, substituted))
    n_dof = current.shape[1] // 2
    keep = np.any(current[:, n_dof:] != 0, axis=1)
    return [tuple(row) for row in current[keep] if tuple(row) in before]


def prune_terms(records, finalists, choice, candidates, spaces, layouts, folds, trajectories,
                dt, noise, **search):
    """Backward elimination of the ``candidates`` among the chosen terms, by the trajectories.

    Parameters
    ----------
    records, finalists : list
        As :func:`~._finalists.choose` takes them; extended in place by the
        pruned law (stage ``"pruned"``) when one is found.
    choice : int
        The chosen finalist (index into ``finalists``).
    candidates : list of tuple
        Multi-indices of the chosen terms that may be dropped
        (:func:`disputed_terms`, :func:`inherited_terms`); none is tried when
        there are more than ``MAX_PRUNED``.
    spaces, layouts, folds, trajectories, dt, noise, **search
        As :func:`offer_cosine_law` takes them.

    Returns
    -------
    choice : int
    dropped : list of str
        The names of the dropped terms (empty when none was).
    """
    chosen = records[finalists[choice]]
    model = chosen["fitted"]
    current = kept_powers(model)
    candidates = list(candidates)
    if not candidates or len(candidates) > MAX_PRUNED:
        return choice, []
    names = {tuple(term.powers): term.text for term in hamiltonian_terms(model, rtol=1e-10)}
    Xt = layouts[chosen["denoise"]]
    dropped = []
    while candidates and len(current) > 1:
        trials = [current[[tuple(row) != drop for row in current]] for drop in candidates]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                models = [model] + [
                    clone(model).set_params(terms=rows.tolist(), threshold=0.0).fit(Xt)
                    for rows in trials]
        except (ValueError, np.linalg.LinAlgError):  # a set the space cannot fit: stop
            break
        best = judge_supports(models, trajectories, dt, noise)["best"]
        if not best:  # None or 0: every drop costs more than its term
            break
        drop = candidates.pop(best - 1)
        dropped.append(names.get(drop, str(drop)))
        model, current = models[best], trials[best - 1]
    if not dropped:
        return choice, []
    space = {**spaces[chosen["space"]], "terms": current.tolist()}
    index = named_finalist(records, finalists, chosen, space, "pruned", spaces, layouts, folds,
                           **search)
    return (choice, []) if index is None else (index, dropped)


def cosine_terms(regressor, states):
    """The chosen terms with each position's Taylor series of ``-cos q`` summed back, or None.

    A position ``q_i`` that is neither periodic nor mixed and whose kept
    even powers ``q_i**4, q_i**6, ...`` alone sum to less than zero on
    average over the observed ``states`` (a potential that softens, as
    ``-g cos q`` does) gets ``cos q_i`` in their place (and ``q_i**2``, if it
    was not kept): at small angles ``cos q``, ``q**2`` and ``q**4`` are nearly
    collinear, so a screen at a degree that holds ``q**4`` may keep the
    series where the law is ``cos q``. Where the series was kept with
    ``q**6`` (one record), ``q**4`` alone may come out with either sign:
    hence the average over the data. A hardening potential (a Duffing
    spring's, a double well's) is left as it is: its cosine would be an
    inverted pendulum held up by a spring, which at 20 % noise the spring's
    records preferred on two seeds of ten.

    A series that also keeps odd powers ``q_i**3, q_i**5, ...`` alone is the
    Taylor series about another centre: an angle read from the top, about
    ``pi`` (a torsion pendulum there, ``p^2/2 + 2 cos q + (q - pi)^2/2``,
    kept ``q, q^2, q^3, q^4``). Its powers from three up are replaced by
    ``cos q_i`` where their quartic coefficient about the mean of the
    observed ``q_i`` is negative, and ``q_i**2`` and ``q_i`` (a spring about
    that centre) are offered with and without, then left to the pruning of
    an offer taken: a tilted pendulum needs ``q`` and not ``q**2``.

    Parameters
    ----------
    regressor : HamiltonianRegressor
        Fitted.
    states : ndarray of shape (n_samples, n_states)
        The observed states, in the regressor's ``(p, q)`` order.

    Returns
    -------
    substitute : tuple or None
        ``(mixed, terms, springs, settled)``: the flags of the mixed positions
        (those already mixed and the substituted ones), the terms'
        multi-indices in the mixed space
        (:class:`~sk_hamiltonian.HamiltonianRegressor`'s ``terms``), the rows
        of the substituted positions' ``q_i**2`` (and ``q_i``, for a series
        with odd powers), offered with and without, and the rows the offers
        settle, which no pruning tries: each ``cos q_i``, and the ``q_i**2``
        of an even series; None when no position qualifies.
    """
    kept = KeptTerms(regressor)
    powers, values = regressor.powers_[kept.terms], kept.theta0
    n_states = powers.shape[1]
    mixed = np.asarray(regressor.mixed_, dtype=bool)
    free = ~(mixed | np.asarray(regressor.periodic_, dtype=bool))
    swapped = np.zeros(n_states, dtype=bool)
    springs, settled = [], []
    for i in range(n_states // 2, n_states):
        if not free[i]:
            continue
        alone = np.count_nonzero(powers, axis=1) == 1
        higher = alone & (powers[:, i] >= 3)
        odd = np.any(higher & (powers[:, i] % 2 == 1))
        if odd:
            series, spring = higher, (2, 1)
            k = powers[series, i].astype(float)
            centre = np.mean(states[:, i])
            quartic = values[series] @ (comb(k, 4) * centre ** np.maximum(k - 4, 0))
            if not quartic < 0:
                continue
        else:
            series, spring = alone & (powers[:, i] >= 4) & (powers[:, i] % 2 == 0), (2,)
            if not series.any():
                continue
            anharmonic = states[:, [i]] ** powers[series, i] @ values[series]
            if np.mean(anharmonic) >= 0:
                continue
        swapped[i] = True
        powers, values = powers[~series], values[~series]
        for code in (-1, *spring):  # cos q_i (code -1 of a mixed variable), then the spring
            row = np.zeros(n_states, dtype=powers.dtype)
            row[i] = code
            if not np.any(np.all(powers == row, axis=1)):
                powers, values = np.vstack([powers, row]), np.append(values, 0.0)
            (springs if code > 0 else settled).append(row.tolist())
        if not odd:  # offered with and without, an even series' q_i**2 is settled
            settled.append(springs[-1])
    if not swapped.any():
        return None
    return (mixed | swapped).tolist(), powers.tolist(), springs, settled


def harmonic_terms(regressor):
    """The chosen terms with each angle's cosine harmonics replaced by ``cos q``, or None.

    On an arc of a circle, ``cos q, cos 2q, cos 3q, ...`` are nearly
    collinear, as ``q**2, q**4`` and ``cos q`` are at small angles: a
    threshold may keep several harmonics where the law has one. A pendulum
    observed about its top, ``p^2/2 + 9.8 cos q`` with ``q`` within 1.3 of
    ``pi``, 4 records of 1 001 samples at 2 % noise: ``-5.46 cos 2q - 1.88
    cos 3q - 0.31 cos 4q``; the same records shifted by ``pi``, where the
    polynomial space holds the Taylor series, gave ``cos q``
    (:func:`cosine_terms`). A periodic position (not mixed) that kept two
    or more cosines alone gets ``cos q_i`` in their place; its sines and the
    other terms stay.

    Parameters
    ----------
    regressor : HamiltonianRegressor
        Fitted.

    Returns
    -------
    substitute : tuple or None
        ``(terms, substituted)``: the offer's multi-indices
        (:class:`~sk_hamiltonian.HamiltonianRegressor`'s ``terms``) and
        those of the ``cos q_i`` put in; None when no position qualifies.
    """
    powers = kept_powers(regressor)
    periodic = np.asarray(regressor.periodic_, dtype=bool) & ~np.asarray(regressor.mixed_,
                                                                          dtype=bool)
    n_states = powers.shape[1]
    substituted = []
    for i in np.flatnonzero(periodic[n_states // 2:]) + n_states // 2:
        alone = np.count_nonzero(powers, axis=1) == 1
        harmonics = alone & (powers[:, i] > 0)  # +k: cos(k q_i) of a periodic variable
        if np.count_nonzero(harmonics) < 2:
            continue
        row = np.zeros(n_states, dtype=powers.dtype)
        row[i] = 1
        powers = np.vstack([powers[~harmonics], row])
        substituted.append(row.tolist())
    return (powers.tolist(), substituted) if substituted else None


def offer_cosine_law(records, finalists, choice, spaces, layouts, folds, trajectories, dt, noise,
                     **search):
    """The chosen finalist against its terms with ``cos q`` summed back (:func:`cosine_terms`).

    Up to two degrees of freedom (``PER_COORDINATE_DOF``), where every
    position is screened as polynomial, periodic and mixed. Two laws are
    offered, with the substituted positions' ``q_i**2`` and without; where
    no position holds a Taylor series, one law with an angle's cosine
    harmonics replaced by ``cos q_i`` (:func:`harmonic_terms`). Each is
    fitted and scored as a finalist of the chosen layout, fit target and
    degree (:func:`named_finalist`, stage ``"cosine"``), then all are
    weighed with the choice by :func:`~._judgement.judge_supports`. The
    offer with the lower criterion is chosen where the criterion also prefers
    it to the choice and either it keeps fewer terms, or the choice's
    residual sum exceeds its own by ``OFFER_Z`` (one) standard errors of the
    difference over the fit's segments (:func:`~._judgement.offered_gain`,
    :func:`offer_taken`).

    Parameters
    ----------
    records, finalists : list
        As :func:`~._finalists.choose` takes them; extended in place.
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
        :func:`~._judgement.judge_supports`' verdict, with ``terms`` of each,
        ``gain`` and ``gain_se`` of the better offer and ``best`` the one
        chosen; None when nothing was offered.
    substituted : list of list of int
        Multi-indices of the terms the offers put in (empty when nothing was
        offered), for :func:`inherited_terms`.
    """
    chosen = records[finalists[choice]]
    if chosen["fitted"].n_features_in_ // 2 > PER_COORDINATE_DOF:
        # Beyond, the spaces are mixed only where the data look like angles,
        # and a chain's quartic springs (FPU) would cost an offer each search.
        return choice, None, []
    space = spaces[chosen["space"]]
    substitute = cosine_terms(chosen["fitted"], np.concatenate(split_times(trajectories, dt)[1]))
    if substitute is not None:
        mixed, terms, springs, substituted = substitute
        space = {**space, "mixed": mixed}
        offers = [terms, [row for row in terms if row not in springs]]
    elif (harmonic := harmonic_terms(chosen["fitted"])) is not None:
        offers, substituted = [harmonic[0]], harmonic[1]
    else:
        return choice, None, []
    indices = []
    for rows in offers:
        index = named_finalist(records, finalists, chosen, {**space, "terms": rows}, "cosine",
                               spaces, layouts, folds, **search)
        if index is not None:
            indices.append(index)
    if not indices:
        return choice, None, []
    models = [chosen["fitted"]] + [records[finalists[i]]["fitted"] for i in indices]
    judgement = judge_supports(models, trajectories, dt, noise)
    judgement.update(terms=[sorted(support_key(model)) for model in models], kind="cosine law")
    bic, n_terms = judgement["bic"], judgement["n_terms"]
    if bic is None or not np.isfinite(bic[1:]).any():
        judgement.update(best=0, gain=np.nan, gain_se=np.nan)
        return choice, judgement, substituted
    better = 1 + int(np.lexsort((n_terms[1:], bic[1:]))[0])
    judgement["gain"], judgement["gain_se"] = offered_gain(
        [judgement["segment_rss"][0], judgement["segment_rss"][better]])
    # With as many terms, the criterion is the residual sums, whose difference
    # on one orbit can be chance: the offer is taken only where the segments
    # show it. With fewer terms, the criterion is parsimony itself.
    if offer_taken(bic[[0, better]], n_terms[[0, better]], judgement["gain"],
                   judgement["gain_se"]):
        judgement["best"] = better
        return indices[better - 1], judgement, substituted
    judgement["best"] = 0
    return choice, judgement, substituted


def offer_taken(bic, n_terms, gain, gain_se):
    """Whether an offer is taken against the choice.

    Parameters
    ----------
    bic, n_terms : ndarray of shape (2,)
        The criterion and number of terms of the choice, then the offer.
    gain, gain_se : float
        The choice's weighted residual sum less the offer's, and its standard
        error over the fit's segments (:func:`~._judgement.offered_gain`).

    Returns
    -------
    taken : bool
        True where the criterion prefers the offer and either it keeps fewer
        terms (the criterion is then parsimony itself) or its gain exceeds
        ``OFFER_Z`` standard errors (NaN, from too few segments, never does).
    """
    return bool(bic[1] < bic[0] and (n_terms[1] < n_terms[0] or gain > OFFER_Z * gain_se))
