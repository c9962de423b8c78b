"""The trajectories' verdict among sets of terms.

Several finalists of the search may keep different terms, say the exact law
and its Taylor series; the rollout score, over held-out trajectories of a
fraction of a second, rarely tells them apart. The trajectories themselves
can (:func:`judge_supports`): each set of terms is fitted to all the raw
trajectories (output error, one fit weighted by the data's own noise model,
the same for every set), and the set with the lowest Bayesian information
criterion

    BIC = RSS / c + k log N

wins, ``RSS`` the weighted sum of squared residuals, ``k`` its number of
terms, ``N`` the number of observations and ``c >= 1`` the residual variance
of the best-fitting set in units of the noise model (so that a noise model
that is too small does not make every term look needed). No fold enters it:
the same data give the same verdict whatever the folds.

The weights ``1 / sigma`` of a relative noise model depend on the states they
are taken at. Taken at each fit's own first simulation, every set would
minimise a cost of its own, and the verdict would follow the least-squares
coefficients the fits start from: on one record of a pendulum at small
angles, the same three terms started from two derivative layouts' fits
differed by 28 in the criterion, more than three terms' price. So every set
is weighed at the same states, the first set's fitted trajectories.
"""

import numpy as np

from .._trajectory_fit import (
    KeptTerms,
    TrajectoryFitError,
    fit_trajectories,
    segmented,
    split_times,
)
from ..inspection import hamiltonian_terms

# The noise model of the judgement never falls below this fraction of each
# variable's root-mean-square: below it, exact data are matched to the
# precision of the integration, and a term that improves on that has nothing
# to do with the law.
JUDGEMENT_FLOOR = 1e-5


def support_key(regressor):
    """The readable terms a fitted regressor keeps, as a set of their names."""
    return frozenset(term.text for term in hamiltonian_terms(regressor, rtol=1e-10))


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
        groups, _, _ = segmented(models[0], times, states)
    except TrajectoryFitError:
        return dict(bic=None, rss=None, n_terms=None, n_observations=0, best=None)
    n_obs = sum(int(mask.sum()) * Y.shape[2] for Y, _, mask in groups)
    n_initial = sum(Y.shape[0] * Y.shape[2] for Y, _, _ in groups)
    rss = np.full(len(models), np.inf)
    per_segment = [None] * len(models)
    reference = None
    for i, term in enumerate(terms):
        if term.reason is not None:
            continue
        result = _weighted_fit(term, term.start, groups, noise, reference)
        if result is not None and reference is None:
            # Every set is weighed at the first fitted set's trajectories
            # (refitted under them, from its own result).
            reference = result["states"]
            result = _weighted_fit(term, result["theta"], groups, noise, reference)
        if result is not None:
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


def _weighted_fit(term, start, groups, noise, weight_states):
    """One fit of :func:`~sk_hamiltonian._trajectory_fit.fit_trajectories`; None where it failed."""
    try:
        with np.errstate(all="ignore"):
            result = fit_trajectories(term.model, start, groups, n_reweights=0,
                                      first_noise=noise, weight_states=weight_states)
    except TrajectoryFitError:
        return None
    return result if np.all(np.isfinite(result["theta"])) else None


def offered_gain(segment_rss):
    """The choice's weighted residual sum less the offer's, and its standard error over segments."""
    if any(values is None for values in segment_rss) or len(segment_rss[0]) < 2:
        return np.nan, np.nan
    difference = segment_rss[0] - segment_rss[1]
    return float(difference.sum()), float(np.sqrt(difference.size) * np.std(difference, ddof=1))
