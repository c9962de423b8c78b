"""Least-squares solvers shared by the regressors.

Both solvers equilibrate the columns of the design (divide each by its norm)
before solving, which removes most of the growth of the Legendre gradients with
the degree, and report the condition number of the equilibrated design.

``"lstsq"`` factorizes the whole design with an SVD-based LAPACK driver: the
most accurate choice, at the memory cost of the design itself. ``"normal"``
streams the design in blocks of rows and accumulates the normal equations, so
memory is ``O(n_terms**2)`` whatever the number of samples; it squares the
condition number, which is harmless while that stays well below ``1e8``.
"""

import warnings

import numpy as np
from scipy import linalg

from .exceptions import IllConditionedWarning

# Designs up to this many entries (400 MB in float64) are factorized whole.
DENSE_MAX_ENTRIES = 50_000_000


def choose_solver(solver, n_rows, n_terms):
    """Resolve ``solver="auto"`` from the size of the design."""
    if solver != "auto":
        return solver
    return "lstsq" if n_rows * n_terms <= DENSE_MAX_ENTRIES else "normal"


def solve_dense(A, b):
    """Least squares on a design held in memory.

    Parameters
    ----------
    A : ndarray of shape (n_rows, n_terms)
        Design matrix; it is overwritten.
    b : ndarray of shape (n_rows,) or (n_rows, n_targets)
        Right-hand side(s).

    Returns
    -------
    coef : ndarray of shape (n_terms,) or (n_terms, n_targets)
    cond : float
        2-norm condition number of the column-equilibrated design.
    rank : int
        Numerical rank of the equilibrated design.
    """
    norms = _column_norms(np.einsum("ij,ij->j", A, A))
    A /= norms
    # A cut-off that depends on the columns only: repeating rows (integer
    # sample weights) must not change which singular values count.
    cutoff = np.finfo(float).eps * A.shape[1]
    coef, _, rank, singular = linalg.lstsq(
        A, b, cond=cutoff, lapack_driver="gelsd", check_finite=False
    )
    cond = singular[0] / singular[-1] if singular[-1] > 0 else np.inf
    return coef / (norms if coef.ndim == 1 else norms[:, None]), float(cond), int(rank)


def normal_equations(blocks, n_terms):
    """Accumulate ``A^T A`` and ``A^T b`` over row blocks of a design.

    Parameters
    ----------
    blocks : iterable of (ndarray, ndarray)
        Pairs ``(A_k, b_k)`` of consecutive row blocks of the design and the
        right-hand side, each ``b_k`` of shape ``(n_rows_k,)`` or
        ``(n_rows_k, n_targets)``.
    n_terms : int
        Number of columns.

    Returns
    -------
    gram : ndarray of shape (n_terms, n_terms)
    rhs : ndarray of shape (n_terms,) or (n_terms, n_targets)
    """
    gram = np.zeros((n_terms, n_terms))
    rhs = None
    for A, b in blocks:
        gram += A.T @ A
        contribution = A.T @ b
        rhs = contribution if rhs is None else rhs + contribution
    return gram, rhs


def solve_normal(gram, rhs):
    """Least squares from its normal equations, by an eigen pseudo-inverse.

    Parameters
    ----------
    gram : ndarray of shape (n_terms, n_terms)
        ``A^T A``; not modified.
    rhs : ndarray of shape (n_terms,) or (n_terms, n_targets)
        ``A^T b``.

    Returns
    -------
    coef, cond, rank
        As in :func:`solve_dense`; ``cond`` is the square root of the
        condition number of the equilibrated normal matrix, that is the
        condition number of the equilibrated design.
    """
    norms = _column_norms(np.diag(gram).copy())
    gram = gram / np.outer(norms, norms)
    rhs = rhs / (norms if rhs.ndim == 1 else norms[:, None])
    eigenvalues, eigenvectors = linalg.eigh(gram, check_finite=False)
    # Pseudo-inverse with the same relative cut-off as lstsq: eigenvalues of the
    # normal matrix are squared singular values of the design.
    cutoff = eigenvalues[-1] * (np.finfo(float).eps * max(gram.shape)) ** 2
    keep = eigenvalues > cutoff
    inverse = np.zeros_like(eigenvalues)
    inverse[keep] = 1.0 / eigenvalues[keep]
    coef = eigenvectors @ ((eigenvectors.T @ rhs) * (inverse if rhs.ndim == 1 else inverse[:, None]))
    smallest = eigenvalues[0]
    cond = np.sqrt(eigenvalues[-1] / smallest) if smallest > 0 else np.inf
    coef = coef / (norms if coef.ndim == 1 else norms[:, None])
    return coef, float(cond), int(keep.sum())


def solve_streaming(blocks, n_terms):
    """Least squares through normal equations accumulated block by block.

    Memory is ``O(n_terms**2)`` whatever the number of rows. See
    :func:`normal_equations` and :func:`solve_normal`.
    """
    return solve_normal(*normal_equations(blocks, n_terms))


def solve_nonnegative_tail(solve, n_columns, n_tail):
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

    Returns
    -------
    coef : ndarray of shape (n_columns,)
        Zero where an unknown was fixed.
    cond, rank
        Of the last solve.
    """
    keep = np.ones(n_columns, dtype=bool)
    while True:
        sub, cond, rank = solve(keep)
        coef = np.zeros(n_columns)
        coef[keep] = sub
        tail = coef[n_columns - n_tail :]
        if n_tail == 0 or tail.min() >= 0:
            return coef, cond, rank
        keep[n_columns - n_tail + int(np.argmin(tail))] = False


def _column_norms(squared):
    norms = np.sqrt(squared)
    # An all-zero column (a basis function with no data) keeps its scale; the
    # rank deficiency is reported through ``rank``.
    norms[norms == 0] = 1.0
    return norms


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
