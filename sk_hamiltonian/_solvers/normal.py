"""``"normal"``: normal equations accumulated block by block, solved by Cholesky and refined."""

import functools
import math

import numpy as np
from scipy import linalg
from scipy.linalg import blas

from .._threads import gram_flops, limit_blas
from .common import _column_norms, _scale

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
    """``A^T A``, ``A^T b`` and ``b^T b`` accumulated over row blocks, by column groups.

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

    Attributes
    ----------
    btb : float or ndarray of shape (n_targets, n_targets)
        ``b^T b`` of the blocks added so far: with the normal equations it
        gives the residual ``||A c - b||**2 = c^T A^T A c - 2 c^T A^T b +
        b^T b`` of any ``c`` without the design (per target on the diagonal).
    """

    def __init__(self, n_columns, groups=None):
        self.n_columns = n_columns
        self.groups = [np.arange(n_columns)] if groups is None else list(groups)
        self.grams = [np.zeros((g.size, g.size), order="F") for g in self.groups]
        self.rhs = None
        self.btb = 0.0
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
        self.btb = self.btb + (b @ b if b.ndim == 1 else b.T @ b)
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
        self.btb = self.btb + other.btb
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


def solve_normal(gram, rhs, residual=None, *, defer_condition=False):
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
    defer_condition : bool, default=False
        Return ``cond`` as a function of no argument that computes it. Its
        eigenvalues cost several times the Cholesky solve (exact up to
        ``EXACT_COND_MAX`` unknowns), and a thresholded fit discards the
        condition numbers of all its solves but the last: deferred, only
        those read are computed.

    Returns
    -------
    coef, cond, rank
        As in :func:`~.dense.solve_dense`; ``cond`` is the square root of the
        condition number of the equilibrated normal matrix (exact up to
        ``EXACT_COND_MAX`` unknowns, else estimated), or with
        ``defer_condition`` a callable returning it (see
        :func:`resolve_condition`).
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
    cond = functools.partial(_normal_condition, G, factor)
    return _scale(solution, norms), cond if defer_condition else cond(), G.shape[0]


def resolve_condition(cond):
    """The condition number ``cond``, computed first when it was deferred (:func:`solve_normal`)."""
    return cond() if callable(cond) else cond


def solve_streaming(blocks, n_terms):
    """Least squares through normal equations accumulated block by block.

    Memory is ``O(n_terms**2)`` whatever the number of rows. See
    :func:`normal_equations` and :func:`solve_normal`.
    """
    return solve_normal(*normal_equations(blocks, n_terms))
