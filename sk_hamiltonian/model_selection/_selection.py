"""How the search chooses: ties within standard errors, then simplicity.

Two choices, both from fold-by-fold scores of candidates on the same folds:

- :func:`pick_within` chooses among candidates that share a derivative layout
  and a fit target, by their held-out *equation error* (lower is better):
  the candidates the data cannot reject against the best tie with it
  (:func:`equation_ties`), and the one with the fewest terms wins (then the
  smaller space, then the lower mean error);
- :func:`pick_among` chooses among those winners by the rollout *score*
  (higher is better), with the rule of the search's ``selection``. Its ties
  are *paired*: two candidates are compared fold by fold, so that what every
  candidate shares on a fold (how noisy its held-out trajectories are)
  cancels. Unpaired, every finalist of the paper's noisy pendulum ties with
  every other (fold-score standard errors of 6e-5); paired, over-smoothing
  (a de-noising degree 2) and noisy derivatives (degree 8) fall 2 to 7
  standard errors behind, while the models that differ only over tens of
  seconds still tie.

Among tied finalists the ``"simplest"`` rule prefers, in this order, fewer
terms; the smoothest derivative layout (the lowest de-noising degree, finite
differences last): the fit's regressors are the layout's states, and noise
left in them biases the coefficients toward zero (errors in variables), so
of two layouts the data cannot tell apart the smoother one is less biased;
the least biased fit target (:data:`FIT_ON_ORDER`); the best mean score.
"""

import numpy as np

#: Fit targets from the least to the most biased, for the ``"simplest"`` rule:
#: the weak form's test functions average the states' noise out of both sides
#: of its equations; Simpson's rule on pairs of observed steps is exact to
#: O(dt**4) and learns ``H`` itself, but the noise of the pair's ends enters
#: both its target and its regressors; the observed steps learn the AVF map's
#: modified Hamiltonian, within O(dt**2) of it; the derivative fit inherits
#: the bias of the derivative estimate, the weakest link of a de-noising
#: polynomial.
FIT_ON_ORDER = ("weak", "simpson", "steps", "derivatives")

SELECTIONS = ("simplest", "best_score")

#: Equation errors within this fraction of the best one's tie with it. The
#: targets of an equation error are estimates (derivatives, smoothed states,
#: steps), and their bias is partly explained by any model rich enough: on an
#: anharmonic spring a dense mixed series beat the exact 3-term polynomial by
#: 4.3 % at 3 % noise and 5.5 % at 1 %, fold by fold, through the
#: derivatives' bias alone (a 4-term cosine series then won on some fold
#: splits). A difference that size says nothing of the law; twice it is the
#: margin.
RELATIVE_TIE = 0.10
#: A larger degree must lower the best equation error by this fraction (and
#: one standard error) to go on: the degrees' search is a cost, not a choice.
DEGREE_GAIN = 0.05
#: Equation errors (relative squared residuals) below this are the
#: truncation error of exact data: every candidate below it ties.
EXACT_FLOOR = 1e-10


def ties(scores, best, higher_is_better, paired):
    """Which rows of ``scores`` (candidates x folds) are within one standard error of ``best``.

    Parameters
    ----------
    scores : ndarray of shape (n_candidates, n_folds)
        Fold scores; rows with a non-finite entry never tie.
    best : int
        Row of the best candidate.
    higher_is_better : bool
        Direction of the score.
    paired : bool
        True: each row's fold-by-fold shortfall against the best, within its
        own standard error. False: each row's mean within the standard error
        of the best row's fold scores (the classical one-standard-error rule).

    Returns
    -------
    tied : ndarray of shape (n_candidates,) of bool
        The best row included.
    """
    scores = np.asarray(scores, dtype=float)
    finite = np.isfinite(scores).all(axis=1)
    sign = 1.0 if higher_is_better else -1.0
    shortfall = sign * (scores[best] - scores)
    with np.errstate(invalid="ignore"):
        mean = shortfall.mean(axis=1)
        spread = shortfall.std(axis=1) if paired else scores[best].std()
        tied = finite & (mean <= spread / np.sqrt(scores.shape[1]))
    tied[best] = finite[best]
    return tied


def _best(means, higher_is_better):
    finite = np.isfinite(means)
    if not finite.any():
        return None
    values = np.where(finite, means, -np.inf if higher_is_better else np.inf)
    return int(np.argmax(values) if higher_is_better else np.argmin(values))


def equation_ties(errors, best):
    """Which candidates the data cannot reject against ``best``, by their equation errors.

    A candidate ties unless it is worse than the best on every count: beyond
    one standard error of the best's fold errors (unpaired), beyond one
    standard error of its own paired differences with the best fold by fold,
    and beyond :data:`RELATIVE_TIE` of the best's mean error. Below
    :data:`EXACT_FLOOR` every candidate ties.

    Parameters
    ----------
    errors : ndarray of shape (n_candidates, n_folds)
        Held-out equation errors (lower is better).
    best : int
        Row of the lowest mean error.

    Returns
    -------
    tied : ndarray of shape (n_candidates,) of bool
    """
    errors = np.asarray(errors, dtype=float)
    tied = (ties(errors, best, higher_is_better=False, paired=False)
            | ties(errors, best, higher_is_better=False, paired=True))
    finite = np.isfinite(errors).all(axis=1)
    with np.errstate(invalid="ignore"):
        mean = errors.mean(axis=1)
        limit = max(mean[best] * (1 + RELATIVE_TIE), EXACT_FLOOR)
        tied |= finite & (mean <= limit)
    return tied


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
    tied = equation_ties(errors, best)
    rows = np.flatnonzero(tied)
    sizes = np.zeros(errors.shape[0]) if space_sizes is None else np.asarray(space_sizes)
    order = np.lexsort((errors[rows].mean(axis=1), sizes[rows], np.asarray(n_terms)[rows]))
    return int(rows[order[0]]), tied


def pick_among(scores, n_terms, smoothing, fit_on, selection="simplest"):
    """The final choice among the finalists' rollout scores.

    Parameters
    ----------
    scores : ndarray of shape (n_finalists, n_folds)
        Rollout scores (higher is better).
    n_terms : ndarray of shape (n_finalists,)
        Their sizes.
    smoothing : ndarray of shape (n_finalists,)
        Their de-noising degrees, ``inf`` for finite differences (lower is
        smoother).
    fit_on : sequence of str
        Their fit targets.
    selection : {"simplest", "best_score"}, default="simplest"
        ``"best_score"``: the best mean score. ``"simplest"``: among the
        finalists within one paired standard error of the best mean score,
        the fewest terms, then the smoothest layout, then the least biased
        fit target (:data:`FIT_ON_ORDER`), then the best mean score.

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
    tied = ties(scores, best, higher_is_better=True, paired=True)
    if selection == "best_score":
        return best, tied
    rows = np.flatnonzero(tied)
    rank = np.array([FIT_ON_ORDER.index(fit_on[r]) for r in rows])
    order = np.lexsort((-means[rows], rank, np.asarray(smoothing, dtype=float)[rows],
                        np.asarray(n_terms)[rows]))
    return int(rows[order[0]]), tied
