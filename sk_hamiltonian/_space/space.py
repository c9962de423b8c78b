"""A model space: 1-D families on a box, combined over an index set.

:class:`ModelSpace` is the one small class on top of the plain functions of
:mod:`.legendre`, :mod:`.fourier`, :mod:`.index_set` and :mod:`.tensor`. It
knows, for each state variable, its family (Legendre on an interval or Fourier
on a period) and its coordinate map, and evaluates the tensor-product basis
over a given set of multi-indices.
"""

import functools
import math

import numpy as np

from .._config import use_numba
from . import compiled, tensor
from .contraction import ContractionPlan
from .derivative_maps import DerivativeMaps
from .flat import FlatPlan, choose_flat
from .readable import ReadableBasis
from .fourier import fourier_column, fourier_frequency, wrap_to_period
from .mixed import MIXED_PERIOD, factor_degrees, mixed_codes, mixed_columns
from .tables import FactorTables

# Up to this many entries, checks of states run on Python floats (see count_outside).
SCALAR_ENTRIES = 32


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
    below, above, _ = _bounds_of(domain, periodic, slack)
    return ((X < below) | (X > above)).any(axis=1)


def count_outside(X, domain, periodic, slack=0.0):
    """Number of rows of ``X`` that :func:`outside_domain` finds outside.

    Same parameters as :func:`outside_domain`. A few states (one
    prediction, one stage of a step) are compared as Python floats: numpy's
    fixed cost per call is several times that of the comparisons.
    """
    if X.size > SCALAR_ENTRIES:
        return int(np.count_nonzero(outside_domain(X, domain, periodic, slack)))
    _, _, pairs = _bounds_of(domain, periodic, slack)
    return sum(
        any(value < low or value > high for value, (low, high) in zip(row, pairs))
        for row in X.tolist()
    )


def all_finite(X):
    """``np.isfinite(X).all()``, on Python floats for a few entries (as :func:`count_outside`)."""
    if X.size > SCALAR_ENTRIES:
        return bool(np.isfinite(X).all())
    return all(map(math.isfinite, X.ravel().tolist()))


def _bounds_of(domain, periodic, slack):
    # The bounds are cached by value: the one state of a prediction would
    # pay more for computing them than for the comparisons.
    domain = np.ascontiguousarray(domain, dtype=float)
    return _bounds(
        domain.tobytes(), domain.shape[0], np.asarray(periodic, dtype=bool).tobytes(), float(slack)
    )


@functools.lru_cache(maxsize=64)
def _bounds(domain, n_states, periodic, slack):
    """Bounds of :func:`outside_domain`, from the bytes of its arguments.

    Returns the lower and upper bounds as arrays, and as ``(low, high)``
    floats per variable (for :func:`count_outside`).
    """
    domain = np.frombuffer(domain, dtype=float).reshape(n_states, 2)
    periodic = np.frombuffer(periodic, dtype=bool)
    margin = slack * (domain[:, 1] - domain[:, 0])
    # Periodic variables get infinite bounds: they are never outside.
    below = np.where(periodic, -np.inf, domain[:, 0] - margin)
    above = np.where(periodic, np.inf, domain[:, 1] + margin)
    below.flags.writeable = above.flags.writeable = False  # shared by every caller
    return below, above, tuple(zip(below.tolist(), above.tolist()))


def cached_binding(store, key, coef, make):
    """``make(coef)``, cached in ``store[key]`` while ``coef`` has the same values.

    Keyed by the values (their bytes are kept), not by the array: a model's
    coefficients of its kept terms are a new array at every call, and a
    coefficient array changed in place must not find the old binding.
    Comparing bytes costs less than a random projection of the values (one
    state's evaluation pays it at every call).
    """
    values = np.ascontiguousarray(coef, dtype=float)
    stamp = (values.shape, values.tobytes())
    cached = store.get(key)
    if cached is not None and cached[0] == stamp:
        return cached[1]
    result = make(values)
    store[key] = (stamp, result)
    return result


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
    mixed : ndarray of shape (n_states,) of bool, default=None
        Which variables are mixed (:mod:`.mixed`: Legendre polynomials on
        their interval and Fourier terms of period ``2 pi``); None: none.
    """

    def __init__(self, domain, powers, periodic=None, mixed=None):
        self.domain = np.asarray(domain, dtype=float)
        self.powers = np.asarray(powers, dtype=np.intp)
        n_states = self.domain.shape[0]
        self.periodic = (
            np.zeros(n_states, dtype=bool) if periodic is None else np.asarray(periodic, bool)
        )
        self.mixed = np.zeros(n_states, dtype=bool) if mixed is None else np.asarray(mixed, bool)
        # Factors of the Fourier family: every factor of a periodic variable,
        # the negative codes of a mixed one.
        trig = self.periodic | (self.mixed & (self.powers < 0))
        magnitude = factor_degrees(self.powers, self.mixed)
        self.legendre_degree = int(magnitude[~trig].max(initial=0))
        self.fourier_degree = int(magnitude[trig].max(initial=0))
        #: Table column of every variable in every basis function.
        self.columns = np.where(self.periodic, fourier_column(self.powers), magnitude)
        if self.mixed.any():
            self.columns[:, self.mixed] = mixed_columns(
                self.powers[:, self.mixed], self.legendre_degree)
        self.width = max(self.legendre_degree + 1, 2 * self.fourier_degree + 1)
        if self.mixed.any():
            self.width = max(self.width, self.legendre_degree + 2 * self.fourier_degree + 1)
        self.layout = tensor.SlotLayout(self.columns, self.width)
        self.factor_tables = FactorTables(
            self.domain, self.periodic, self.legendre_degree, self.fourier_degree, self.width,
            self.mixed,
        )
        # Built on first use: (plan,), the flat plans by order, the
        # coefficient matrices of the last coefficients (cached_binding), the
        # derivative maps and the readable basis.
        self._contraction = None
        self._flat_plans = {}
        self._bindings = {}
        self._derivative_maps = None
        self._readable = None

    def __getstate__(self):
        # Caches are rebuilt on first use; keep pickles (joblib, dask) small.
        state = {**self.__dict__, "_contraction": None, "_flat_plans": {}, "_bindings": {},
                 "_derivative_maps": None, "_readable": None}
        state.pop("_kernel_tree", None)
        state.pop("_checked_kernel", None)
        return state

    def __setstate__(self, state):
        # Pickles of other versions may lack (or carry other) caches.
        self.__dict__.update(state)
        self._contraction, self._flat_plans, self._bindings = None, {}, {}
        self._derivative_maps = self._readable = None
        # Spaces pickled before mixed variables existed.
        self.__dict__.setdefault("mixed", np.zeros(self.domain.shape[0], dtype=bool))

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
        return int(factor_degrees(self.powers, self.mixed).sum(axis=1).max(initial=0))

    def codes_of_columns(self, columns):
        """Multi-indices of table columns (the inverse of ``columns``, for any rows)."""
        powers = np.where(self.periodic, fourier_frequency(columns), columns)
        if self.mixed.any():
            powers[:, self.mixed] = mixed_codes(columns[:, self.mixed], self.legendre_degree)
        return powers

    @property
    def has_fourier(self):
        """Whether some variable carries Fourier terms (periodic, or mixed with one)."""
        return bool(self.periodic.any() or (self.mixed.any() and self.fourier_degree > 0))

    @property
    def phase_rates(self):
        """Radians per unit of each variable turned by the fastest factor.

        ``2 pi K / P`` for a periodic variable of period ``P`` in a space of
        highest frequency ``K`` (``P = 2 pi`` for a mixed variable), 0 for
        the others: along a segment from ``x0``
        to ``x1`` no trigonometric factor turns through more than
        ``phase_rates @ |x1 - x0|`` (what the quadrature of the segment needs,
        :func:`~sk_hamiltonian._design.quadrature_nodes`).
        """
        period = np.where(self.mixed, MIXED_PERIOD, self.domain[:, 1] - self.domain[:, 0])
        return np.where(self.periodic | self.mixed, 2.0 * np.pi * self.fourier_degree / period,
                        0.0)

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

    def unwrap(self, Y, start):
        """Trajectories ``Y`` with the periodic variables continued from the chart of ``start``.

        ``Y`` has shape ``(..., n_times, n_states)``, its periodic variables
        wrapped into their period (as the integrators output them); each step
        is taken in ``[-P/2, P/2)`` and summed from ``start``, the states at
        the first time in the chart wanted (the data's). A NaN stays, and
        so does every later time of its trajectory.
        """
        Y = np.array(Y, dtype=float)
        if self.periodic.any():
            steps = self.wrap_difference(np.diff(Y, axis=-2))[..., self.periodic]
            start = np.broadcast_to(np.asarray(start, dtype=float),
                                    Y[..., 0, :].shape)[..., self.periodic]
            Y[..., 0, self.periodic] = start
            Y[..., 1:, self.periodic] = start[..., None, :] + np.cumsum(steps, axis=-2)
        return Y

    def outside(self, X, slack=0.0):
        """Rows of ``X`` with a non-periodic variable outside its interval."""
        return outside_domain(X, self.domain, self.periodic, slack)

    # ------------------------------------------------------------ evaluation
    # The kernels work terms-major (samples last); these methods return the
    # samples-first arrays the estimators use, as transposed views.
    def _plan(self):
        """The contraction plan, or None where scattering slots is cheaper (built once)."""
        if self._contraction is None:
            plan = None
            if self.layout.dense or self.n_terms == 0:
                plan = ContractionPlan(self.columns, self.width)
            else:
                candidate = ContractionPlan(self.columns, self.width)
                # Slot kernels cost about 4 passes over (n_terms, n_slots) per state.
                if candidate.cost <= 4 * self.n_terms * self.layout.n_slots:
                    plan = candidate
            self._contraction = (plan,)
        return self._contraction[0]

    def _flat(self, order, kernels="numpy", n_samples=1):
        """The flat plan of derivative ``order``, or None where the tree costs less.

        A small space (a sparse model's kept terms) pays mostly for the
        tree's fixed bookkeeping; its flat products cost less (see
        :mod:`.flat`). The plans are built once.
        """
        if order not in self._flat_plans:
            # Every function costs at least two multiply-adds: skip building
            # a plan that cannot win.
            tree = self._tree_cost(order)
            small = 0 < self.n_terms and choose_flat(2 * self.n_terms, tree, "numpy")
            self._flat_plans[order] = (
                (FlatPlan(self.columns, self.width, order), tree) if small else None)
        entry = self._flat_plans[order]
        if entry is None:
            return None
        flat, tree = entry
        return flat if choose_flat(flat.cost, tree, kernels, n_samples) else None

    def _tree_cost(self, order):
        """Multiply-adds per state of the tree (or slot) contraction up to ``order``."""
        plan = self._plan()
        if plan is not None:
            return plan.cost * (order + 1)
        return 4 * self.n_terms * self.layout.n_slots

    def _binding(self, key, coef, make):
        """``make(coef)``, cached on this space under ``key`` (:func:`cached_binding`)."""
        return cached_binding(self._bindings, key, coef, make)

    def _flat_bound(self, flat, coef):
        """:meth:`FlatPlan.bind` of ``coef``, cached (:func:`cached_binding`)."""
        return self._binding(("flat", flat.order), coef, flat.bind)

    def _flat_contract(self, flat, X, coef):
        """Patterns of ``flat`` at ``X``, samples first: (n_samples, n_patterns) + coef.shape[1:]."""
        tables = self.factor_tables(X, flat.order, evaluation=True)
        out = flat.contract(tables, self._flat_bound(flat, coef))  # (patterns, K, samples)
        out = out.transpose(2, 0, 1)
        return out[:, :, 0] if np.ndim(coef) == 1 else out

    def _bound(self, plan, coef):
        """The coefficient matrix of ``coef`` (:meth:`ContractionPlan.bind`), cached."""
        return self._binding("tree", coef, plan.bind)

    def _contract(self, X, coef, order):
        """Contraction results (n_patterns, K, n_samples) and patterns, or None."""
        plan = self._plan()
        if plan is None:
            return None
        tables = self.factor_tables(X, order, evaluation=True)
        return plan.contract(tables, self._bound(plan, coef), order)

    def values(self, X):
        """Values of the basis functions, ndarray of shape (n_samples, n_terms)."""
        return self.values_t(X).T

    def values_t(self, X, out=None):
        """Values of the basis functions, terms-major: ndarray (n_terms, n_samples), into ``out`` if given."""
        return tensor.values(self.factor_tables(X, 0), self.layout, out=out)

    def gradients(self, X):
        """Gradients of the basis functions, ndarray of shape (n_samples, n_states, n_terms)."""
        return np.transpose(self.gradients_t(X), (2, 1, 0))

    def gradients_t(self, X, out=None):
        """Gradients, terms-major: ndarray (n_terms, n_states, n_samples), into ``out`` if given."""
        return tensor.gradients(self.factor_tables(X, 1), self.layout, out=out)

    def readable_basis(self):
        """The change to the readable basis (:class:`.ReadableBasis`), built once."""
        if self._readable is None:
            self._readable = ReadableBasis(self.powers, self.domain, self.periodic, self.mixed)
        return self._readable

    def derivative_maps(self):
        """The gradient as maps onto a value basis (:class:`.DerivativeMaps`), built once."""
        if self._derivative_maps is None:
            self._derivative_maps = DerivativeMaps(self)
        return self._derivative_maps

    def gradient_rows_t(self, X, rows, outs):
        """``d phi_j / d x_i`` for the functions ``rows[i]``, into ``outs[i]`` (dense layouts).

        See :func:`.tensor.gradient_rows`; a design assembled by variable
        skips the functions that do not depend on it.
        """
        tensor.gradient_rows(self.factor_tables(X, 1), self.layout, rows, outs)

    def _compiled(self, X, coef, order):
        """:func:`.compiled.contract` shaped as the numpy path's results."""
        value, grad, hess = compiled.contract(self, X, coef, order)
        result = (value, grad, hess)[order]
        return result[..., 0] if np.ndim(coef) == 1 else result

    def value_dot(self, X, coef):
        """Values of ``sum_j coef[j] phi_j`` (``coef`` may have a trailing target axis)."""
        if use_numba():
            return self._compiled(X, coef, 0)
        flat = self._flat(0, n_samples=len(X))
        if flat is not None:
            return self._flat_contract(flat, X, coef)[:, 0]
        result = self._contract(X, coef, 0)
        if result is None:
            return self.values(X) @ coef
        values, _ = result
        values = values[0].T  # (n_samples, K)
        return values[:, 0] if np.ndim(coef) == 1 else values

    def gradient_dot(self, X, coef):
        """Gradient of ``sum_j coef[j] phi_j``, ndarray of shape (n_samples, n_states) + coef.shape[1:]."""
        if use_numba():
            return self._compiled(X, coef, 1)
        flat = self._flat(1, n_samples=len(X))
        if flat is not None:
            return self._flat_contract(flat, X, coef)  # patterns (i,) in order
        result = self._contract(X, coef, 1)
        if result is None:
            if np.ndim(coef) == 1:
                return tensor.gradient_dot(self.factor_tables(X, 1, evaluation=True), self.layout, coef).T
            return np.einsum("jis,jk->sik", self.gradients_t(X), coef)
        derivatives, _ = result
        rows = self._plan().rows(1, [(i,) for i in range(self.n_states)])
        grad = derivatives[rows].transpose(2, 0, 1)  # (n_samples, n_states, K)
        return grad[:, :, 0] if np.ndim(coef) == 1 else grad

    def hessian_dot(self, X, coef):
        """Hessian of ``sum_j coef[j] phi_j``, ndarray of shape (n_samples, n_states, n_states)."""
        if use_numba() and np.ndim(coef) == 1:
            return self._compiled(X, coef, 2)
        flat = self._flat(2, n_samples=len(X))
        if flat is not None and np.ndim(coef) == 1:
            upper = self._flat_contract(flat, X, coef)  # (i, j), i <= j, row by row
            i, j = np.triu_indices(self.n_states)
            H = np.empty((upper.shape[0], self.n_states, self.n_states))
            H[:, i, j] = upper
            H[:, j, i] = upper
            return H
        result = self._contract(X, coef, 2)
        if result is None:
            H = tensor.hessian_dot(self.factor_tables(X, 2, evaluation=True), self.layout, coef)
            return np.moveaxis(H, -1, 0)
        derivatives, patterns = result
        m = self.n_states
        second = [(k, p) for k, p in enumerate(patterns) if len(p) == 2]
        rows = np.array([k for k, _ in second])
        i, j = np.array([p for _, p in second]).T
        H = np.empty((derivatives.shape[-1], m, m))
        H[:, i, j] = derivatives[rows, 0].T
        H[:, j, i] = derivatives[rows, 0].T
        return H
