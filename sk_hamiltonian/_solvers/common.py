"""What every solver shares: equilibrated columns, a non-negative tail, the warning of lost rank.

Every solver equilibrates the columns of the design (divides each by its
norm), which removes most of the growth of the Legendre gradients with the
degree, and reports the condition number of the equilibrated design.
"""

import warnings

import numpy as np

from ..exceptions import IllConditionedWarning


def _column_norms(squared):
    norms = np.sqrt(squared)
    # An all-zero column (a basis function with no data) keeps its scale; the
    # rank deficiency is reported through ``rank``.
    norms[norms == 0] = 1.0
    return norms


def _scale(x, norms):
    return x / (norms if x.ndim == 1 else norms[:, None])


def solve_nonnegative_tail(solve, n_columns, n_tail, keep=None):
    """Least squares whose last ``n_tail`` unknowns are constrained to be ``>= 0``.

    An active-set loop for a handful of constrained unknowns (damping
    coefficients): solve without constraints; while a constrained unknown is
    negative, fix the most negative one at zero and solve again.

    Parameters
    ----------
    solve : callable
        ``solve(keep) -> (coef, cond, rank)`` for the columns selected by the
        boolean mask ``keep``.
    n_columns : int
        Number of unknowns.
    n_tail : int
        How many of the last unknowns must be non-negative.
    keep : ndarray of shape (n_columns,) of bool, default=None
        Columns to solve for (e.g. a thresholded support); the others are
        zero. None: all.

    Returns
    -------
    coef : ndarray of shape (n_columns,)
        Zero where an unknown was fixed.
    cond, rank
        Of the last solve; ``rank`` counts the unknowns fixed at zero too
        (the constraint determines them), so that a fixed damping is not
        reported as lost rank.
    """
    keep = np.ones(n_columns, dtype=bool) if keep is None else np.array(keep, dtype=bool)
    fixed = 0
    while True:
        sub, cond, rank = solve(keep)
        coef = np.zeros(n_columns)
        coef[keep] = sub
        tail = coef[n_columns - n_tail :]
        if n_tail == 0 or tail.min() >= 0:
            return coef, cond, rank + fixed
        keep[n_columns - n_tail + int(np.argmin(tail))] = False
        fixed += 1


def warn_if_ill_conditioned(cond, rank, n_terms, estimator_name):
    """Warn when the solve lost rank or digits."""
    if rank < n_terms or cond > 1e10:
        warnings.warn(
            f"{estimator_name}: the least-squares problem is ill-conditioned "
            f"(condition number {cond:.3g}, rank {rank} of {n_terms}). The data do "
            f"not determine all {n_terms} coefficients: use more or longer "
            f"trajectories spread over the domain, a tighter `domain`, or a "
            f"lower `degree`.",
            IllConditionedWarning,
            stacklevel=3,
        )
