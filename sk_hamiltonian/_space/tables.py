"""1-D factor tables of a model space, laid out for the tensor kernels.

A *factor table* holds, for every state variable, its 1-D family (Legendre on
an interval, Fourier on a period, or both for a mixed variable: Legendre
columns first, then the Fourier ones, see :mod:`.mixed`) and the family's
derivatives at every sample,
already multiplied by the chain-rule factor of the variable's coordinate map.
The kernels of :mod:`.tensor` and :mod:`.contraction` read them as arrays of
shape ``(n_states + 1, width, n_samples)``: samples on the last, contiguous
axis, so that gathering the columns of many basis functions copies whole rows,
and row ``n_states`` is the dummy variable of the slot layout (``1``,
derivatives ``0``).

Two ways to fill a Legendre table, chosen by size: for a handful of samples
(one state of a simulation) a single call of :func:`scipy.special.eval_legendre`
costs less than the Python loop of the three-term recurrence; for many samples
the recurrence does ``O(degree)`` work per point against that function's
``O(degree**2)``.
"""

import numpy as np
from scipy.special import eval_legendre

from .fourier import period_to_angle
from .legendre import interval_to_window, legendre_derivative_matrix
from .mixed import MIXED_PERIOD

# Up to this many (sample, variable) points, one eval_legendre call; beyond,
# the recurrence (measured crossover on one core: about 40 points at degree 15).
DIRECT_POINTS = 32
# Evaluation (not the fit's design, whose values stay as they were) uses
# eval_legendre up to this many points times columns: the recurrence's
# Python loop costs 4 numpy calls per degree on strided rows. Measured on one
# core (2-core VM, load 3), eval_legendre against the recurrence: 8 against
# 19 us for 64 points at degree 3, 11 against 45 us at degree 6, 29 against
# 107 us at degree 15; the crossover lies near 1 000 points at degree 3 and
# 350 at degree 15.
EVALUATION_DIRECT_ENTRIES = 5000


_DERIVATIVE_MATRICES = {}
# Degrees as a column, for eval_legendre (one allocation fewer per evaluation).
_ORDERS = np.arange(64)[:, None]


def _derivative_matrix_t(degree):
    """``D.T`` of :func:`legendre_derivative_matrix`, contiguous (cached)."""
    if degree not in _DERIVATIVE_MATRICES:
        _DERIVATIVE_MATRICES[degree] = np.ascontiguousarray(legendre_derivative_matrix(degree).T)
    return _DERIVATIVE_MATRICES[degree]


def _legendre(xi, degree, out, evaluation=False, chain=None):
    """Fill ``out[r]`` (n_vars, degree + 1, S) with the r-th derivatives of P_0..P_degree at xi.

    ``chain`` (n_vars, 1, 1), the factor ``d xi / d x`` per variable, makes
    them derivatives with respect to ``x``; default 1 (with respect to xi).
    """
    value = out[0]
    direct = xi.size * (degree + 1) <= EVALUATION_DIRECT_ENTRIES if evaluation else (
        xi.size <= DIRECT_POINTS)
    if direct:
        orders = _ORDERS[: degree + 1] if degree < _ORDERS.size else np.arange(degree + 1)[:, None]
        eval_legendre(orders, xi[:, None, :], out=value)
    else:
        value[:, 0] = 1.0
        if degree >= 1:
            value[:, 1] = xi
        for k in range(1, degree):
            np.multiply(((2 * k + 1) / (k + 1)) * xi, value[:, k], out=value[:, k + 1])
            value[:, k + 1] -= (k / (k + 1)) * value[:, k - 1]
    if out.shape[0] == 1:
        return
    # P'_n = sum_k D[k, n] P_k: one product over the degree axis per order,
    # with the chain-rule factor folded into the matrix (one product, not two).
    DT = _derivative_matrix_t(degree)
    if chain is not None:
        DT = chain * DT
    for r in range(1, out.shape[0]):
        np.matmul(DT, out[r - 1], out=out[r])


def _fourier(theta, degree, out, evaluation=False, chain=None):
    """Fill ``out[r]`` (n_vars, 2K + 1, S) with d^r/dtheta^r of 1, cos theta, sin theta, ...

    ``chain`` (n_vars, 1, 1), the factor ``d theta / d x`` per variable, makes
    them derivatives with respect to ``x``; default 1.
    """
    k = np.arange(1, degree + 1, dtype=float)
    angles = k[None, :, None] * theta[:, None, :]
    cos, sin = np.cos(angles), np.sin(angles)
    rate = k[None, :, None] if chain is None else chain * k[None, :, None]
    for r in range(out.shape[0]):
        out[r, :, 0] = 1.0 if r == 0 else 0.0
        # d^r/dtheta^r of cos(k.) and sin(k.) cycle through +-k^r (cos, sin).
        factor = rate**r
        c, s = [(cos, sin), (-sin, cos), (-cos, -sin)][r]
        np.multiply(factor, c, out=out[r, :, 1::2])
        np.multiply(factor, s, out=out[r, :, 2::2])


def _mixed(window, degrees, out, evaluation=False, chain=None, angle=None, rate=None):
    """Fill ``out[r]`` with Legendre columns ``0..L`` at ``window``, then Fourier ones at ``angle``.

    ``degrees`` is ``(L, K)``; ``rate`` (n_vars, 1, 1) is ``d angle / d x``. The
    Fourier table's constant column is the Legendre ``P_0`` already there.
    """
    L, K = degrees
    _legendre(window, L, out[:, :, : L + 1], evaluation, chain)
    if K:
        part = np.empty(out.shape[:2] + (2 * K + 1,) + out.shape[3:])
        _fourier(angle, K, part, evaluation, rate)
        out[:, :, L + 1 : L + 1 + 2 * K] = part[:, :, 1:]


class FactorTables:
    """The factor tables of one model space, with its coordinate maps precomputed.

    Parameters
    ----------
    domain : ndarray of shape (n_states, 2)
        The box (one period for periodic variables).
    periodic : ndarray of shape (n_states,) of bool
        Which variables are periodic.
    legendre_degree, fourier_degree : int
        Highest Legendre degree and Fourier frequency.
    width : int
        Columns per table.
    mixed : ndarray of shape (n_states,) of bool, default=None
        Which variables are mixed (:mod:`.mixed`); None: none.
    """

    def __init__(self, domain, periodic, legendre_degree, fourier_degree, width, mixed=None):
        self.n_states = domain.shape[0]
        self.width = width
        mixed = np.zeros(self.n_states, dtype=bool) if mixed is None else mixed
        low, high = domain[:, 0], domain[:, 1]
        self.families = []
        for flags, family, to_window, degree in (
            (~periodic & ~mixed, _legendre, interval_to_window, legendre_degree),
            (periodic, _fourier, period_to_angle, fourier_degree),
            (mixed, _mixed, interval_to_window, (legendre_degree, fourier_degree)),
        ):
            if flags.any():
                rows = np.flatnonzero(flags)
                # The map is affine: window = slope * x + offset, computed as
                # the family's own map does on the box's corners.
                start, scale = to_window(low[rows], low[rows], high[rows])
                columns = {
                    _legendre: lambda n: n + 1, _fourier: lambda n: 2 * n + 1,
                    _mixed: lambda n: n[0] + 2 * n[1] + 1,
                }[family](degree)
                self.families.append((
                    family, degree, columns,
                    None if rows.size == self.n_states else rows,
                    scale[:, None], start[:, None] - scale[:, None] * low[rows, None],
                ))
        #: ``d angle / d x`` of the Fourier terms of mixed variables (angle ``0`` at ``x = 0``).
        self.mixed_rate = 2.0 * np.pi / MIXED_PERIOD

    def __call__(self, X, n_derivatives=1, evaluation=False):
        """Tables at ``X`` (n_samples, n_states): ndarray (n_derivatives + 1, n_states + 1, width, n_samples).

        ``evaluation=True`` (a model's evaluation, not a design) may fill
        Legendre tables by the route that is faster at this size; the
        values agree to round-off.

        ``tables[r, i, c, s]``: ``r``-th derivative, with respect to ``x_i``,
        of column ``c`` of variable ``i``'s family at sample ``s``; zero
        beyond the family's columns; row ``n_states`` is the dummy variable.
        """
        n_samples = X.shape[0]
        m = self.n_states
        tables = np.zeros((n_derivatives + 1, m + 1, self.width, n_samples))
        tables[0, m, 0] = 1.0
        for family, degree, columns, rows, slope, offset in self.families:
            chain = slope[:, :, None]
            x = X.T if rows is None else X[:, rows].T
            window = x * slope + offset
            extra = {}
            if family is _mixed:
                rate = np.full_like(chain, self.mixed_rate)
                extra = dict(angle=x * self.mixed_rate, rate=rate)
            if rows is None:
                family(window, degree, tables[:, :m, :columns], evaluation, chain, **extra)
            else:
                target = np.empty((n_derivatives + 1, rows.size, columns, n_samples))
                family(window, degree, target, evaluation, chain, **extra)
                tables[:, rows, :columns] = target
        return tables
