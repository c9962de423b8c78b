"""The least-squares problem of a fit: its design, the terms kept, and their solve.

Every fit of the package is ``min_c ||A c - b||``, possibly over a subspace of
the coefficients. Three parts, each replaceable on its own:

- :class:`LeastSquaresProblem`, the design of one fit in the forms the
  solvers take (row blocks, grouped blocks for a sketch, an operator, and
  its normal equations by the estimator's cheapest route);
- a *column solver* (:func:`column_solver`, :func:`accumulated_solver`):
  ``solve(keep, basis=None) -> (u, cond, rank)``, the least-squares solution
  over the columns of the boolean mask ``keep``, or over the coefficients
  ``basis @ u`` of those columns; with the normal equations a new support is a
  smaller solve on the same Gram matrix, not a new assembly;
- a *support rule* (:func:`fit_support`): every term (``threshold=0``, the
  paper's dense fit), or sequentially thresholded least squares (STLSQ) in the
  readable basis, with friction unknowns constrained to be non-negative and
  never dropped.

The STLSQ loop, for a threshold ``lambda``, works on the coefficients of the
*readable* basis (monomials and angles in the user's coordinates, see
:mod:`._space.readable`), where a formula such as ``p**2 / 2 - 9.81 cos q`` is
two terms; in the fitting (Legendre) basis the same function needs the
lower-degree companions of ``p**2`` on the box, and dropping one of them
changes the physics (``p**2`` becomes ``p**2 - c p``):

1. solve on the current support (at first, on every term);
2. scale each readable coefficient by the norm of its design column (its
   coefficient in the column-equilibrated design), and mark the terms whose
   scaled coefficient is below ``lambda`` times the largest;
3. the new support is the unmarked terms; refit on it, the coefficients of the
   fitting basis being ``to_fitting[:, support] @ u``, which touch only the
   support's lower-degree companions;
4. stop when no term is marked, or after ``STLSQ_MAX_ITER`` solves (reported
   with a warning: the last solve's support is returned with its
   coefficients).

Supports only shrink, so the loop ends after at most as many solves as there
are terms; in practice after two to five.
"""

import warnings

import numpy as np
from scipy import sparse
from sklearn.exceptions import ConvergenceWarning

from ._solvers import (
    solve_dense,
    solve_iterative,
    solve_nonnegative_tail,
    solve_normal,
    stack_blocks,
    warn_not_converged,
)
from ._sketch import DesignSketch

# Cap on the solves of one thresholded fit (each one shrinks the support).
STLSQ_MAX_ITER = 25


class LeastSquaresProblem:
    """The design of one fit, in the forms the solvers take.

    Parameters
    ----------
    blocks : callable
        ``blocks(grouped=False)``: an iterable of row blocks ``(A, b)`` of
        every column, or ``(A, b, group)`` with ``grouped=True`` (see
        ``groups``).
    operator : callable
        ``operator()``: the design as a
        :class:`~sk_hamiltonian._design_operator.DesignOperator`.
    normal_equations : callable
        ``normal_equations(progress=None) -> (A^T A, A^T b)``, by the
        estimator's cheapest route (grouped blocks, or :mod:`._factored`);
        ``progress(k, n_rows)`` after each block.
    n_columns : int
        Columns of the design (unknowns).
    n_nonnegative : int, default=0
        How many of the last unknowns are constrained to be ``>= 0``.
    groups : list of ndarray of int, default=None
        The columns of each group of ``blocks(grouped=True)``, as the sketch
        accumulates them; None: one group of every column.
    """

    def __init__(self, blocks, operator, normal_equations, n_columns, n_nonnegative=0,
                 groups=None):
        self.blocks = blocks
        self.operator = operator
        self.normal_equations = normal_equations
        self.n_columns = n_columns
        self.n_nonnegative = n_nonnegative
        self.groups = groups

    def column_norms(self, basis=None):
        """Norms of the columns of ``A`` (or ``A @ basis``), from one pass over its blocks."""
        squared = 0.0
        for A, _ in self.blocks():
            squared = squared + _squared_norms(A, basis)
        return np.sqrt(squared)


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
        How to solve (see :mod:`._solvers` and :mod:`._sketch`).
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
    gram, rhs = problem.normal_equations(block_progress)
    operator = problem.operator()

    def residual(keep):
        def refine(coef):
            full = np.zeros((problem.n_columns,) + coef.shape[1:])
            full[keep] = coef
            r = operator.targets - operator.matvec(full if full.ndim == 2 else full[:, None])
            out = operator.rmatvec(r)[keep]
            return out if coef.ndim == 2 else out[:, 0]

        return refine

    return accumulated_solver(gram, rhs, residual)


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
        :func:`~sk_hamiltonian._solvers.solve_normal` for the kept columns;
        None: no refinement.

    Returns
    -------
    solve, column_norms : callable
        As in :func:`column_solver`.
    """

    def solve(keep, basis=None):
        refine = None if residual is None else residual(keep)
        if basis is None:
            if keep.all():
                return solve_normal(gram, rhs, refine)
            return solve_normal(gram[np.ix_(keep, keep)], rhs[keep], refine)
        # The normal equations of A @ basis: basis^T G basis (G symmetric).
        left = basis.T @ gram[np.ix_(keep, keep)]
        reduced = basis.T @ left.T
        if refine is not None:
            inner = refine

            def refine(u):
                return basis.T @ inner(basis @ u)

        return solve_normal(reduced, basis.T @ rhs[keep], refine)

    def column_norms(basis=None):
        if basis is None:
            return np.sqrt(np.diag(gram))
        product = (basis.T @ gram).T
        return np.sqrt(np.asarray(basis.multiply(product).sum(axis=0)).ravel())

    return solve, column_norms


class Solution:
    """What :func:`fit_support` found.

    Attributes
    ----------
    coef : ndarray of shape (n_columns,) or (n_columns, n_targets)
        Coefficients in the fitting basis, then the friction ones.
    support : ndarray of shape (n_basis,) or (n_basis, n_targets) of bool
        Fitting-basis functions with a coefficient (per target for several).
    n_kept : int
        Fitted unknowns: kept readable terms (all terms without a threshold),
        summed over targets, plus the friction unknowns.
    cond, rank : float, int
        Of the last solve (several targets: the largest condition number, and
        the solved columns less the largest rank deficiency of any target).
    n_solved : int
        Unknowns of the last solve, the reference of ``rank``.
    n_iter : int
        Solves of the support rule (the most over targets).
    """

    def __init__(self, coef, support, n_kept, cond, rank, n_solved, n_iter):
        self.coef, self.support, self.n_kept = coef, support, n_kept
        self.cond, self.rank, self.n_solved, self.n_iter = cond, rank, n_solved, n_iter


def fit_support(solve, column_norms, n_columns, *, n_basis=None, threshold=0.0,
                readable=None, n_nonnegative=0, max_iter=STLSQ_MAX_ITER, name="estimator"):
    """Solve on every term, or on the terms sequential thresholding keeps.

    Parameters
    ----------
    solve, column_norms : callable
        From :func:`column_solver` or :func:`accumulated_solver`.
    n_columns : int
        Unknowns: the fitting-basis coefficients, then ``n_nonnegative``
        friction coefficients.
    n_basis : int, default=None
        Fitting-basis coefficients (the first columns); None:
        ``n_columns - n_nonnegative``.
    threshold : float, default=0.0
        Relative threshold ``lambda`` of the STLSQ loop (module docstring); 0
        keeps every column (one solve).
    readable : ReadableBasis, default=None
        The change to the basis the threshold acts in; needed when
        ``threshold > 0``.
    n_nonnegative : int, default=0
        Last unknowns constrained ``>= 0`` (never dropped by the threshold).
    max_iter : int, default=STLSQ_MAX_ITER
        Cap on the solves of the loop; reaching it warns.
    name : str, default="estimator"
        Named in warnings.

    Returns
    -------
    solution : Solution
    """
    n_basis = n_columns - n_nonnegative if n_basis is None else n_basis
    every = np.ones(n_columns, dtype=bool)
    if n_nonnegative:
        coef, cond, rank = solve_nonnegative_tail(solve, n_columns, n_nonnegative)
    else:
        coef, cond, rank = solve(every)
    support = np.ones((n_basis,) + coef.shape[1:], dtype=bool)
    if threshold == 0:
        return Solution(coef, support, support.sum() + n_nonnegative, cond, rank, n_columns, 1)
    to_fitting = readable.to_fitting
    padded = sparse.vstack([to_fitting, sparse.csc_array((n_nonnegative, n_basis))]).tocsc()
    norms = column_norms(padded)
    terms = readable.from_fitting @ coef[:n_basis]
    reduced = _ReducedSolve(solve, to_fitting, n_basis, n_nonnegative)
    if coef.ndim == 1:
        part = _stlsq(reduced, (terms, coef[n_basis:], cond, rank), norms, threshold,
                      max_iter, name)
        return part.solution(to_fitting, n_nonnegative)
    # Several targets (the baseline's components): each gets its own support,
    # as in SINDy. Their least-squares problems share the design but not the
    # right-hand side, so one solve per distinct support serves every target.
    parts = []
    for k in range(coef.shape[1]):
        first = (terms[:, k], coef[n_basis:, k], cond, rank)
        parts.append(_stlsq(reduced.target(k), first, norms, threshold, max_iter, name))
    solutions = [p.solution(to_fitting, n_nonnegative) for p in parts]
    n_solved = int(np.any([p.kept for p in parts], axis=0).sum())
    lost = max(s.n_solved - s.rank for s in solutions)
    return Solution(
        np.column_stack([s.coef for s in solutions]),
        np.column_stack([s.support for s in solutions]),
        sum(s.n_kept for s in solutions), max(s.cond for s in solutions),
        n_solved - lost, n_solved, max(s.n_iter for s in solutions),
    )


class _ReducedSolve:
    """Least squares over the readable terms of a mask (and the friction tail).

    The unknowns are the readable coefficients ``u`` of the kept terms and the
    friction coefficients; the fitting coefficients are ``to_fitting[:, kept] @
    u``, so only the rows of ``to_fitting`` they touch enter the solve.
    Friction coefficients stay ``>= 0`` by the active set of
    :func:`~sk_hamiltonian._solvers.solve_nonnegative_tail`.
    """

    def __init__(self, solve, to_fitting, n_basis, n_tail, target=None, cache=None):
        self._solve, self._to_fitting = solve, to_fitting
        self._n_basis, self._n_tail, self._target = n_basis, n_tail, target
        self._cache = {} if cache is None else cache

    def target(self, k):
        """The same solve, returning target ``k`` only (sharing the solves)."""
        return _ReducedSolve(self._solve, self._to_fitting, self._n_basis, self._n_tail, k,
                             self._cache)

    def __call__(self, kept):
        key = kept.tobytes()
        if key not in self._cache:
            self._cache[key] = self._compute(kept)
        terms, tail, cond, rank = self._cache[key]
        if self._target is None:
            return terms, tail, cond, rank
        return terms[:, self._target], tail[:, self._target], cond, rank

    def _compute(self, kept):
        block = self._to_fitting[:, kept]
        rows = np.zeros(self._n_basis, dtype=bool)
        rows[block.indices] = True
        terms_of = block[np.flatnonzero(rows)]
        n_terms = int(kept.sum())

        def solve_reduced(columns):
            # ``columns``: the kept terms (all True), then the active frictions.
            active = columns[n_terms:]
            basis = terms_of
            if active.any():
                basis = sparse.block_diag(
                    [terms_of, sparse.identity(int(active.sum()))], format="csc"
                )
            return self._solve(np.concatenate([rows, active]), basis)

        if not self._n_tail:
            u, cond, rank = solve_reduced(np.ones(n_terms, dtype=bool))
            return u, u[:0], cond, rank
        # Friction stays >= 0 by the same active set as the dense fit.
        u, cond, rank = solve_nonnegative_tail(solve_reduced, n_terms + self._n_tail, self._n_tail)
        return u[:n_terms], u[n_terms:], cond, rank


class _Part:
    """One target's STLSQ result in the readable basis."""

    def __init__(self, kept, terms, tail, cond, rank, n_iter):
        self.kept, self.terms, self.tail = kept, terms, tail
        self.cond, self.rank, self.n_iter = cond, rank, n_iter

    def solution(self, to_fitting, n_tail):
        block = to_fitting[:, self.kept]
        coef = np.concatenate([block @ self.terms, self.tail])
        support = np.zeros(to_fitting.shape[0], dtype=bool)
        support[block.indices] = True
        n_kept = int(self.kept.sum()) + n_tail
        return Solution(coef, support, n_kept, self.cond, self.rank, n_kept, self.n_iter)


def _stlsq(reduced, first, norms, threshold, max_iter, name):
    """The STLSQ loop for one target, from the solve on every term."""
    terms, tail, cond, rank = first
    n_basis = terms.shape[0]
    kept = np.ones(n_basis, dtype=bool)
    values = terms
    n_iter = 1
    while True:
        scaled = np.abs(values) * norms[kept]
        largest = scaled.max(initial=0.0)
        if largest == 0:
            # Nothing to compare with (the target is zero): keep the support.
            break
        small = scaled < threshold * largest
        if not small.any():
            break
        if n_iter >= max_iter:
            warnings.warn(
                f"{name}: the thresholded fit (threshold={threshold}) was still dropping "
                f"terms after {max_iter} solves; the last support is kept. Its size "
                f"({int(kept.sum())} terms) may not be final: a larger threshold "
                f"usually settles faster.",
                ConvergenceWarning,
                stacklevel=4,
            )
            break
        kept = kept.copy()
        kept[np.flatnonzero(kept)[small]] = False
        values, tail, cond, rank = reduced(kept)
        n_iter += 1
    return _Part(kept, values, tail, cond, rank, n_iter)
