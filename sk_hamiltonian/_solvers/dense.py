"""``"lstsq"``: the whole design factorized by an SVD-based LAPACK driver."""

import numpy as np
from scipy import linalg

from .common import _column_norms, _scale


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
