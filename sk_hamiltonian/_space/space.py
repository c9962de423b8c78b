"""A model space: 1-D families on a box, combined over an index set.

:class:`ModelSpace` is the one small class on top of the plain functions of
:mod:`.legendre`, :mod:`.fourier`, :mod:`.index_set` and :mod:`.tensor`. It
knows, for each state variable, its family (Legendre on an interval or Fourier
on a period) and its coordinate map, and evaluates the tensor-product basis
over a given set of multi-indices.
"""

import numpy as np

from . import tensor
from .fourier import fourier_column, fourier_tables, period_to_angle, wrap_to_period
from .legendre import interval_to_window, legendre_tables


def outside_domain(X, domain, periodic, slack=0.0):
    """Rows of ``X`` with a non-periodic variable outside its interval.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_states)
        Points.
    domain : ndarray of shape (n_states, 2)
        The box.
    periodic : ndarray of shape (n_states,) of bool
        Periodic variables are never outside: they are wrapped.
    slack : float, default=0.0
        Tolerance, relative to each interval's width.

    Returns
    -------
    outside : ndarray of shape (n_samples,) of bool
    """
    low, high = domain[:, 0], domain[:, 1]
    margin = slack * (high - low)
    out = (X < low - margin) | (X > high + margin)
    return np.any(out[:, ~np.asarray(periodic, dtype=bool)], axis=1)


class ModelSpace:
    """Tensor-product basis over a box, some of whose variables may be periodic.

    Parameters
    ----------
    domain : ndarray of shape (n_states, 2)
        ``(low, high)`` per variable: an interval, or one period for a
        periodic variable.
    powers : ndarray of shape (n_terms, n_states)
        Multi-indices (signed frequencies for periodic variables), as from
        :func:`~sk_hamiltonian._space.index_set.index_set`.
    periodic : ndarray of shape (n_states,) of bool, default=None
        Which variables are periodic; None: none.
    """

    def __init__(self, domain, powers, periodic=None):
        self.domain = np.asarray(domain, dtype=float)
        self.powers = np.asarray(powers, dtype=np.intp)
        n_states = self.domain.shape[0]
        self.periodic = (
            np.zeros(n_states, dtype=bool) if periodic is None else np.asarray(periodic, bool)
        )
        #: Table column of every variable in every basis function.
        self.columns = np.where(self.periodic, fourier_column(self.powers), np.abs(self.powers))
        self.layout = tensor.SlotLayout(self.columns)
        magnitude = np.abs(self.powers)
        self.legendre_degree = int(magnitude[:, ~self.periodic].max(initial=0))
        self.fourier_degree = int(magnitude[:, self.periodic].max(initial=0))
        self.width = max(self.legendre_degree + 1, 2 * self.fourier_degree + 1)

    @property
    def n_states(self):
        """Number of state variables."""
        return self.domain.shape[0]

    @property
    def n_terms(self):
        """Number of basis functions."""
        return self.powers.shape[0]

    @property
    def degree(self):
        """Largest total degree of a basis function."""
        return int(np.abs(self.powers).sum(axis=1).max(initial=0))

    def wrap(self, X):
        """Wrap the periodic variables of ``X`` into their period (a copy)."""
        X = np.array(X, dtype=float)
        if self.periodic.any():
            low, high = self.domain[self.periodic, 0], self.domain[self.periodic, 1]
            X[..., self.periodic] = wrap_to_period(X[..., self.periodic], low, high)
        return X

    def wrap_difference(self, D):
        """Differences of states, with periodic components taken in ``[-P/2, P/2)``."""
        D = np.array(D, dtype=float)
        if self.periodic.any():
            period = self.domain[self.periodic, 1] - self.domain[self.periodic, 0]
            D[..., self.periodic] = wrap_to_period(D[..., self.periodic], -period / 2, period / 2)
        return D

    def outside(self, X, slack=0.0):
        """Rows of ``X`` with a non-periodic variable outside its interval."""
        return outside_domain(X, self.domain, self.periodic, slack)

    def tables(self, X, n_derivatives=1):
        """1-D tables of every variable, derivatives already in ``X``'s coordinates.

        Parameters
        ----------
        X : ndarray of shape (n_samples, n_states)
            Points.
        n_derivatives : {0, 1, 2}, default=1
            Derivative orders to tabulate beyond the values.

        Returns
        -------
        tables : list of ndarray of shape (n_samples, n_states + 1, width)
            ``tables[r][s, i, c]``: ``r``-th derivative of column ``c`` of
            variable ``i``'s family at sample ``s``; row ``n_states`` is the
            dummy variable of the slot layout (``1``, derivatives ``0``).
        """
        n_samples = X.shape[0]
        shape = (n_samples, self.n_states + 1, self.width)
        tables = [np.zeros(shape) for _ in range(n_derivatives + 1)]
        tables[0][:, self.n_states, 0] = 1.0
        low, high = self.domain[:, 0], self.domain[:, 1]
        for flags, family, to_window, degree in (
            (~self.periodic, legendre_tables, interval_to_window, self.legendre_degree),
            (self.periodic, fourier_tables, period_to_angle, self.fourier_degree),
        ):
            if not flags.any():
                continue
            window, scale = to_window(X[:, flags], low[flags], high[flags])
            parts = family(window, degree, n_derivatives)
            for r, part in enumerate(parts):
                tables[r][:, : self.n_states][:, flags, : part.shape[-1]] = part * (
                    scale[:, None] ** r
                )
        return tables

    def values(self, X):
        """Values of the basis functions, ndarray of shape (n_samples, n_terms)."""
        return tensor.values(self.tables(X, 0), self.layout)

    def gradients(self, X):
        """Gradients of the basis functions, ndarray of shape (n_samples, n_states, n_terms)."""
        return tensor.gradients(self.tables(X, 1), self.layout)

    def value_dot(self, X, coef):
        """Values of ``sum_j coef[j] phi_j`` (``coef`` may have trailing target axes)."""
        return self.values(X) @ coef

    def gradient_dot(self, X, coef):
        """Gradient of ``sum_j coef[j] phi_j``, ndarray of shape (n_samples, n_states)."""
        return tensor.gradient_dot(self.tables(X, 1), self.layout, coef)

    def hessian_dot(self, X, coef):
        """Hessian of ``sum_j coef[j] phi_j``, ndarray of shape (n_samples, n_states, n_states)."""
        return tensor.hessian_dot(self.tables(X, 2), self.layout, coef)
