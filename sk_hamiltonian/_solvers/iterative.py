"""``"iterative"`` and ``"sketch"``: preconditioned conjugate gradients on the normal equations."""

import math
import warnings

import numpy as np
from scipy import linalg
from sklearn.exceptions import ConvergenceWarning

from .common import _column_norms, _scale
from .normal import _normal_condition

# Conjugate gradients: relative (preconditioned) normal-residual tolerance and
# iteration cap.
CG_RTOL = 1e-11
CG_MAX_ITER = 400



def _ritz_condition(alphas, betas):
    """Condition number of the preconditioned normal matrix from CG's coefficients (Lanczos)."""
    if not alphas:
        return 1.0
    a = np.asarray(alphas)
    b = np.asarray(betas[: len(alphas) - 1])
    diagonal = 1.0 / a
    diagonal[1:] += b / a[:-1]
    off = np.sqrt(b) / a[:-1]
    ritz = linalg.eigvalsh_tridiagonal(diagonal, off, check_finite=False)
    return float(ritz[-1] / ritz[0]) if ritz[0] > 0 else np.inf


# Shift of the unit diagonal of an equilibrated preconditioner that is not
# numerically positive definite (a sketch's Gram matrix where the design is
# rank deficient): directions of the design below sqrt(PRECONDITIONER_SHIFT)
# relative are then not preconditioned, and round-off in the null directions
# is amplified at most 1 / PRECONDITIONER_SHIFT times (to ~1e-8 relative).
PRECONDITIONER_SHIFT = np.sqrt(np.finfo(float).eps)


def _preconditioner_factor(M_eq):
    """Cholesky factor of an equilibrated preconditioner, shifted if it is singular."""
    try:
        return linalg.cho_factor(M_eq, lower=False, check_finite=False)
    except linalg.LinAlgError:
        shifted = M_eq + PRECONDITIONER_SHIFT * np.eye(M_eq.shape[0])
        return linalg.cho_factor(shifted, lower=False, check_finite=False, overwrite_a=True)


def solve_iterative(operator, keep=None, rtol=CG_RTOL, max_iter=CG_MAX_ITER, progress=None, *,
                    basis=None, gram=None):
    """Preconditioned conjugate gradients on the normal equations (CGLS).

    Parameters
    ----------
    operator : DesignOperator
        ``matvec``, ``rmatvec``, ``targets`` and ``gram_estimate``.
    keep : ndarray of shape (n_columns,) of bool, default=None
        Columns to solve for (the others are zero); None: all.
    rtol : float, default=CG_RTOL
        Stop when the preconditioned normal residual has dropped by this
        factor.
    max_iter : int, default=CG_MAX_ITER
        Iteration cap.
    progress : callable, default=None
        Called as ``progress(iteration, relative_residual)``.
    basis : sparse matrix of shape (n_kept, n_unknowns), default=None
        Solve for ``u`` with the kept columns' coefficients ``basis @ u``
        (a subspace, e.g. a thresholded support); None: for the kept
        columns' coefficients themselves.
    gram : ndarray of shape (n_columns, n_columns), default=None
        An approximation of ``A^T A`` whose Cholesky factor preconditions
        the iteration, e.g. the Gram matrix of a sketch of the design
        (:class:`~sk_hamiltonian._sketch.DesignSketch`); None: the
        operator's closed-form ``gram_estimate()``.

    Returns
    -------
    coef : ndarray of shape (n_unknowns,) or (n_unknowns, K)
        The kept columns' coefficients (or ``u``); 1-D when the operator has
        one target.
    cond : float
        Estimated condition number of the equilibrated design (an upper
        bound: preconditioner times the Ritz estimate of the preconditioned
        operator).
    rank : int
        Number of unknowns (rank is not measured).
    converged : bool
        Whether ``rtol`` was reached within ``max_iter`` iterations.
    """
    n = operator.n_columns
    keep = np.ones(n, dtype=bool) if keep is None else np.asarray(keep, dtype=bool)
    M = (operator.gram_estimate() if gram is None else gram)
    M = M[np.ix_(keep, keep)] if not np.all(keep) else M
    if basis is not None:
        M = basis.T @ (basis.T @ M).T
    norms = _column_norms(np.diag(M).copy())
    M_eq = M / np.outer(norms, norms)
    factor = _preconditioner_factor(M_eq)

    def precondition(s):
        return _scale(linalg.cho_solve(factor, _scale(s, norms), check_finite=False), norms)

    def full(x):
        out = np.zeros((n, x.shape[1]))
        out[keep] = x if basis is None else basis @ x
        return out

    def restrict(r):
        s = operator.rmatvec(r)[keep]
        return s if basis is None else basis.T @ s

    b = operator.targets
    x = np.zeros((M.shape[0], b.shape[1]))
    r = b.copy()
    s = restrict(r)
    z = precondition(s)
    p = z.copy()
    gamma = np.einsum("ik,ik->k", s, z)
    gamma0 = np.where(gamma > 0, gamma, 1.0)
    alphas, betas = [], []
    converged = bool(np.all(gamma == 0))
    for iteration in range(max_iter if not converged else 0):
        q = operator.matvec(full(p))
        qq = np.einsum("iks,iks->k", q, q)
        alpha = np.where(qq > 0, gamma / np.where(qq > 0, qq, 1.0), 0.0)
        x += alpha * p
        r -= alpha[None, :, None] * q
        s = restrict(r)
        z = precondition(s)
        gamma_new = np.einsum("ik,ik->k", s, z)
        relative = float(np.sqrt(np.max(gamma_new / gamma0)))
        beta = np.where(gamma > 0, gamma_new / np.where(gamma > 0, gamma, 1.0), 0.0)
        alphas.append(float(alpha[0]))
        betas.append(float(beta[0]))
        if progress is not None:
            progress(iteration + 1, relative)
        if relative <= rtol:
            converged = True
            break
        p = z + beta * p
        gamma = gamma_new
    cond_preconditioner = _normal_condition(M_eq, factor) ** 2
    cond = math.sqrt(cond_preconditioner * _ritz_condition(alphas, betas))
    if operator.one_target:
        x = x[:, 0]
    return x, cond, x.shape[0], converged


def warn_not_converged(estimator_name, max_iter=CG_MAX_ITER, solver="iterative"):
    """Warn when conjugate gradients stopped at the iteration cap."""
    why = ("the samples probably cover the domain unevenly, which weakens its preconditioner"
           if solver == "iterative" else
           "the design is probably too ill-conditioned for its sketch's Gram matrix "
           "(a condition number beyond about 1e7)")
    warnings.warn(
        f"{estimator_name}: solver={solver!r} did not converge in {max_iter} "
        f"iterations; {why}. Use solver='normal' (or 'auto').",
        ConvergenceWarning,
        stacklevel=3,
    )
