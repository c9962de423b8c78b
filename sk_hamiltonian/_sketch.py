"""A sketch of the design: the preconditioner of ``solver="sketch"``.

Conjugate gradients on the normal equations converge in a number of
iterations that grows with the condition number of the preconditioned
design. A *sketch* ``S A`` of a few times ``n_columns`` rows, ``S`` a random
embedding, keeps the geometry of the design's column space up to a small
distortion: if ``(S A)^T (S A) = R^T R``, then ``A R^{-1}`` has a condition
number close to 1 whatever the design's, and conjugate gradients
preconditioned by ``R^T R`` converge in a few dozen iterations that do not
depend on how the samples are spread (sketch-and-precondition, as in
Blendenpik and LSRN; Martinsson and Tropp, "Randomized numerical linear
algebra", Acta Numerica 2020, section 10). The iterations apply the design
itself, so the solution is the least-squares one, not the sketch's.

The embedding is a CountSketch: every row of the design is added, with a
random sign, to one random row of the sketch (see :class:`DesignSketch`).
Forming the sketch is one pass of additions over the design, and its Gram
matrix costs ``SKETCH_ROWS_PER_COLUMN / 2 * n_columns**3`` multiply-adds:
for the paper's degree-18 fit (7 314 unknowns, 720 000 rows) 3 % of the
design's Gram matrix. The triangle comes from a Cholesky factorization of
that small Gram matrix rather than a QR factorization of the sketch, which
LAPACK ran at a tenth of the speed (a 9 000 x 3 000 QR took 13 s on two threads, its Gram
matrix 1.1 s); squaring the sketch's condition number costs a
preconditioner nothing while it stays below about ``1e7``, and a design that
ill-conditioned needs the normal equations' pseudo-inverse anyway.

The embedding is drawn from a fixed seed, so that a fit is reproducible.
"""

import numpy as np
from scipy.linalg import blas

from ._threads import gram_flops, limit_blas
from ._solvers import mirror_upper

# Rows of the sketch per column of the design. A sketch of r n rows leaves
# the preconditioned design a condition number of about
# (1 + 1/sqrt(r)) / (1 - 1/sqrt(r)): 5.8 at r = 2, 3.7 at r = 3, 3.0 at r = 4
# (measured on the double pendulum's designs, as for a Gaussian embedding of
# the same size), while the sketch's Gram matrix costs r n**3 / 2 and the
# sketch r n**2 floats. On the paper's degree-18 fit r = 4 took 47
# iterations where r = 3 took 48 to 50, for a third more memory and Gram
# work: the iterations fall more slowly than the bound.
SKETCH_ROWS_PER_COLUMN = 3
# The seed of the embedding.
SKETCH_SEED = 0


class DesignSketch:
    """``S A`` accumulated over row blocks of a design, ``S`` a CountSketch.

    The counterpart of :class:`~sk_hamiltonian._solvers.normal.NormalEquations`
    for ``solver="sketch"``: the same blocks and column groups, but one pass
    of additions per block instead of a rank-k update.

    The rows of a block go, in order and each with a random sign, to a
    window of consecutive rows of the sketch at a random offset (wrapping
    around): a pair of rows of different blocks meets in one row of the
    sketch with probability ``1 / n_rows``, as for independent hashing, and
    rows of one block never meet. The window is a strided slab of the
    sketch, which NumPy updates at 7 to 8 ns per entry; independent rows
    scattered through an index took 200 to 256 ns per entry (scratch timings
    of one degree-18 block of 363 rows and 5 500 columns).

    Parameters
    ----------
    n_columns : int
        Columns of the design.
    groups : list of ndarray of int, default=None
        Column indices of each group (a block of group ``g`` holds the
        columns ``groups[g]`` only); None: one group of all columns.
    n_rows : int, default=None
        Rows of the sketch; None: ``SKETCH_ROWS_PER_COLUMN * n_columns``.
    seed : int, default=SKETCH_SEED
        Seed of the embedding.
    """

    def __init__(self, n_columns, groups=None, n_rows=None, seed=SKETCH_SEED):
        self.n_columns = n_columns
        self.groups = [np.arange(n_columns)] if groups is None else list(groups)
        self.n_rows = SKETCH_ROWS_PER_COLUMN * n_columns if n_rows is None else int(n_rows)
        # Held transposed, (n_columns, n_rows) in C order: a block arrives as
        # the transpose of a C-ordered (columns, rows) array, and the window
        # of a block is then a slab of contiguous runs; the transpose of this
        # array is what the BLAS rank-k update takes.
        self.transposed = np.zeros((n_columns, self.n_rows))
        self._rng = np.random.default_rng(seed)

    def add(self, A, b=None, group=0):
        """Add a row block ``A`` (columns ``groups[group]``); ``b`` is not needed."""
        block = np.asarray(A, dtype=float).T  # (columns, rows)
        columns = self.groups[group]
        every_column = columns.size == self.n_columns
        for start in range(0, block.shape[1], self.n_rows):
            chunk = block[:, start : start + self.n_rows]
            signed = chunk * self._rng.choice((-1.0, 1.0), chunk.shape[1])
            offset = int(self._rng.integers(self.n_rows))
            head = min(chunk.shape[1], self.n_rows - offset)
            for window, part in ((slice(offset, offset + head), signed[:, :head]),
                                 (slice(0, chunk.shape[1] - head), signed[:, head:])):
                if not part.size:
                    continue
                view = self.transposed[:, window]
                if every_column:
                    view += part
                else:
                    # Gather, add, scatter: ``view[columns] += part`` through
                    # an index on a strided view was 3 to 17 times slower.
                    rows = view[columns]
                    rows += part
                    view[columns] = rows
        return self

    def add_blocks(self, blocks):
        """Add every block of an iterable of ``(A, b)`` or ``(A, b, group)``."""
        for block in blocks:
            self.add(*block)
        return self

    def gram(self):
        """``(S A)^T (S A)``: ndarray of shape (n_columns, n_columns), symmetric.

        The sketch itself is released: only its Gram matrix is needed.
        """
        T = self.transposed
        with limit_blas(gram_flops(*T.T.shape)):
            upper = blas.dsyrk(1.0, T.T, trans=1, lower=0)
        self.transposed = None
        return mirror_upper(upper)
