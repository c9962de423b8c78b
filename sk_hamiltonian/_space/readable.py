"""The readable basis of a model space: monomials and angles in the user's coordinates.

The fitting basis (Legendre polynomials on the box mapped to ``[-1, 1]``, Fourier
series of angles measured from the start of their period) is well conditioned,
but a formula that is short in the user's coordinates is not short in it:
``p**2`` on a box that is not centred at zero is ``P_2``, ``P_1`` and ``P_0`` of
the mapped coordinate. The *readable* basis of the same space has one function
per multi-index ``beta``: the product of ``x_i**beta_i`` over ordinary variables
and of ``cos(k w x_i)`` (``beta_i = +k``) or ``sin(k w x_i)`` (``-k``) over
periodic ones, ``w = 2 pi / period``. It spans the same functions (up to the
constant), since the index sets are closed downward; a sparse Hamiltonian is
sparse in it, so it is where a threshold decides which terms stay.

:class:`ReadableBasis` holds the change of basis both ways as sparse matrices.
"""

import numpy as np
from numpy.polynomial import Legendre, Polynomial
from scipy import sparse
from scipy.linalg import block_diag, solve_triangular

from .mixed import mixed_columns


def legendre_to_monomials(degree, low, high):
    """``M[k, e]``: the coefficient of ``x**e`` in ``P_k`` of the mapped coordinate.

    Parameters
    ----------
    degree : int
        Highest Legendre degree.
    low, high : float
        The interval mapped onto ``[-1, 1]``.

    Returns
    -------
    M : ndarray of shape (degree + 1, degree + 1)
        Lower triangular.
    """
    window = Polynomial([-(high + low) / (high - low), 2.0 / (high - low)])
    M = np.zeros((degree + 1, degree + 1))
    for k in range(degree + 1):
        c = Legendre.basis(k).convert(kind=Polynomial)(window).coef
        M[k, : c.size] = c
    return M


# Entries of one block of the dense change of basis (float64): 4 million is
# 32 MB; the blocks' nonzeros are kept, sparse.
BLOCK_ENTRIES = 4_000_000


def _angle_table(top, low, omega):
    """Readable coefficients of the basis ``cos, sin (k w (x - low))``, by angle addition.

    Rows and columns are the signed frequencies ``-top..top`` shifted by
    ``top``; row: fitting function, column: readable function.
    """
    table = np.zeros((2 * top + 1, 2 * top + 1))
    table[top, top] = 1.0
    for k in range(1, top + 1):
        c, s = np.cos(k * omega * low), np.sin(k * omega * low)
        # A period starting at a multiple of a quarter turn (e.g. -pi) makes
        # one of them zero; the rounded angle leaves ~1e-16, which would tie
        # every cosine to a sine. Below the angle's own rounding it is zero.
        tiny = 4 * np.finfo(float).eps * max(1.0, abs(k * omega * low))
        c, s = (0.0 if abs(c) <= tiny else c), (0.0 if abs(s) <= tiny else s)
        plus, minus = top + k, top - k
        table[plus, plus], table[plus, minus] = c, s
        table[minus, plus], table[minus, minus] = -s, c
    return table


class ReadableBasis:
    """The change between a space's fitting basis and its readable basis.

    Parameters
    ----------
    powers : ndarray of shape (n_terms, n_states)
        Multi-indices of the space (signed frequencies for periodic
        variables); the readable functions carry the same multi-indices.
    domain : ndarray of shape (n_states, 2)
        The box (one period for periodic variables).
    periodic : ndarray of shape (n_states,) of bool
        Which variables are periodic.
    mixed : ndarray of shape (n_states,) of bool, default=None
        Which variables are mixed (:mod:`.mixed`); their Fourier terms are
        already readable (``cos(k x)``, ``sin(k x)``), their Legendre ones
        become monomials. None: none.

    Attributes
    ----------
    to_fitting : scipy.sparse.csc_array of shape (n_terms, n_terms)
        Column ``beta``: the fitting-basis coefficients of readable function
        ``beta`` (without its constant part, when the space has no constant).
    from_fitting : scipy.sparse.csr_array of shape (n_terms, n_terms)
        Row ``beta``: the readable coefficient ``beta`` of each fitting
        function (its inverse, up to the constant).
    """

    def __init__(self, powers, domain, periodic, mixed=None):
        powers = np.asarray(powers, dtype=np.intp)
        periodic = np.asarray(periodic, dtype=bool)
        mixed = np.zeros(powers.shape[1], dtype=bool) if mixed is None else np.asarray(mixed, bool)
        # One dense 1-D table per variable (row: source entry, column: target
        # entry, both shifted by ``offsets``), fitting -> readable (forward)
        # and readable -> fitting (backward).
        forward, backward, offsets = [], [], []
        entries = powers.copy()
        for i, (low, high) in enumerate(np.asarray(domain, dtype=float)):
            top = int(np.abs(powers[:, i]).max(initial=0))
            if mixed[i]:
                # Legendre columns become monomials; the Fourier terms (angle
                # 0 at x = 0) are readable as they are.
                codes = powers[:, i]
                degree = int(codes.max(initial=0))
                n_trig = int(-codes.min(initial=0))
                M = legendre_to_monomials(degree, low, high)
                forward.append(block_diag(M, np.eye(n_trig)))
                backward.append(block_diag(
                    solve_triangular(M, np.eye(degree + 1), lower=True), np.eye(n_trig)))
                entries[:, i] = mixed_columns(codes, degree)
                offsets.append(0)
            elif periodic[i]:
                table = _angle_table(top, low, 2 * np.pi / (high - low))
                # The 2 x 2 rotations are orthogonal: the inverse is the transpose.
                forward.append(table)
                backward.append(table.T)
                offsets.append(top)
            else:
                M = legendre_to_monomials(top, low, high)
                forward.append(M)
                # The inverse of a lower-triangular matrix is lower triangular;
                # a general inverse leaves round-off (~1e-17) above the
                # diagonal, which gave every kept monomial spurious
                # higher-degree companions to evaluate (37 functions instead
                # of 11 for the sparse Henon-Heiles model).
                backward.append(solve_triangular(M, np.eye(top + 1), lower=True))
                offsets.append(0)
        shifted = entries + np.asarray(offsets, dtype=np.intp)
        self.to_fitting = _tensor(shifted, backward).T.tocsc()
        self.from_fitting = _tensor(shifted, forward).T.tocsr()


def _tensor(entries, tables):
    """Sparse ``T[j, k] = prod_i tables[i][entries[j, i], entries[k, i]]`` over the index set.

    Row ``j`` is the source function, column ``k`` the target. Functions
    outside the index set (the constant of a Hamiltonian's) are left out: the
    constant part of a function is dropped.
    """
    n = entries.shape[0]
    rows, columns, values = [], [], []
    size = max(1, BLOCK_ENTRIES // max(1, n))
    for start in range(0, n, size):
        block = entries[start : start + size]
        product = np.ones((block.shape[0], n))
        for i, table in enumerate(tables):
            product *= table[block[:, i][:, None], entries[:, i][None, :]]
        r, c = np.nonzero(product)
        rows.append(r + start)
        columns.append(c)
        values.append(product[r, c])
    return sparse.coo_array(
        (np.concatenate(values), (np.concatenate(rows), np.concatenate(columns))), shape=(n, n)
    )
