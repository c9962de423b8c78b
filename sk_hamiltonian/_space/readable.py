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

from itertools import product

import numpy as np
from numpy.polynomial import Legendre, Polynomial
from scipy import sparse


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


def _angle_rotation(frequency, low, omega):
    """Readable ``cos, sin (k w x)`` from basis ``cos, sin (k w (x - low))``, and back."""
    c, s = np.cos(frequency * omega * low), np.sin(frequency * omega * low)
    # Basis (+k, -k) in readable (+k, -k) by angle addition, rows the basis.
    forward = np.array([[c, s], [-s, c]])
    return forward, forward.T


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

    Attributes
    ----------
    to_fitting : scipy.sparse.csc_array of shape (n_terms, n_terms)
        Column ``beta``: the fitting-basis coefficients of readable function
        ``beta`` (without its constant part, when the space has no constant).
    from_fitting : scipy.sparse.csr_array of shape (n_terms, n_terms)
        Row ``beta``: the readable coefficient ``beta`` of each fitting
        function (its inverse, up to the constant).
    """

    def __init__(self, powers, domain, periodic):
        powers = np.asarray(powers, dtype=np.intp)
        periodic = np.asarray(periodic, dtype=bool)
        where = {tuple(row): j for j, row in enumerate(powers.tolist())}
        # One pair of 1-D tables per variable: fitting -> readable (forward) and
        # readable -> fitting (backward), indexed by (basis entry, readable entry).
        forward, backward = [], []
        for i, (low, high) in enumerate(np.asarray(domain, dtype=float)):
            top = int(np.abs(powers[:, i]).max(initial=0))
            if periodic[i]:
                forward.append(self._angle_table(top, low, 2 * np.pi / (high - low), 0))
                backward.append(self._angle_table(top, low, 2 * np.pi / (high - low), 1))
            else:
                M = legendre_to_monomials(top, low, high)
                forward.append(_dictionary(M))
                backward.append(_dictionary(np.linalg.inv(M)))
        self.to_fitting = self._tensor(powers, where, backward).T.tocsc()
        self.from_fitting = self._tensor(powers, where, forward).T.tocsr()

    @staticmethod
    def _angle_table(top, low, omega, which):
        table = {(0, 0): 1.0}
        for k in range(1, top + 1):
            matrix = _angle_rotation(k, low, omega)[which]
            for a, sa in enumerate((k, -k)):
                for b, sb in enumerate((k, -k)):
                    table[(sa, sb)] = matrix[a, b]
        return _grouped(table)

    @staticmethod
    def _tensor(powers, where, tables):
        """Sparse ``T[alpha, beta] = prod_i table_i[alpha_i, beta_i]`` over the index set.

        ``tables[i]`` maps a source entry to ``[(target entry, value)]``; the
        rows are the sources.
        """
        rows, columns, values = [], [], []
        for j, alpha in enumerate(powers.tolist()):
            factors = [tables[i][a] for i, a in enumerate(alpha)]
            for combination in product(*factors):
                k = where.get(tuple(entry for entry, _ in combination))
                if k is None:
                    # The constant, outside a Hamiltonian's index set: a shift.
                    continue
                value = np.prod([v for _, v in combination])
                if value != 0.0:
                    rows.append(j)
                    columns.append(k)
                    values.append(value)
        n = powers.shape[0]
        return sparse.coo_array((values, (rows, columns)), shape=(n, n))


def _dictionary(matrix):
    """A dense 1-D change of basis as ``{source: [(target, value)]}``."""
    return {
        a: [(int(b), float(matrix[a, b])) for b in np.flatnonzero(matrix[a])]
        for a in range(matrix.shape[0])
    }


def _grouped(table):
    grouped = {}
    for (a, b), value in table.items():
        if value != 0.0:
            grouped.setdefault(a, []).append((b, float(value)))
    return grouped
