"""How the search chooses: ties by paired standard errors, then simplicity.

Two choices, both from fold-by-fold scores of candidates on the same folds:

- :func:`pick_within` chooses among candidates that share a derivative layout
  and a fit target, by their held-out *equation error* (lower is better):
  the candidates whose mean error is within one paired standard error of the
  best tie with it, and the one with the fewest terms wins (then the lower
  mean error);
- :func:`pick_among` chooses among those winners by the rollout *score*
  (higher is better), with the rule of the search's ``selection``.

A *paired* standard error compares two candidates fold by fold: what every
candidate shares on a fold (how noisy its held-out trajectories are) cancels,
so the band shows the difference the data can resolve.
"""

import numpy as np

#: Fit targets from the least to the most biased, for the ``"simplest"`` rule:
#: Simpson's rule on pairs of observed steps is exact to O(dt**4) and learns
#: ``H`` itself; the observed steps learn the AVF map's modified Hamiltonian,
#: within O(dt**2) of it; the derivative fit inherits the bias of the
#: derivative estimate, the weakest link of a de-noising polynomial.
FIT_ON_ORDER = ("simpson", "steps", "derivatives")

SELECTIONS = ("simplest", "best_score")


def paired_ties(scores, best, higher_is_better):
    """Which rows of ``scores`` (candidates x folds) are within one paired standard error of ``best``.

    Parameters
    ----------
    scores : ndarray of shape (n_candidates, n_folds)
        Fold scores; rows with a non-finite entry never tie.
    best : int
        Row of the best candidate.
    higher_is_better : bool
        Direction of the score.

    Returns
    -------
    tied : ndarray of shape (n_candidates,) of bool
        The best row included.
    """
    scores = np.asarray(scores, dtype=float)
    finite = np.isfinite(scores).all(axis=1)
    sign = 1.0 if higher_is_better else -1.0
    # Fold-by-fold shortfall of each candidate against the best.
    shortfall = sign * (scores[best] - scores)
    with np.errstate(invalid="ignore"):
        mean = shortfall.mean(axis=1)
        se = shortfall.std(axis=1) / np.sqrt(scores.shape[1])
    tied = finite & (mean <= se)
    tied[best] = finite[best]
    return tied


def _best(means, higher_is_better):
    finite = np.isfinite(means)
    if not finite.any():
        return None
    values = np.where(finite, means, -np.inf if higher_is_better else np.inf)
    return int(np.argmax(values) if higher_is_better else np.argmin(values))


def pick_within(errors, n_terms, space_sizes=None):
    """The fewest terms among the candidates tied with the lowest mean equation error.

    Parameters
    ----------
    errors : ndarray of shape (n_candidates, n_folds)
        Held-out equation errors.
    n_terms : ndarray of shape (n_candidates,)
        Terms each candidate keeps.
    space_sizes : ndarray of shape (n_candidates,), default=None
        Size of each candidate's dense space, the next tie-breaker: of two
        models with as many terms, the one from the smaller space (a
        periodic angle rather than a mixed one holding the same terms).

    Returns
    -------
    index : int or None
        None when no candidate has finite errors in every fold.
    tied : ndarray of shape (n_candidates,) of bool
    """
    errors = np.asarray(errors, dtype=float)
    best = _best(np.where(np.isfinite(errors).all(axis=1), errors.mean(axis=1), np.nan), False)
    if best is None:
        return None, np.zeros(errors.shape[0], dtype=bool)
    tied = paired_ties(errors, best, higher_is_better=False)
    rows = np.flatnonzero(tied)
    sizes = np.zeros(errors.shape[0]) if space_sizes is None else np.asarray(space_sizes)
    order = np.lexsort((errors[rows].mean(axis=1), sizes[rows], np.asarray(n_terms)[rows]))
    return int(rows[order[0]]), tied


def pick_among(scores, n_terms, fit_on, selection="simplest"):
    """The final choice among the finalists' rollout scores.

    Parameters
    ----------
    scores : ndarray of shape (n_finalists, n_folds)
        Rollout scores (higher is better).
    n_terms : ndarray of shape (n_finalists,)
        Their sizes.
    fit_on : sequence of str
        Their fit targets.
    selection : {"simplest", "best_score"}, default="simplest"
        ``"best_score"``: the best mean score. ``"simplest"``: among the
        finalists within one paired standard error of the best mean score,
        the fewest terms, then the least biased fit target
        (:data:`FIT_ON_ORDER`), then the best mean score.

    Returns
    -------
    index : int or None
        None when no finalist has finite scores in every fold.
    tied : ndarray of shape (n_finalists,) of bool
    """
    scores = np.asarray(scores, dtype=float)
    means = np.where(np.isfinite(scores).all(axis=1), scores.mean(axis=1), np.nan)
    best = _best(means, True)
    if best is None:
        return None, np.zeros(scores.shape[0], dtype=bool)
    tied = paired_ties(scores, best, higher_is_better=True)
    if selection == "best_score":
        return best, tied
    rows = np.flatnonzero(tied)
    rank = np.array([FIT_ON_ORDER.index(fit_on[r]) for r in rows])
    order = np.lexsort((-means[rows], rank, np.asarray(n_terms)[rows]))
    return int(rows[order[0]]), tied
