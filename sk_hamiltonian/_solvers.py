"""Least-squares solvers shared by the regressors.

Every solver equilibrates the columns of the design (divides each by its
norm), which removes most of the growth of the Legendre gradients with the
degree, and reports the condition number of the equilibrated design.

``"lstsq"``
    Factorizes the whole design with an SVD-based LAPACK driver: the most
    accurate choice, at the memory cost of the design itself and ``O(rows *
    n_terms**2)`` work with a large constant.
``"normal"``
    Streams the design in blocks into the normal equations (an in-place BLAS
    rank-k update per block), factorizes them by Cholesky and refines the
    solution against the design, so that the result matches ``"lstsq"`` while
    the design's condition number stays below about ``1e7``; where the
    factorization fails or rank is lost it falls back to an eigen
    pseudo-inverse with ``lstsq``'s cut-off. Memory is ``O(n_terms**2)``
    whatever the number of samples; the time is one Gram matrix, the bound of
    every dense method.
``"iterative"``
    Never forms the Gram matrix: conjugate gradients on the normal equations
    (CGLS), with the design applied as an operator (:mod:`._design_operator`,
    a few times cheaper per pass than the explicit design) and preconditioned
    by the *closed-form* Gram matrix of the basis under the uniform measure on
    the box, which the empirical one approaches when the samples cover the box
    evenly (the paper's setting). The cost is a Cholesky factorization of that
    ``n_terms x n_terms`` matrix plus two operator applications per iteration.
    Its condition number is an estimate (an upper bound, from the
    preconditioner and the iteration's Ritz values).
``"sketch"``
    The same iteration, preconditioned by the Gram matrix of a random sketch
    of the design (:mod:`._sketch`): a few dozen iterations whatever the
    samples' distribution, for one pass over the design and the sketch's
    ``n_terms x n_terms`` products.

:func:`choose_solver` resolves ``"auto"`` by size; the choices are measured in
``benchmarks/bench_scale.py`` and explained in the documentation (Solvers and
scaling).
"""

import math
import warnings

import numpy as np
from scipy import linalg
from scipy.linalg import blas
from sklearn.exceptions import ConvergenceWarning

from ._threads import gram_flops, limit_blas
from .exceptions import IllConditionedWarning

# Designs up to this many entries (400 MB in float64) are factorized whole by
# "auto" (today's answers on small problems, to round-off).
DENSE_MAX_ENTRIES = 50_000_000
# From this many unknowns on, "auto" solves by conjugate gradients. Measured
# on the double pendulum (benchmarks/bench_scale.py): one iteration costs
# 1/13 of the (grouped) Gram matrix at n = 14 (3 059 unknowns) and 1/100 at
# n = 18 (7 314), while the closed-form preconditioner needs 100-200
# iterations, so the Gram matrix wins below about 10 000 unknowns.
ITERATIVE_MIN_TERMS = 10_000
# From this many unknowns, and this many rows per unknown, "auto" solves by
# conjugate gradients preconditioned by a sketch of the design (see
# :mod:`._sketch`): about 50 iterations, each a pass of the operator, plus
# the sketch's Gram matrix (SKETCH_ROWS_PER_COLUMN / 2 * n**3 multiply-adds,
# which the rows make small beside the design's). Measured on the double
# pendulum, M = 60 000 (720 000 rows), both cores: at n = 16 (4 844
# unknowns) 165 s against the normal equations' 172 s, at n = 18 (7 314)
# 240 s against 405 s. Factored normal equations (one Gram matrix of the
# value basis, see _factored) took 55 s and 119 s on the same fits, so the
# sketch is left to designs without them.
SKETCH_MIN_TERMS = 5_000
SKETCH_MIN_ROWS_PER_TERM = 50
# Reciprocal condition number of the equilibrated normal matrix below which
# Cholesky is not trusted and the eigen pseudo-inverse is used (the design's
# condition number above 1e7: refinement would then gain little).
CHOLESKY_RCOND = 1e-14
# Refinement steps against the design after a Cholesky solve, stopped early
# once a correction is below REFINED relative to the solution.
REFINEMENT_STEPS = 3
REFINED = 1e-12
# Up to this many unknowns, the condition number of the normal matrix is
# computed exactly (eigvalsh); beyond, estimated by power and inverse iteration.
EXACT_COND_MAX = 1500
# Conjugate gradients: relative (preconditioned) normal-residual tolerance and
# iteration cap.
CG_RTOL = 1e-11
CG_MAX_ITER = 400


def choose_solver(solver, n_rows, n_terms, factored=False):
    """Resolve ``solver="auto"`` from the size of the design.

    Parameters
    ----------
    solver : {"auto", "lstsq", "normal", "iterative", "sketch"}
        The requested solver.
    n_rows, n_terms : int
        Shape of the design.
    factored : bool or callable, default=False
        Whether the normal equations come from one Gram matrix of a value
        basis (:mod:`._factored`), ``n_states`` times cheaper than the
        grouped ones the sketch's threshold was measured against; a callable
        returning it is called only where the choice depends on it.

    Returns
    -------
    solver : str
        ``"lstsq"`` up to ``DENSE_MAX_ENTRIES`` entries; beyond, ``"normal"``;
        unless ``factored``, ``"sketch"`` from ``SKETCH_MIN_TERMS`` unknowns
        and ``SKETCH_MIN_ROWS_PER_TERM`` rows per unknown on; ``"iterative"``
        from ``ITERATIVE_MIN_TERMS`` unknowns on, where the Gram matrix costs
        more than the iterations it saves (and more memory than is
        reasonable).
    """
    if solver != "auto":
        return solver
    if n_rows * n_terms <= DENSE_MAX_ENTRIES:
        return "lstsq"
    if n_terms >= ITERATIVE_MIN_TERMS:
        return "iterative"
    if n_terms >= SKETCH_MIN_TERMS and n_rows >= SKETCH_MIN_ROWS_PER_TERM * n_terms:
        return "normal" if (factored() if callable(factored) else factored) else "sketch"
    return "normal"


def _column_norms(squared):
    norms = np.sqrt(squared)
    # An all-zero column (a basis function with no data) keeps its scale; the
    # rank deficiency is reported through ``rank``.
    norms[norms == 0] = 1.0
    return norms


def _scale(x, norms):
    return x / (norms if x.ndim == 1 else norms[:, None])


# ----------------------------------------------------------------- lstsq
def solve_dense(A, b):
    """Least squares on a design held in memory.

    Parameters
    ----------
    A : ndarray of shape (n_rows, n_terms)
        Design matrix (Fortran order avoids a copy); it is overwritten.
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
    return _scale(coef, norms), float(cond), int(rank)


def stack_blocks(blocks, n_columns):
    """The whole design and right-hand side from row blocks, the design in Fortran order."""
    columns, rhs = [], []
    for A, b in blocks:
        # Blocks may be views of a reused buffer: copy each one as it comes.
        columns.append(np.array(A.T, order="C"))
        rhs.append(np.array(b))
    A = np.concatenate(columns, axis=1).T if columns else np.zeros((0, n_columns))
    return A, np.concatenate(rhs)


# ---------------------------------------------------------------- normal
def symmetric_from_upper(upper):
    """The symmetric matrix whose upper triangle is ``upper`` (a new array, in ``upper``'s order).

    A copy in the same memory order, then the mirror: a copy of the
    Fortran-ordered Gram matrices into C order read across the cache, twice
    the time (0.34 against 0.17 s at 5 985 columns, best of five each).
    """
    return mirror_upper(np.array(upper, dtype=float, order="K"))


# Rows of the tiles mirror_upper copies: a tile and its transpose stay in cache.
MIRROR_TILE = 256


def mirror_upper(a):
    """Copy the upper triangle of the square ``a`` onto its lower one, in place; return ``a``.

    Tile by tile: ``upper + upper.T`` of a whole Gram matrix of 3 000
    columns allocates three matrices and reads the transpose across the
    cache, about three times the time of the copy.
    """
    n = a.shape[0]
    for start in range(0, n, MIRROR_TILE):
        stop = min(start + MIRROR_TILE, n)
        a[stop:, start:stop] = a[start:stop, stop:].T
        tile = a[start:stop, start:stop]
        below = np.tril_indices(stop - start, -1)
        tile[below] = tile.T[below]
    return a


def _assembled_on_one_thread(blocks):
    """The blocks of an iterable, each one produced on one BLAS thread.

    NumPy may bring its own OpenBLAS besides SciPy's, whose worker threads
    keep spinning for a while after a multi-threaded call, on the core that the
    next rank-k update's second thread needs; measured on a degree-14 fit
    (2 cores, 116 blocks of 840 x 2380), the updates then ran at one thread's
    speed.
    """
    blocks = iter(blocks)
    while True:
        with limit_blas(0):
            block = next(blocks, None)
        if block is None:
            return
        yield block


class NormalEquations:
    """``A^T A`` and ``A^T b`` accumulated over row blocks, by column groups.

    Rows of different kinds may touch different columns only (see
    :func:`~sk_hamiltonian._design.column_groups`): a block of group ``g``
    holds only the columns ``groups[g]``, and each group keeps its own
    (smaller) Gram matrix, updated in place by a BLAS rank-k update; the
    groups are scattered into one matrix at the end. With one group of all
    columns this is the plain accumulation.

    Parameters
    ----------
    n_columns : int
        Columns of the design.
    groups : list of ndarray of int, default=None
        Column indices of each group; None: one group of all columns.
    """

    def __init__(self, n_columns, groups=None):
        self.n_columns = n_columns
        self.groups = [np.arange(n_columns)] if groups is None else list(groups)
        self.grams = [np.zeros((g.size, g.size), order="F") for g in self.groups]
        self.rhs = None
        self.n_rows = 0

    def add(self, A, b, group=0):
        """Add a row block ``A`` (columns ``groups[group]``) and its right-hand side ``b``."""
        A = np.asfortranarray(A)
        b = np.asarray(b, dtype=float)
        with limit_blas(gram_flops(*A.shape)):
            blas.dsyrk(1.0, A, beta=1.0, c=self.grams[group], trans=1, lower=0, overwrite_c=1)
            # A^T b by SciPy's BLAS too (see _assembled_on_one_thread).
            product = (blas.dgemv(1.0, A, b, trans=1) if b.ndim == 1
                       else blas.dgemm(1.0, A, b.reshape(b.shape[0], -1), trans_a=1))
        if self.rhs is None:
            self.rhs = np.zeros((self.n_columns,) + b.shape[1:])
        self.rhs[self.groups[group]] += product.reshape((A.shape[1],) + b.shape[1:])
        self.n_rows += A.shape[0]

    def add_blocks(self, blocks, progress=None):
        """Add every block of an iterable of ``(A, b)`` or ``(A, b, group)``."""
        for k, block in enumerate(_assembled_on_one_thread(blocks), start=1):
            self.add(*block)
            if progress is not None:
                progress(k, self.n_rows)
        return self

    def __iadd__(self, other):
        """Add another accumulator with the same groups (e.g. from another chunk)."""
        for mine, theirs in zip(self.grams, other.grams):
            mine += theirs
        if other.rhs is not None:
            self.rhs = other.rhs.copy() if self.rhs is None else self.rhs + other.rhs
        self.n_rows += other.n_rows
        return self

    def result(self):
        """The accumulated ``(A^T A, A^T b)``."""
        if len(self.groups) == 1 and self.groups[0].size == self.n_columns:
            gram = symmetric_from_upper(self.grams[0])
        else:
            # Where a group's columns increase, its upper triangle lands in the
            # upper triangle: scatter that alone and symmetrize once at the end
            # (symmetrizing every group first took 1.45 s at degree 14). Column
            # by column into the transpose, whose rows are the columns: one
            # contiguous read and a short scatter each (np.ix_ on the whole
            # block took ten times as long at 3 000 columns).
            n = self.n_columns
            transposed = np.zeros((n, n))
            for columns, upper in zip(self.groups, self.grams):
                if np.all(np.diff(columns) > 0):
                    lower = upper.T  # row j: the group's column j
                    for j, column in enumerate(columns):
                        transposed[column, columns[: j + 1]] += lower[j, : j + 1]
                else:
                    transposed[np.ix_(columns, columns)] += symmetric_from_upper(upper)
            mirror_upper(transposed.T)
            gram = transposed  # symmetric: its own transpose
        rhs = np.zeros(self.n_columns) if self.rhs is None else self.rhs
        return gram, rhs


def normal_equations(blocks, n_terms, progress=None):
    """Accumulate ``A^T A`` and ``A^T b`` over row blocks of a design.

    Parameters
    ----------
    blocks : iterable of (ndarray, ndarray)
        Pairs ``(A_k, b_k)`` of consecutive row blocks of the design and the
        right-hand side, each ``b_k`` of shape ``(n_rows_k,)`` or
        ``(n_rows_k, n_targets)``.
    n_terms : int
        Number of columns.
    progress : callable, default=None
        Called as ``progress(k, n_rows)`` after block ``k``.

    Returns
    -------
    gram : ndarray of shape (n_terms, n_terms)
    rhs : ndarray of shape (n_terms,) or (n_terms, n_targets)
    """
    return NormalEquations(n_terms).add_blocks(blocks, progress).result()


def _extreme_eigenvalues(G, factor, n_iter=30, seed=0):
    """Estimates of the largest and smallest eigenvalues of SPD ``G`` (Cholesky ``factor``)."""
    rng = np.random.default_rng(seed)
    v = rng.standard_normal(G.shape[0])
    w = v.copy()
    largest = smallest_inverse = 0.0
    for _ in range(n_iter):
        v = G @ v
        largest = np.linalg.norm(v)
        v /= largest
        w = linalg.cho_solve(factor, w, check_finite=False)
        smallest_inverse = np.linalg.norm(w)
        w /= smallest_inverse
    return largest, 1.0 / smallest_inverse


def _normal_condition(G, factor):
    """2-norm condition number of the design from its equilibrated normal matrix ``G``."""
    if G.shape[0] <= EXACT_COND_MAX:
        eigenvalues = linalg.eigvalsh(G, check_finite=False)
        return math.sqrt(eigenvalues[-1] / eigenvalues[0]) if eigenvalues[0] > 0 else np.inf
    largest, smallest = _extreme_eigenvalues(G, factor)
    return math.sqrt(largest / smallest)


def _eigen_solve(G, rhs):
    """Pseudo-inverse solve with ``lstsq``'s relative cut-off; (solution, cond, rank)."""
    eigenvalues, eigenvectors = linalg.eigh(G, check_finite=False)
    # Eigenvalues of the normal matrix are squared singular values of the
    # design, but forming it rounds them by about eps * N * largest: below
    # that they are noise (a singular value below sqrt(eps * N) relative is
    # not resolved by the normal equations; lstsq would resolve it).
    cutoff = eigenvalues[-1] * np.finfo(float).eps * max(G.shape)
    keep = eigenvalues > cutoff
    inverse = np.zeros_like(eigenvalues)
    inverse[keep] = 1.0 / eigenvalues[keep]
    weights = inverse if rhs.ndim == 1 else inverse[:, None]
    solution = eigenvectors @ ((eigenvectors.T @ rhs) * weights)
    smallest = eigenvalues[0]
    cond = math.sqrt(eigenvalues[-1] / smallest) if smallest > 0 else np.inf
    return solution, cond, int(keep.sum())


def solve_normal(gram, rhs, residual=None):
    """Least squares from its normal equations: Cholesky, refined against the design.

    Parameters
    ----------
    gram : ndarray of shape (n_terms, n_terms)
        ``A^T A``; not modified.
    rhs : ndarray of shape (n_terms,) or (n_terms, n_targets)
        ``A^T b``.
    residual : callable, default=None
        ``residual(coef) -> A^T (b - A coef)``, computed from the design
        (not from ``gram``); with it, the Cholesky solution is refined
        ``REFINEMENT_STEPS`` times, which brings it to the accuracy of a
        QR or SVD solve while the design's condition number is below about
        ``1e7``. None: no refinement (e.g. ``partial_fit``, whose samples
        are gone).

    Returns
    -------
    coef, cond, rank
        As in :func:`solve_dense`; ``cond`` is the square root of the
        condition number of the equilibrated normal matrix (exact up to
        ``EXACT_COND_MAX`` unknowns, else estimated).
    """
    norms = _column_norms(np.diag(gram).copy())
    G = gram / np.outer(norms, norms)
    scaled_rhs = _scale(rhs, norms)
    factor = None
    try:
        factor = linalg.cho_factor(G, lower=False, check_finite=False)
        rcond, info = linalg.lapack.dpocon(factor[0], np.abs(G).sum(axis=0).max())
        if info != 0 or rcond < CHOLESKY_RCOND:
            factor = None
    except linalg.LinAlgError:
        factor = None
    if factor is None:
        solution, cond, rank = _eigen_solve(G, scaled_rhs)
        return _scale(solution, norms), cond, rank
    solution = linalg.cho_solve(factor, scaled_rhs, check_finite=False)
    if residual is not None:
        for _ in range(REFINEMENT_STEPS):
            correction = _scale(residual(_scale(solution, norms)), norms)
            step = linalg.cho_solve(factor, correction, check_finite=False)
            solution = solution + step
            # A correction at round-off level means the solve was already
            # accurate: another pass over the design would change nothing.
            if np.linalg.norm(step) <= REFINED * np.linalg.norm(solution):
                break
    return _scale(solution, norms), _normal_condition(G, factor), G.shape[0]


def solve_streaming(blocks, n_terms):
    """Least squares through normal equations accumulated block by block.

    Memory is ``O(n_terms**2)`` whatever the number of rows. See
    :func:`normal_equations` and :func:`solve_normal`.
    """
    return solve_normal(*normal_equations(blocks, n_terms))


# ------------------------------------------------------------- iterative
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


# ------------------------------------------------------------ constraints
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
