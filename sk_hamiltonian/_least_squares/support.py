"""Support rules: which terms a fit keeps, and their coefficients.

Every term (``threshold=0``, the paper's dense fit), or sequentially
thresholded least squares (STLSQ) in the readable basis, with friction
unknowns constrained to be non-negative and never dropped.
:class:`SupportRule` binds a rule to one model space; given a column solver
(:mod:`.column_solvers`), or the normal equations themselves
(:meth:`SupportRule.from_normal_equations`), it returns a :class:`Solution`.

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

A rule may also name its terms (``keep``, a mask of the readable basis, from
the regressors' ``terms``): the first solve is then on those terms alone, and
the loop above, if any, only drops among them.

Supports only shrink, so the loop ends after at most as many solves as there
are terms; in practice after two to five.
"""

import warnings

import numpy as np
from scipy import sparse
from sklearn.exceptions import ConvergenceWarning

from .._solvers import resolve_condition, solve_nonnegative_tail
from .column_solvers import accumulated_solver

# Cap on the solves of one thresholded fit (each one shrinks the support).
STLSQ_MAX_ITER = 25


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
        the solved columns less the largest rank deficiency of any target);
        ``cond`` is computed when first read if the solve deferred it.
    n_solved : int
        Unknowns of the last solve, the reference of ``rank``.
    n_iter : int
        Solves of the support rule (the most over targets).
    """

    def __init__(self, coef, support, n_kept, cond, rank, n_solved, n_iter):
        self.coef, self.support, self.n_kept = coef, support, n_kept
        self._cond, self.rank, self.n_solved, self.n_iter = cond, rank, n_solved, n_iter

    @property
    def cond(self):
        """The last solve's condition number (see the class docstring)."""
        self._cond = resolve_condition(self._cond)
        return self._cond


class SupportRule:
    """The support rule of one fit: its threshold over one model space's columns.

    Parameters
    ----------
    space : ModelSpace
        The basis: the first ``space.n_terms`` columns; its readable form
        (:class:`~sk_hamiltonian._space.readable.ReadableBasis`) is what the
        threshold acts on.
    n_columns : int
        Unknowns: the basis coefficients, then ``n_nonnegative`` friction
        coefficients.
    threshold : float
        ``lambda`` of the STLSQ loop; 0 keeps every term.
    n_nonnegative : int, default=0
        Last unknowns constrained ``>= 0`` (never dropped).
    name : str, default="estimator"
        Named in warnings.
    keep : ndarray of shape (space.n_terms,) of bool, default=None
        The readable terms the fit may use; None: every term.
    """

    def __init__(self, space, n_columns, threshold, n_nonnegative=0, name="estimator", keep=None):
        self.space = space
        self.n_columns = n_columns
        self.threshold = threshold
        self.n_nonnegative = n_nonnegative
        self.name = name
        self.keep = keep

    def __call__(self, solve, column_norms):
        """The :class:`Solution` of the rule over a column solver (:func:`fit_support`)."""
        space = self.space
        return fit_support(
            solve, column_norms, self.n_columns, n_basis=space.n_terms,
            threshold=self.threshold, n_nonnegative=self.n_nonnegative,
            readable=(space.readable_basis() if self.threshold or self.keep is not None
                      else None),
            name=self.name, keep=self.keep,
        )

    def from_normal_equations(self, normal_equations, residual=None):
        """The :class:`Solution` of the rule solved from ``(A^T A, A^T b[, b^T b])``.

        Parameters
        ----------
        normal_equations : tuple
            ``(gram, rhs)`` or ``(gram, rhs, btb)``, e.g. of
            :meth:`~.problem.Design.normal_equations`, or a sum of them over
            pieces of data.
        residual : callable, default=None
            ``residual(keep)``: the refinement callback against the design
            (see :func:`~.column_solvers.accumulated_solver`); None: the
            Cholesky solution as it is.

        Returns
        -------
        solution : Solution
        """
        gram, rhs = normal_equations[0], normal_equations[1]
        return self(*accumulated_solver(gram, rhs, residual))


def fit_support(solve, column_norms, n_columns, *, n_basis=None, threshold=0.0,
                readable=None, n_nonnegative=0, max_iter=STLSQ_MAX_ITER, name="estimator",
                keep=None):
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
    keep : ndarray of shape (n_basis,) of bool, default=None
        The readable terms to solve on (``readable`` needed); the threshold,
        if any, drops among them. None: every column.

    Returns
    -------
    solution : Solution
    """
    n_basis = n_columns - n_nonnegative if n_basis is None else n_basis
    if keep is not None:
        return _fit_named(solve, column_norms, readable.to_fitting, keep, threshold,
                          n_nonnegative, max_iter, name)
    every = np.ones(n_columns, dtype=bool)
    if n_nonnegative:
        coef, cond, rank = solve_nonnegative_tail(solve, n_columns, n_nonnegative)
    else:
        coef, cond, rank = solve(every)
    support = np.ones((n_basis,) + coef.shape[1:], dtype=bool)
    if threshold == 0:
        return Solution(coef, support, support.sum() + n_nonnegative, cond, rank, n_columns, 1)
    to_fitting = readable.to_fitting
    norms = _readable_norms(column_norms, to_fitting, n_nonnegative)
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


def _fit_named(solve, column_norms, to_fitting, keep, threshold, n_nonnegative, max_iter, name):
    """:func:`fit_support` on the readable terms ``keep`` only (one target)."""
    n_basis = to_fitting.shape[0]
    reduced = _ReducedSolve(solve, to_fitting, n_basis, n_nonnegative)
    keep = np.asarray(keep, dtype=bool)
    terms, tail, cond, rank = reduced(keep)
    if terms.ndim != 1:
        raise ValueError(f"{name}: named terms take one target; got {terms.shape[1]}.")
    if threshold == 0:
        return _Part(keep, terms, tail, cond, rank, 1).solution(to_fitting, n_nonnegative)
    part = _stlsq(reduced, (terms, tail, cond, rank),
                  _readable_norms(column_norms, to_fitting, n_nonnegative), threshold,
                  max_iter, name, kept=keep)
    return part.solution(to_fitting, n_nonnegative)


def _readable_norms(column_norms, to_fitting, n_nonnegative):
    """The design's column norms of the readable terms (the friction columns add none)."""
    n_basis = to_fitting.shape[0]
    padded = sparse.vstack([to_fitting, sparse.csc_array((n_nonnegative, n_basis))]).tocsc()
    return column_norms(padded)


class _ReducedSolve:
    """Least squares over the readable terms of a mask (and the friction tail).

    The unknowns are the readable coefficients ``u`` of the kept terms and the
    friction coefficients; the fitting coefficients are ``to_fitting[:, kept] @
    u``, so only the rows of ``to_fitting`` they touch enter the solve.
    Friction coefficients stay ``>= 0`` by the active set of
    :func:`~sk_hamiltonian._solvers.common.solve_nonnegative_tail`.
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


def _stlsq(reduced, first, norms, threshold, max_iter, name, kept=None):
    """The STLSQ loop for one target, from the solve on every term (or on ``kept``)."""
    terms, tail, cond, rank = first
    if kept is None:
        kept = np.ones(terms.shape[0], dtype=bool)
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
