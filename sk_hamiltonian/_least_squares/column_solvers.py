"""Column solvers: ``solve(keep, basis=None)`` of a least-squares problem, by one solver each.

``solve(keep, basis=None) -> (u, cond, rank)`` is the least-squares solution
over the columns of the boolean mask ``keep``, or over the coefficients
``basis @ u`` of those columns (``cond`` may come deferred, as a callable:
:class:`~.support.Solution` computes it when it is read); with the normal
equations a new support is a smaller solve on the same Gram matrix, not a
new assembly. The support rules of :mod:`.support` call it once per support
they try.
"""

import functools

import numpy as np

from .._sketch import DesignSketch
from .._solvers import solve_dense, solve_iterative, solve_normal, stack_blocks, warn_not_converged


def _squared_norms(A, basis=None):
    if basis is not None:
        A = _times(A, basis)
    return np.einsum("ij,ij->j", A, A)


def _times(A, basis):
    """``A @ basis`` for a dense ``A`` and a sparse ``basis``, in Fortran order."""
    return np.asfortranarray((basis.T @ A.T).T)


class CGNotConverged(Exception):
    """Conjugate gradients stopped at their cap where a fall-back is allowed."""


def column_solver(problem, solver, *, single_solve=False, many_supports=False, fall_back=False,
                  progress=None, block_progress=None, name="estimator"):
    """``solve(keep, basis=None)`` and the column norms of a problem, by one solver.

    Parameters
    ----------
    problem : LeastSquaresProblem
        The design.
    solver : {"lstsq", "normal", "iterative", "sketch"}
        How to solve (see :mod:`sk_hamiltonian._solvers` and
        :mod:`sk_hamiltonian._sketch`).
    single_solve : bool, default=False
        Whether ``solve`` will be called once only, on all columns: ``"lstsq"``
        may then factorize the design in place instead of a copy.
    many_supports : bool, default=False
        Whether ``solve`` will be called on many column sets (a threshold's
        support iterations, a threshold path): ``"lstsq"`` then reduces the
        design once to the triangle of its QR factorization, on which every
        solve and column norm is as on the design (``||A S u - b|| = ||R S u
        - Q^T b||`` up to a constant, for any column map ``S``) at the cost
        of a square system.
    fall_back : bool, default=False
        With ``"iterative"`` or ``"sketch"``: raise :class:`CGNotConverged` when conjugate
        gradients reach their cap (``solver="auto"`` then uses the normal
        equations), instead of warning.
    progress : callable, default=None
        ``progress(iteration, residual)`` for conjugate gradients.
    block_progress : callable, default=None
        ``block_progress(k, n_rows)`` after each block of the normal
        equations.
    name : str, default="estimator"
        Named in warnings.

    Returns
    -------
    solve : callable
        ``solve(keep, basis=None) -> (u, cond, rank)``: the columns of
        ``keep`` only, or the coefficients ``basis @ u`` of those columns
        (``basis`` sparse, one row per kept column).
    column_norms : callable
        ``column_norms(basis=None)``: the norms of the columns of the design,
        or of the design times ``basis`` (one row per column).
    """
    if solver in ("iterative", "sketch"):
        gram = None
        if solver == "sketch":
            gram = DesignSketch(problem.n_columns, problem.groups).add_blocks(
                problem.blocks(grouped=True)).gram()
        operator = problem.operator()

        def solve_cg(keep, basis=None):
            coef, cond, rank, converged = solve_iterative(
                operator, keep, basis=basis, progress=progress, gram=gram
            )
            if not converged and fall_back:
                raise CGNotConverged
            if not converged:
                warn_not_converged(name, solver=solver)
            return coef, cond, rank

        return solve_cg, problem.column_norms
    if solver == "lstsq":
        A, b = stack_blocks(problem.blocks(), problem.n_columns)
        if many_supports and not single_solve:
            A, b = _triangle(A, b)

        def solve_svd(keep, basis=None):
            if single_solve:
                return solve_dense(A, b)
            # solve_dense overwrites its design: a Fortran-ordered copy of the
            # kept columns.
            kept = A.T[keep].T
            return solve_dense(kept if basis is None else _times(kept, basis), b)

        return solve_svd, lambda basis=None: np.sqrt(_squared_norms(A, basis))
    gram, rhs, _ = problem.normal_equations(block_progress)
    return accumulated_solver(gram, rhs, design_residual(problem.operator(), problem.n_columns))


def design_residual(operator, n_columns):
    """The refinement callback of normal equations against the design itself.

    Parameters
    ----------
    operator : DesignOperator
        The design (``matvec``, ``rmatvec``, ``targets``).
    n_columns : int
        Its columns.

    Returns
    -------
    residual : callable
        ``residual(keep)`` returns ``refine(coef) -> A_keep^T (b - A_keep
        coef)``, what :func:`~sk_hamiltonian._solvers.normal.solve_normal`
        refines a Cholesky solution with (:func:`accumulated_solver`).
    """

    def residual(keep):
        def refine(coef):
            full = np.zeros((n_columns,) + coef.shape[1:])
            full[keep] = coef
            r = operator.targets - operator.matvec(full if full.ndim == 2 else full[:, None])
            out = operator.rmatvec(r)[keep]
            return out if coef.ndim == 2 else out[:, 0]

        return refine

    return residual


def _triangle(A, b):
    """``R`` and ``Q^T b`` from the QR factorization of ``[A | b]``, the design in Fortran order.

    ``b`` lies in the span of ``Q``, so for any ``S`` the residual of ``A S
    u - b`` has the norm of ``R_A S u - R_b``: least squares on the small
    triangle gives the same solutions, singular values and rank.
    """
    n = A.shape[1]
    R = np.linalg.qr(np.column_stack([A, b]), mode="r")
    return np.asfortranarray(R[:, :n]), R[:, n] if b.ndim == 1 else R[:, n:]


def accumulated_solver(gram, rhs, residual=None):
    """``solve(keep, basis=None)`` and the column norms from normal equations.

    Parameters
    ----------
    gram, rhs : ndarray
        ``A^T A`` and ``A^T b``.
    residual : callable, default=None
        ``residual(keep)`` returns the refinement callback of
        :func:`~sk_hamiltonian._solvers.normal.solve_normal` for the kept columns;
        None: no refinement.

    Returns
    -------
    solve, column_norms : callable
        As in :func:`column_solver`, but ``solve`` returns ``cond`` deferred:
        a callable that computes it
        (:func:`~sk_hamiltonian._solvers.normal.resolve_condition`).
    """

    # Each solve's condition number is computed only if its Solution's is
    # read: a thresholded fit reads only the last of its solves'.
    lazy = functools.partial(solve_normal, defer_condition=True)

    def solve(keep, basis=None):
        refine = None if residual is None else residual(keep)
        if basis is None:
            if keep.all():
                return lazy(gram, rhs, refine)
            return lazy(gram[np.ix_(keep, keep)], rhs[keep], refine)
        # The normal equations of A @ basis: basis^T G basis (G symmetric).
        left = basis.T @ gram[np.ix_(keep, keep)]
        reduced = basis.T @ left.T
        if refine is not None:
            inner = refine

            def refine(u):
                return basis.T @ inner(basis @ u)

        return lazy(reduced, basis.T @ rhs[keep], refine)

    def column_norms(basis=None):
        if basis is None:
            return np.sqrt(np.diag(gram))
        product = (basis.T @ gram).T
        return np.sqrt(np.asarray(basis.multiply(product).sum(axis=0)).ravel())

    return solve, column_norms
