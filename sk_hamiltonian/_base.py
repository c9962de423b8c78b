"""What the two regressors share: input handling, domain, simulation and scoring."""

import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context
from sklearn.utils import check_array
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted, validate_data

from ._integrate import integrate, raise_on_failure
from ._scoring import multistep_errors
from ._solvers import choose_solver, warn_if_ill_conditioned
from ._trajectories import unpack_derivatives
from .exceptions import DomainWarning

# Rows of gradients assembled at once, to bound memory (entries of float64).
BLOCK_ENTRIES = 10_000_000
# Relative slack for "outside the domain", so that training points on the
# bounding box do not warn after round-off.
DOMAIN_SLACK = 1e-9


def is_trajectory_container(X):
    """Whether ``X`` is a 3-D array or a list of 2-D arrays (trajectories)."""
    if hasattr(X, "ndim") and not hasattr(X, "columns"):
        return X.ndim == 3
    if isinstance(X, (list, tuple)) and len(X) > 0:
        return np.ndim(X[0]) == 2
    return False


def check_time(t):
    """Validate output times: 1-D, finite, strictly increasing."""
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 1:
        raise ValueError(f"t must be a non-empty 1-D array of times; got shape {t.shape}.")
    if not np.isfinite(t).all():
        raise ValueError("t contains NaN or infinity.")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing.")
    return t


class BaseTrajectoryRegressor(RegressorMixin, BaseEstimator):
    """Polynomial models of ``dx/dt = f(x)`` on a box, fitted by least squares.

    Subclasses define the model space through ``_fit_coef`` and
    ``_vector_field``, and the integrators they support through ``_integrator``.
    """

    _parameter_constraints = {
        "degree": [Interval(Integral, 1, None, closed="left")],
        "domain": ["array-like", None],
        "solver": [StrOptions({"auto", "lstsq", "normal"})],
    }

    def __init__(self, degree=3, *, domain=None, solver="auto"):
        self.degree = degree
        self.domain = domain
        self.solver = solver

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Fit the model to states and their time derivatives.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states), or derivative layout
            Either states, with their time derivatives in ``y``, or the output
            of :class:`DerivativeTransformer` (a 3-D array or list of
            trajectories), whose states and derivatives are used.
        y : array-like of shape (n_samples, n_states) or None
            Time derivatives of the states in ``X``; None with the derivative
            layout.

        Returns
        -------
        self : object
            The fitted estimator.
        """
        if is_trajectory_container(X):
            if y is not None:
                raise ValueError(
                    "y must be None when X is trajectory data: the time derivatives "
                    "are part of the DerivativeTransformer output."
                )
            data = unpack_derivatives(X)
            X = np.concatenate(list(data.states))
            y = np.concatenate(list(data.derivatives))
        X, y = validate_data(self, X, y, multi_output=True, y_numeric=True)
        self._check_dimensions(X)
        n_rows, n_terms = self._design_shape(X.shape[0], X.shape[1])
        if n_rows < n_terms:
            raise ValueError(
                f"X has n_samples={X.shape[0]}, which gives {n_rows} equations for "
                f"{n_terms} unknowns at degree={self.degree}: the least-squares problem "
                f"is underdetermined. Provide more samples (more or longer "
                f"trajectories) or lower `degree`."
            )
        self._check_targets(X, y)
        self.domain_ = self._fit_domain(X)
        self.solver_ = choose_solver(self.solver, n_rows, n_terms)
        self._fit_coef(X, y)
        warn_if_ill_conditioned(self.cond_, self.rank_, n_terms, type(self).__name__)
        self.n_terms_ = int(np.size(self.coef_))
        return self

    def _fit_domain(self, X):
        if self.domain is None:
            domain = np.column_stack([X.min(axis=0), X.max(axis=0)])
            flat = np.flatnonzero(domain[:, 1] <= domain[:, 0])
            if flat.size:
                raise ValueError(
                    f"State variable(s) {flat.tolist()} are constant in the training "
                    f"data, so the bounding box is empty; pass an explicit `domain` "
                    f"of shape ({X.shape[1]}, 2)."
                )
            return domain
        domain = check_array(self.domain, input_name="domain")
        if domain.shape != (X.shape[1], 2) or np.any(domain[:, 1] <= domain[:, 0]):
            raise ValueError(
                f"domain must have shape ({X.shape[1]}, 2) with one (low, high) row "
                f"per state variable and low < high; got {domain.tolist()}."
            )
        # Frames: _warn_outside, _fit_domain, fit, its _fit_context wrapper.
        self._warn_outside(X, domain, "the training states", stacklevel=5)
        return domain

    def _warn_outside(self, X, domain=None, what="X", stacklevel=3):
        domain = self.domain_ if domain is None else domain
        slack = DOMAIN_SLACK * (domain[:, 1] - domain[:, 0])
        outside = np.any((X < domain[:, 0] - slack) | (X > domain[:, 1] + slack), axis=1)
        if outside.any():
            warnings.warn(
                f"{outside.mean():.1%} of {what} lie outside the domain "
                f"{domain.tolist()}, where the polynomial model is not trusted.",
                DomainWarning,
                stacklevel=stacklevel,
            )

    def _check_states(self, X):
        """Validate states of shape (..., n_states); return them 2-D and the lead shape."""
        if hasattr(X, "columns") or np.ndim(X) == 2:
            X = validate_data(self, X, reset=False)
            return X, X.shape[:-1]
        X = np.asarray(X, dtype=float)
        if X.ndim < 1 or X.shape[-1] != self.n_features_in_:
            raise ValueError(
                f"X must have {self.n_features_in_} state variables on its last axis, "
                f"as in fit; got shape {X.shape}."
            )
        flat = check_array(X.reshape(-1, X.shape[-1]), ensure_min_samples=1)
        return flat, X.shape[:-1]

    def _in_blocks(self, X, fun, width):
        """Apply ``fun`` to row blocks of ``X`` small enough to bound memory."""
        size = max(1, BLOCK_ENTRIES // max(1, width))
        if X.shape[0] <= size:
            return fun(X)
        return np.concatenate([fun(X[i : i + size]) for i in range(0, X.shape[0], size)])

    def predict(self, X):
        """Time derivatives of the learned system at the given states.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states), or derivative layout
            States, or the output of :class:`DerivativeTransformer`.

        Returns
        -------
        dXdt : ndarray of shape (n_samples, n_states)
            The learned vector field; for the derivative layout, an array of
            shape (n_trajectories, n_times, n_states) (a list if it was a list),
            evaluated at the layout's states.
        """
        check_is_fitted(self)
        if is_trajectory_container(X):
            states = unpack_derivatives(X).states
            if isinstance(states, np.ndarray):
                return self.predict(states.reshape(-1, states.shape[-1])).reshape(states.shape)
            return [self.predict(s) for s in states]
        X = validate_data(self, X, reset=False)
        self._warn_outside(X)
        return self._vector_field(X)

    def simulate(self, x0, t, *, method="rk4", max_step=None):
        """Integrate the learned system from one or several initial states.

        Parameters
        ----------
        x0 : array-like of shape (n_states,) or (n_initial, n_states)
            Initial state(s), taken at time ``t[0]``.
        t : array-like of shape (n_times,)
            Strictly increasing output times.
        method : {"rk4", "avf"}, default="rk4"
            ``"rk4"``: classical Runge-Kutta (the paper's solver).
            ``"avf"``: averaged vector field, which conserves the learned
            Hamiltonian to round-off at any step size
            (:class:`HamiltonianRegressor` only).
        max_step : float, default=None
            Largest integration step; each interval of ``t`` is split into the
            fewest equal steps no longer than this. None steps from one output
            time to the next.

        Returns
        -------
        X : ndarray of shape (n_times, n_states) or (n_initial, n_times, n_states)
            The trajectories, sampled at ``t``.

        Raises
        ------
        SimulationError
            If a trajectory became non-finite or an implicit step did not converge.
        """
        check_is_fitted(self)
        x0 = np.asarray(x0, dtype=float)
        single = x0.ndim == 1
        x0 = np.atleast_2d(x0)
        if x0.ndim != 2 or x0.shape[1] != self.n_features_in_:
            raise ValueError(
                f"x0 must have shape ({self.n_features_in_},) or (n_initial, "
                f"{self.n_features_in_}); got {np.shape(x0)}."
            )
        if not np.isfinite(x0).all():
            raise ValueError("x0 contains NaN or infinity.")
        t = check_time(t)
        if max_step is not None and not (isinstance(max_step, Real) and max_step > 0):
            raise ValueError(f"max_step must be a positive number or None; got {max_step!r}.")
        Y, failed_at = integrate(self._integrator(method), x0, t, max_step)
        raise_on_failure(failed_at, t, what=f"the learned system ({type(self).__name__})")
        Y = np.swapaxes(Y, 0, 1)
        self._warn_outside(Y.reshape(-1, Y.shape[-1]), what="the simulated states", stacklevel=3)
        return Y[0] if single else Y

    def score(self, X, y=None, sample_weight=None):
        """Accuracy of rollouts against observed trajectories (or R² of derivatives).

        With the derivative layout (what a pipeline passes on), each trajectory
        is integrated from its first *observed* state over its time stamps and
        compared with its observations; the score is
        ``1 - mean_k min(1, ||X_hat_k - X_k|| / ||X_k||)`` (Frobenius norms per
        trajectory), so 1 is perfect and a rollout that fails or strays by more
        than the size of the data scores 0. Neither the derivatives nor the
        smoothed states enter, so tuning the derivative estimator cannot game it.
        With 2-D states ``X`` and derivatives ``y``, the usual
        :func:`~sklearn.metrics.r2_score` of the predicted derivatives.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states), or derivative layout
            Test data.
        y : array-like of shape (n_samples, n_states) or None
            Time derivatives for 2-D ``X``; None with the derivative layout.
        sample_weight : array-like of shape (n_samples,), default=None
            Weights of the samples (of the trajectories, for the layout).

        Returns
        -------
        score : float
            Greater is better; at most 1.
        """
        if not is_trajectory_container(X):
            return super().score(X, y, sample_weight=sample_weight)
        check_is_fitted(self)
        errors = multistep_errors(self, X)
        return float(1.0 - np.average(np.minimum(errors, 1.0), weights=sample_weight))

    def _check_dimensions(self, X):
        """Hook: reject state dimensions the model cannot handle."""

    def _check_targets(self, X, y):
        """Hook: reject targets that are not time derivatives of X."""

    def _design_shape(self, n_samples, n_states):
        raise NotImplementedError

    def _fit_coef(self, X, y):
        raise NotImplementedError

    def _vector_field(self, X):
        raise NotImplementedError

    def _integrator(self, method):
        raise NotImplementedError

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.three_d_array = True
        tags.target_tags.required = True
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = False
        return tags
