"""Normal equations of a gradient design, from the Gram matrix of its value design.

The rows of variable ``i`` of a Hamiltonian fit hold gradients, ``A_i = B
T_i`` (:mod:`._space.derivative_maps`): ``B`` the values of the value basis
at the fit's points, with the same quadrature and weights for every variable.
So::

    A^T A = sum_i T_i^T (B^T B) T_i,        A^T b = sum_i T_i^T (B^T b_i),

and the samples are visited once, by one rank-k update of ``B^T B``, instead of
once per variable (:class:`~sk_hamiltonian._solvers.normal.NormalEquations` with the
groups of :func:`~sk_hamiltonian._design.column_groups`). The maps ``T_i`` are
sparse (at most ``degree / 2 + 1`` entries per function), so applying them
costs about ``n_terms * n_values * degree / 2`` multiply-adds per variable, once:
small against the samples' pass.

Columns besides the basis (the friction unknowns, each in the rows of one
variable) ride along as extra columns of ``B``.
"""

import numpy as np

from ._solvers import MIRROR_TILE, NormalEquations, mirror_upper

# Rows of the maps per sparse product in FactoredNormalEquations.result.
RESULT_ROWS = 128


class FactoredNormalEquations:
    """``A^T A`` and ``A^T b`` of a gradient design, accumulated on its value design.

    The counterpart of :class:`~sk_hamiltonian._solvers.normal.NormalEquations`
    (same ``add_blocks``, ``+=``, ``result`` and ``btb``), for the blocks of
    :func:`~sk_hamiltonian._design.value_blocks`.

    Parameters
    ----------
    maps : DerivativeMaps
        The gradient of the model space on its value basis.
    extra_variables : sequence of int, default=()
        For each column after the basis (the friction unknowns), the
        variable in whose rows it is nonzero.
    """

    def __init__(self, maps, extra_variables=()):
        self.maps = maps
        self.extra_variables = np.asarray(extra_variables, dtype=np.intp)
        self.n_terms = maps.n_terms
        self.n_columns = self.n_terms + self.extra_variables.size
        self.values = NormalEquations(maps.n_values + self.extra_variables.size)

    @property
    def n_rows(self):
        """Equations accumulated: samples times variables."""
        return self.values.n_rows * len(self.maps.maps_t)

    def add_blocks(self, blocks, progress=None):
        """Add blocks ``(B, targets)``: values and extras ``(n, n_values + n_extra)``, ``(n, n_states)``."""
        counted = None if progress is None else (lambda k, _: progress(k, self.n_rows))
        self.values.add_blocks(blocks, counted)
        return self

    def __iadd__(self, other):
        """Add another accumulator of the same design (e.g. from another chunk)."""
        self.values += other.values
        return self

    @property
    def btb(self):
        """``b^T b`` of the gradient design: the targets of every variable, squared and summed."""
        products = self.values.btb
        return float(np.trace(products)) if np.ndim(products) == 2 else products

    def result(self):
        """The accumulated ``(A^T A, A^T b)`` of the gradient design."""
        # A copy of the value Gram matrix (0.02 to 0.04 s at degree 14, about
        # 0.5 s at degree 18, against mirroring the accumulator's own state in
        # place): this method leaves the accumulator as it was.
        values_gram, values_rhs = self.values.result()
        # Symmetric and Fortran-ordered: its transpose is the same matrix in
        # C order, which the sparse products read without a copy.
        values_gram = values_gram.T
        n_values, n_terms = self.maps.n_values, self.n_terms
        if values_rhs.ndim == 1:  # nothing accumulated yet
            values_rhs = np.zeros((values_gram.shape[0], len(self.maps.maps_t)))
        G = values_gram[:n_values, :n_values]
        if self.extra_variables.size:
            G = np.ascontiguousarray(G)
        gram = np.zeros((self.n_columns, self.n_columns))
        rhs = np.zeros(self.n_columns)
        basis = gram[:n_terms, :n_terms]
        GT = np.empty((n_values, n_terms))
        # By blocks of rows: the products' temporaries then stay in cache and
        # are reused from the heap, where whole-matrix ones were fresh pages
        # each time (cProfile at degree 14: 1.0 s for this method with
        # whole-matrix products, 0.26 s by blocks of 128 rows; degree 18: 8.6
        # and 3.8 s; both before the copy above).
        blocks = [slice(start, start + RESULT_ROWS) for start in range(0, n_terms, RESULT_ROWS)]
        for i, T_t in enumerate(self.maps.maps_t):
            if T_t.nnz == 0:
                continue
            parts = [T_t[rows] for rows in blocks]
            for rows, part in zip(blocks, parts):
                _transpose_into(part @ G, GT[:, rows])  # G T_i, G symmetric
            for rows, part in zip(blocks, parts):
                basis[rows] += part @ GT
            rhs[:n_terms] += T_t @ values_rhs[:n_values, i]
        for e, i in enumerate(self.extra_variables):
            column = n_terms + e
            gram[:n_terms, column] = self.maps.maps_t[i] @ values_gram[:n_values, n_values + e]
            gram[column, column] = values_gram[n_values + e, n_values + e]
            rhs[column] = values_rhs[n_values + e, i]
        # The sparse products round the two triangles differently: keep one.
        return mirror_upper(gram), rhs


def _transpose_into(a, out):
    """``out[...] = a.T``, tile by tile.

    ``np.ascontiguousarray(a.T)`` reads across the cache: 1.9 s for a
    7 314 x 5 985 matrix, against 0.15 s by tiles (as in
    :func:`~sk_hamiltonian._solvers.normal.mirror_upper`; one timing each).
    """
    rows, columns = a.shape
    for start in range(0, rows, MIRROR_TILE):
        for first in range(0, columns, MIRROR_TILE):
            out[first:first + MIRROR_TILE, start:start + MIRROR_TILE] = (
                a[start:start + MIRROR_TILE, first:first + MIRROR_TILE].T)
    return out
