"""What the two regressors share: input handling, model space, simulation and scoring."""

import copy
import operator
import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context
from sklearn.utils import check_array
from sklearn.utils._available_if import available_if
from sklearn.utils._param_validation import Interval, InvalidParameterError, StrOptions
from sklearn.utils.validation import _check_sample_weight, check_is_fitted, validate_data

from ._design import TrainingData
from ._integrate import integrate, make_integrator, raise_on_failure
from ._kernels.threads import gram_flops, limit_blas
from ._least_squares import (
    CGNotConverged,
    LeastSquaresProblem,
    accumulated_solver,
    column_solver,
    fit_support,
)
from ._scoring import rollout_score
from ._solvers import NormalEquations, choose_solver, warn_if_ill_conditioned
from ._streaming import PartialFitState
from ._space import ModelSpace, index_set
from ._space.readable import ReadableBasis
from ._space.space import all_finite, count_outside
from ._trajectories import unpack_derivatives
from .exceptions import DomainWarning

# Rows of evaluations done at once, to bound memory (entries of float64).
BLOCK_ENTRIES = 10_000_000
# Relative slack for "outside the domain", so that training points on the
# bounding box do not warn after round-off.
DOMAIN_SLACK = 1e-9
# Thinnest interval of a domain: the map onto the basis window scales
# derivatives by 2 / width, Hessians and Gram products by its square, and
# 1e200 leaves room for both below overflow (1.8e308).
THINNEST_DOMAIN = 1e-100
# Default integration step as a fraction of the learned system's time scale
# 1 / rho (rho: spectral radius of its Jacobian over the training states):
# the global error of RK4 then stays near (0.1)**4 / 120 per unit of rho * t,
# that of the second-order methods near (0.02)**2 / 12.
STEP_FRACTION = {"rk4": 0.1, "yoshida4": 0.1, "avf": 0.02, "leapfrog": 0.02}
# Training states at which the Jacobian is evaluated for the time scale.
TIME_SCALE_SAMPLES = 256


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


def _is_dask(X):
    """Whether ``X`` is a dask collection (without importing dask)."""
    return type(X).__module__.split(".")[0] == "dask" and hasattr(X, "__dask_graph__")


class _ShapeOnly:
    """A chunk's data seen by ``_check_size`` only for its shapes (never underdetermined)."""

    def __init__(self, data):
        self.states, self.derivatives = data.states, data.derivatives

    def n_rows(self, fit_on):
        return np.inf


class BaseTrajectoryRegressor(RegressorMixin, BaseEstimator):
    """Linear models of ``dx/dt = f(x)`` in a tensor-product space, fitted by least squares.

    Subclasses define what is fitted through ``_fit_coef`` and
    ``_vector_field``, and which integrators they support through
    ``_dynamics``.
    """

    _parameter_constraints = {
        "degree": [Interval(Integral, 1, None, closed="left")],
        "domain": ["array-like", None],
        "periodic": ["array-like", None],
        "momentum_degree": [Interval(Integral, 0, None, closed="left"), None],
        "separable": ["boolean"],
        "max_interaction": [Interval(Integral, 1, None, closed="left"), None],
        "couplings": ["array-like", None],
        "fit_on": [StrOptions({"derivatives", "steps", "simpson"})],
        "threshold": [Interval(Real, 0, None, closed="left")],
        "solver": [StrOptions({"auto", "lstsq", "normal", "iterative", "sketch"})],
        "verbose": ["verbose"],
    }

    #: Whether the basis holds the constant (set by subclasses).
    _include_constant = False

    def __init__(
        self, degree=3, *, domain=None, periodic=None, momentum_degree=None,
        separable=False, max_interaction=None, couplings=None, fit_on="derivatives",
        threshold=0.0, solver="auto", verbose=0,
    ):
        self.degree = degree
        self.domain = domain
        self.periodic = periodic
        self.momentum_degree = momentum_degree
        self.separable = separable
        self.max_interaction = max_interaction
        self.couplings = couplings
        self.fit_on = fit_on
        self.threshold = threshold
        self.solver = solver
        self.verbose = verbose

    # ------------------------------------------------------------------ fit
    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None, sample_weight=None):
        """Fit the model to states and their time derivatives, or to trajectories.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states), or derivative layout
            Either states, with their time derivatives in ``y``, or the output
            of :class:`DerivativeTransformer` (a 3-D array or list of
            trajectories), whose states, derivatives and times are used.
        y : array-like of shape (n_samples, n_states) or None
            Time derivatives of the states in ``X``; None with the derivative
            layout.
        sample_weight : array-like of shape (n_samples,), default=None
            Weights of the states, or of the trajectories for the derivative
            layout (so that a pipeline in cross-validation passes one weight
            per trajectory). None weighs all equally.

        Returns
        -------
        self : object
            The fitted estimator.
        """
        self._check_integer_params()
        if _is_dask(X) or _is_dask(y):
            from ._distributed import fit_distributed

            return fit_distributed(self, X, y, sample_weight)
        self._partial = None
        data = self._training_data(X, y, sample_weight)
        n_rows = self._set_up_fit(data)
        # Small problems on one BLAS thread: thread start-up and, on a busy
        # machine, oversubscription cost more than they save.
        with limit_blas(gram_flops(n_rows, self._n_unknowns())):
            self._fit_coef(data)
        self._finish_fit(data)
        return self

    def _check_partial_fit(self):
        # partial_fit exists only with a fixed box: the basis (and so the
        # accumulated normal equations) lives on it.
        if self.domain is None:
            raise AttributeError(
                "partial_fit needs an explicit `domain` (one (low, high) row per state "
                "variable): the basis must stay on the same box for every chunk. Pass "
                "domain=..., or use fit."
            )
        return True

    @available_if(_check_partial_fit)
    def partial_fit(self, X, y=None, sample_weight=None):
        """Add a chunk of samples to the fit (normal equations accumulated across calls).

        Each call adds the chunk's normal equations ``A^T A`` and ``A^T b`` to
        those of the previous calls and solves them (Cholesky, as
        ``solver="normal"`` without its refinement, since earlier samples are
        gone), so that after the last chunk the coefficients are those of
        :meth:`fit` on all chunks together, to round-off on well-conditioned
        problems. Memory is ``O(n_terms**2)``, independent of the number of
        samples. Available only with an explicit ``domain``; the model-space
        parameters must not change between calls.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states), or derivative layout
            A chunk of states (with their derivatives in ``y``), or of
            trajectories in the derivative layout; with ``fit_on="steps"``
            or ``"simpson"`` each chunk holds whole trajectories.
        y : array-like of shape (n_samples, n_states) or None
            Time derivatives of the states; None with the derivative layout.
        sample_weight : array-like of shape (n_samples,), default=None
            Weights of the chunk's states (of its trajectories for the
            derivative layout).

        Returns
        -------
        self : object
            The estimator, with ``coef_`` and the other fitted attributes
            updated from all chunks so far; ``state_scale_`` over all samples,
            ``time_scale_`` from a random sample of them, ``dt_`` the median
            of the chunks' median steps, and the energy-trend attributes from
            the last chunk.
        """
        state = getattr(self, "_partial", None)
        if state is None:
            self._validate_params()
            self._check_integer_params()
            if self.solver not in ("auto", "normal"):
                raise ValueError(
                    f"partial_fit accumulates the normal equations, so it needs "
                    f"solver='auto' or 'normal'; got solver={self.solver!r}."
                )
        else:
            state.check_parameters(self)
        data = self._training_data(X, y, sample_weight, reset=state is None)
        if state is None:
            # Each chunk may be smaller than the number of unknowns: only the
            # accumulated equations must determine them.
            self._set_up_space(data, size_data=_ShapeOnly(data))
            state = PartialFitState(self, self._normal_accumulator(), data.states.shape[1])
        else:
            self._check_size(_ShapeOnly(data))
            # Frames: _warn_outside, partial_fit, its available_if wrapper.
            self._warn_outside(data.states, what="the training states", stacklevel=4)
        state.add(self, data, self._training_step(data))
        self._partial = state
        self._solve_accumulated(state, data)
        return self

    def _solve_accumulated(self, state, data, residual=None):
        """Solve accumulated normal equations and set every fitted attribute.

        ``state`` is a :class:`~sk_hamiltonian._streaming.PartialFitState`;
        ``data`` (one chunk) serves the energy-trend check; ``residual(keep)``
        optionally returns the refinement callback against the design.
        """
        solve, norms = accumulated_solver(*state.normal_equations(), residual)
        self._set_solution(self._fit_support(solve, norms))
        self.solver_ = "normal"
        self._finish_fit(
            data, scale=state.scale(), magnitude=state.magnitude(),
            time_scale_states=state.reservoir,
        )
        self.dt_ = state.training_step()

    def _set_up_space(self, data, size_data=None):
        """Check the data against the parameters and build the model space."""
        n_states = data.states.shape[1]
        self._check_dimensions(n_states)
        self.periodic_ = self._fit_periodic(n_states)
        self.powers_ = self._index_set(n_states)
        self._check_size(data if size_data is None else size_data)
        self.domain_ = self._fit_domain(
            data.states if data.sample_weight is None else data.states[data.sample_weight > 0]
        )
        self._space = ModelSpace(self.domain_, self.powers_, self.periodic_)

    def _finish_fit(self, data, scale=None, magnitude=None, time_scale_states=None):
        """Fitted attributes beyond the coefficients, from the training data."""
        warn_if_ill_conditioned(self.cond_, self.rank_, self._n_solved, type(self).__name__)
        self.dt_ = self._training_step(data)
        self.state_scale_ = self._state_scale(data.states) if scale is None else scale
        # Typical size of each variable, for ranking terms (inspection).
        self._state_magnitude = (
            np.sqrt(np.mean(data.states**2, axis=0)) if magnitude is None else magnitude
        )
        self.time_scale_ = self._time_scale(
            data.states if time_scale_states is None else time_scale_states
        )
        self._after_fit(data)

    def _check_integer_params(self):
        # scikit-learn's Interval(Integral) lets booleans through; True is no degree.
        for name in ("degree", "momentum_degree", "max_interaction"):
            value = getattr(self, name)
            if isinstance(value, (bool, np.bool_)):
                raise InvalidParameterError(
                    f"The {name!r} parameter of {type(self).__name__} must be an int, not "
                    f"a boolean; got {value!r}."
                )

    def _training_data(self, X, y, sample_weight, reset=True):
        """Validate the input and gather what the fit needs."""
        if not is_trajectory_container(X):
            # float64 throughout: one dtype for every fitted array (and model file).
            X, y = validate_data(self, X, y, multi_output=True, y_numeric=True, reset=reset,
                                 dtype=np.float64)
            weight = None if sample_weight is None else _check_sample_weight(sample_weight, X)
            return TrainingData(X, y, weight)
        if y is not None:
            raise ValueError(
                "y must be None when X is trajectory data: the time derivatives "
                "are part of the DerivativeTransformer output."
            )
        layout = unpack_derivatives(X)
        states, derivatives, times = list(layout.states), list(layout.derivatives), list(layout.times)
        lengths = [S.shape[0] for S in states]
        X2, y2 = validate_data(
            self, np.concatenate(states), np.concatenate(derivatives), multi_output=True,
            y_numeric=True, reset=reset, dtype=np.float64,
        )
        trajectory_weight = weight = None
        if sample_weight is not None:
            trajectory_weight = np.asarray(sample_weight, dtype=float)
            if trajectory_weight.shape != (len(states),):
                raise ValueError(
                    f"sample_weight must have one weight per trajectory, shape "
                    f"({len(states)},), when X is the derivative layout; got shape "
                    f"{trajectory_weight.shape}."
                )
            trajectory_weight = _check_sample_weight(trajectory_weight, states)
            weight = np.repeat(trajectory_weight, lengths)
        pieces = np.split(X2, np.cumsum(lengths)[:-1])
        return TrainingData(
            X2, y2, weight, trajectories=list(zip(times, pieces)),
            trajectory_weight=trajectory_weight,
        )

    def _fit_periodic(self, n_states):
        if self.periodic is None:
            return np.zeros(n_states, dtype=bool)
        periodic = np.asarray(self.periodic)
        if (
            periodic.shape != (n_states,)
            or not (periodic.dtype == bool or np.isin(periodic, (0, 1)).all())
        ):
            raise ValueError(
                f"periodic must be None or an array of {n_states} booleans, True for "
                f"each state variable that is an angle; got {self.periodic!r}."
            )
        return periodic.astype(bool)

    def _fit_domain(self, X):
        n_states = X.shape[1]
        if self.domain is None:
            if X.shape[0] < 2:
                raise ValueError(
                    f"Found n_samples={X.shape[0]} (with positive weight): at least 2 are "
                    f"needed, since the domain is their bounding box."
                )
            # An angle's default period is [-pi, pi); other variables take the
            # bounding box of the training states (those with positive weight).
            domain = np.column_stack([X.min(axis=0), X.max(axis=0)])
            domain[self.periodic_] = [-np.pi, np.pi]
            width = domain[:, 1] - domain[:, 0]
            scale = np.maximum(np.abs(domain).max(axis=1), np.finfo(float).tiny)
            flat = np.flatnonzero(width <= 1e-9 * scale)  # within round-off of the values
            if flat.size:
                raise ValueError(
                    f"State variable(s) {flat.tolist()} are constant in the training "
                    f"data (up to round-off), so the bounding box is empty; pass an "
                    f"explicit `domain` of shape ({n_states}, 2), or drop the "
                    f"variable(s)."
                )
            thin = np.flatnonzero(width < THINNEST_DOMAIN)
            if thin.size:
                raise ValueError(
                    f"State variable(s) {thin.tolist()} span less than {THINNEST_DOMAIN:g} "
                    f"in the training data ({width[thin].tolist()}): on so thin a "
                    f"bounding box (the default domain) the basis' derivatives overflow. "
                    f"Rescale the variable(s) to units in which they span about 1."
                )
            return domain
        domain = check_array(self.domain, input_name="domain", ensure_2d=False, dtype=np.float64)
        if domain.shape != (n_states, 2) or np.any(domain[:, 1] <= domain[:, 0]):
            raise ValueError(
                f"domain must have shape ({n_states}, 2) with one (low, high) row "
                f"per state variable and low < high; got {np.asarray(self.domain).tolist()}."
            )
        with np.errstate(over="ignore", invalid="ignore"):
            width = domain[:, 1] - domain[:, 0]
        thin = np.flatnonzero(~(width >= THINNEST_DOMAIN) | ~np.isfinite(width))
        if thin.size:
            raise ValueError(
                f"domain rows {thin.tolist()} are {width[thin].tolist()} wide: the "
                f"basis' derivatives overflow on an interval narrower than "
                f"{THINNEST_DOMAIN:g} (or one whose width is not finite). Rescale "
                f"the variable(s) to units in which they span about 1."
            )
        # Frames: _warn_outside, _fit_domain, fit, its _fit_context wrapper.
        self._warn_outside(X, domain, "the training states", stacklevel=5)
        return domain

    def _index_set(self, n_states):
        if (self.momentum_degree is not None or self.separable) and n_states % 2:
            raise ValueError(
                f"momentum_degree and separable need states (p_1..p_d, q_1..q_d) with an "
                f"even number of variables; X has {n_states}."
            )
        return index_set(
            n_states, self.degree, periodic=self._fit_periodic(n_states),
            momentum_degree=self.momentum_degree, separable=self.separable,
            max_interaction=self.max_interaction, couplings=self._couplings(n_states),
            include_constant=self._include_constant,
        )

    def _couplings(self, n_states):
        """``couplings`` as tuples of variable indices, checked against ``n_states``."""
        if self.couplings is None:
            return None
        groups = []
        for group in self.couplings:
            try:
                members = [operator.index(i) for i in group]
            except TypeError:
                members = None
            if (
                members is None or isinstance(group, str)
                or any(isinstance(i, (bool, np.bool_)) for i in group)
                or len(set(members)) < 2 or len(set(members)) != len(members)
                or not all(0 <= i < n_states for i in members)
            ):
                raise ValueError(
                    f"couplings must be a list of groups of state-variable indices, each "
                    f"naming at least two distinct variables in [0, {n_states}) (momenta "
                    f"first: p_1..p_d are 0..d-1, q_1..q_d are d..2d-1); got the group "
                    f"{group!r}. For nearest neighbours on a chain of d particles, pass "
                    f"[(d + i, d + i + 1) for i in range(d - 1)]."
                )
            groups.append(tuple(members))
        return groups

    def _n_terms(self, n_states):
        """Number of basis functions for data with ``n_states`` variables."""
        return self._index_set(n_states).shape[0]

    def _set_up_fit(self, data):
        """Model space and solver for ``data``; returns the number of equations."""
        self._set_up_space(data)
        n_rows = data.n_rows(self.fit_on) * self._rows_per_sample(data.states.shape[1])
        self.solver_ = choose_solver(
            self.solver, n_rows, self.powers_.shape[0],
            factored=lambda: self._factored_maps() is not None,
        )
        return n_rows

    def _least_squares_problem(self, data):
        """The design of a fit on ``data``, in the forms the solvers take."""
        return LeastSquaresProblem(
            lambda grouped=False: self._design_blocks(data, grouped=grouped),
            lambda: self._design_operator(data),
            lambda progress=None: self._accumulate(data, progress).result(),
            self._n_unknowns(), self._n_nonnegative(), groups=self._column_groups(),
        )

    def _accumulate(self, data, progress=None, accumulator=None):
        """``accumulator`` (default: a new :meth:`_normal_accumulator`) with ``data``'s blocks added."""
        if accumulator is None:
            accumulator = self._normal_accumulator()
        return accumulator.add_blocks(self._normal_blocks(data, accumulator), progress)

    def _fit_coef(self, data):
        """Solve the least-squares problem of ``data`` with ``solver_``; set the coefficients."""
        problem = self._least_squares_problem(data)
        name = type(self).__name__
        single_solve = self.threshold == 0 and not self._n_nonnegative()
        try:
            solve, norms = column_solver(
                problem, self.solver_, single_solve=single_solve,
                many_supports=self.threshold > 0, fall_back=self.solver == "auto",
                progress=self._progress("iteration {0}: relative normal residual {1:.2e}"),
                block_progress=self._progress("block {0}: {1} equations accumulated"),
                name=name,
            )
            solution = self._fit_support(solve, norms)
        except CGNotConverged:
            # The closed-form preconditioner assumes samples spread over the
            # box, a sketch a design well enough conditioned for its Gram
            # matrix; where that fails, fall back to the normal equations.
            self.solver_ = "normal"
            if self.verbose:
                print(f"[{name}] conjugate gradients did not converge; normal equations")
            solution = self._fit_support(*column_solver(
                problem, "normal",
                block_progress=self._progress("block {0}: {1} equations accumulated"), name=name,
            ))
        self._set_solution(solution)

    def _fit_threshold_path(self, X, thresholds):
        """Fitted copies of this estimator, one per threshold, from one assembly.

        Each equals ``clone(self).set_params(threshold=t).fit(X)`` up to
        round-off, but the design (and with ``solver="normal"`` its Gram
        matrix) is built once: a new support needs only a smaller solve.
        In-memory data only; the caller falls back to separate fits for dask
        arrays and when conjugate gradients do not converge.

        Parameters
        ----------
        X : derivative layout or array-like of shape (n_samples, n_states)
            What :meth:`fit` takes (2-D states need ``y``, which this path
            does not take: pass the derivative layout).
        thresholds : sequence of float
            Non-negative thresholds.

        Returns
        -------
        models : list of estimators
            Fitted, in the order of ``thresholds``.
        """
        self._validate_params()
        self._check_integer_params()
        self._partial = None
        data = self._training_data(X, None, None)
        n_rows = self._set_up_fit(data)
        problem = self._least_squares_problem(data)
        models = []
        with limit_blas(gram_flops(n_rows, self._n_unknowns())):
            solve, norms = column_solver(
                problem, self.solver_, many_supports=True, fall_back=self.solver == "auto",
                name=type(self).__name__,
            )
            for threshold in thresholds:
                model = copy.copy(self)
                model.threshold = float(threshold)
                model._set_solution(model._fit_support(solve, norms))
                model._finish_fit(data)
                models.append(model)
        return models

    def _fit_support(self, solve, column_norms):
        """The support rule of ``threshold`` over a column solver (see :mod:`._least_squares`)."""
        return fit_support(
            solve, column_norms, self._n_unknowns(), n_basis=self._space.n_terms,
            threshold=self.threshold, n_nonnegative=self._n_nonnegative(),
            readable=self._readable_basis() if self.threshold else None,
            name=type(self).__name__,
        )

    def _readable_basis(self):
        return ReadableBasis(self.powers_, self.domain_, self.periodic_)

    def _set_solution(self, solution):
        """Set the fitted coefficients, support and solve diagnostics from a Solution."""
        self.support_ = solution.support
        self.n_terms_ = int(solution.n_kept)
        self.n_iter_ = solution.n_iter
        self.cond_, self.rank_ = solution.cond, solution.rank
        self._n_solved = solution.n_solved
        self._set_coef(solution.coef)
        self._rebuild_fitted()

    def _rebuild_fitted(self):
        """Private state derived from the public fitted attributes.

        Called after every fit, and after loading a saved model: the model
        space of ``powers_`` on ``domain_``, and the smaller space of the kept
        terms that evaluation and simulation use, so that their cost follows
        ``support_``.
        """
        if getattr(self, "_space", None) is None:
            self._space = ModelSpace(self.domain_, self.powers_, self.periodic_)
        rows = self.support_ if self.support_.ndim == 1 else self.support_.any(axis=1)
        if rows.all():
            self._eval_space, self._eval_rows = self._space, None
        else:
            self._eval_space = ModelSpace(self.domain_, self.powers_[rows], self.periodic_)
            self._eval_rows = rows

    @property
    def _eval_coef(self):
        """Coefficients of the kept terms, read from ``coef_`` at each use (it may be set)."""
        return self.coef_ if self._eval_rows is None else self.coef_[self._eval_rows]

    def _progress(self, message):
        """A progress callback printing ``message`` when ``verbose`` (None when silent)."""
        if not self.verbose:
            return None
        name = type(self).__name__

        def report(*values):
            print(f"[{name}] " + message.format(*values), flush=True)

        return report

    def _training_step(self, data):
        """Median sampling step of the training trajectories (NaN without them)."""
        if data.trajectories is None:
            return float("nan")
        steps = np.concatenate([np.diff(t) for t, _ in data.trajectories])
        return float(np.median(steps)) if steps.size else float("nan")

    def _state_scale(self, states):
        scale = np.std(states, axis=0)
        # A constant variable (possible with an explicit domain) keeps unit scale.
        return np.where(scale > 0, scale, 1.0)

    def _time_scale(self, states):
        """``1 / rho``, rho the 90th percentile of the Jacobian's spectral radius."""
        jacobian = self._jacobian(states[:: max(1, states.shape[0] // TIME_SCALE_SAMPLES)])
        if jacobian is None:
            return float("nan")
        jacobian = jacobian[np.isfinite(jacobian).all(axis=(1, 2))]
        with np.errstate(all="ignore"):
            radius = np.abs(np.linalg.eigvals(jacobian)).max(axis=1)
        radius = radius[np.isfinite(radius)]
        rho = float(np.percentile(radius, 90)) if radius.size else 0.0
        return 1.0 / rho if rho > 0 else float("inf")

    # ------------------------------------------------------------ evaluation
    def _warn_outside(self, X, domain=None, what="X", stacklevel=3):
        domain = self.domain_ if domain is None else domain
        n_outside = count_outside(X, domain, self.periodic_, slack=DOMAIN_SLACK)
        self._warn_n_outside(n_outside, X.shape[0], domain, what, stacklevel + 1)

    def _warn_n_outside(self, n_outside, n_samples, domain=None, what="X", stacklevel=3):
        """The ``DomainWarning`` for ``n_outside`` of ``n_samples`` states (none for none)."""
        if n_outside:
            domain = self.domain_ if domain is None else domain
            warnings.warn(
                f"{n_outside / n_samples:.1%} of {what} lie outside the domain "
                f"{domain.tolist()}, where the model is not trusted.",
                DomainWarning,
                stacklevel=stacklevel,
            )

    def _check_states(self, X):
        """Validate states of shape (..., n_states); return them 2-D and the lead shape."""
        if hasattr(X, "columns") or np.ndim(X) == 2:
            X = self._validate_states(X)
            return X, X.shape[:-1]
        X = np.asarray(X)
        if X.ndim < 2 or X.shape[-1] != self.n_features_in_:
            raise ValueError(
                f"X must have shape (..., {self.n_features_in_}): states on the last axis, "
                f"as in fit; got shape {X.shape}. For a single state x, pass x[None]."
            )
        flat = check_array(X.reshape(-1, X.shape[-1]), ensure_min_samples=1)
        return flat, X.shape[:-1]

    def _in_blocks(self, X, fun, width):
        """Apply ``fun`` to row blocks of ``X`` small enough to bound memory."""
        size = max(1, BLOCK_ENTRIES // max(1, width))
        if X.shape[0] <= size:
            return fun(X)
        return np.concatenate([fun(X[i : i + size]) for i in range(0, X.shape[0], size)])

    def _check_fitted(self):
        """``check_is_fitted(self)``, short-cut for a model that has ``coef_``.

        ``check_is_fitted`` reads the tags and every attribute's name (about
        15 us, as long as the compiled prediction of one state); a model with
        ``coef_`` is fitted, and any other goes the full way to its error.
        """
        if "coef_" not in self.__dict__:
            check_is_fitted(self)

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
        self._check_fitted()
        checked = self._checked_prediction(X)
        if checked is not None:
            dXdt, n_outside = checked
            self._warn_n_outside(n_outside, X.shape[0])
            return dXdt
        if is_trajectory_container(X):
            states = unpack_derivatives(X).states
            if isinstance(states, np.ndarray):
                return self.predict(states.reshape(-1, states.shape[-1])).reshape(states.shape)
            return [self.predict(s) for s in states]
        X = self._validate_states(X)
        self._warn_outside(X)
        return self._vector_field(X)

    def _checked_prediction(self, X):
        """``(dXdt, n_outside)`` of a few states in one compiled call, or None.

        What ``predict`` does for a few states (validation, domain check,
        field) costs more in Python than the compiled field itself; a model
        that can do it in one compiled call overrides this. None means the
        general path (and its errors).
        """
        return None

    def _validate_states(self, X):
        """``validate_data(self, X, reset=False)``, short-cut for a plain finite float64 array.

        For such an array (no feature names at fit) the validation returns
        it unchanged; its generic path costs about ten times the prediction
        of one state.
        """
        if (
            type(X) is np.ndarray and X.dtype == np.float64 and X.ndim == 2
            and X.shape[0] > 0 and X.shape[1] == self.n_features_in_
            and not hasattr(self, "feature_names_in_") and all_finite(X)
        ):
            return X
        return validate_data(self, X, reset=False)

    # ------------------------------------------------------------ simulation
    def _integrator(self, method=None):
        return make_integrator(self._default_method() if method is None else method,
                               self._dynamics())

    def _default_method(self):
        # A fit on steps learns the averaged-vector-field map at the data step.
        return "avf" if self.fit_on == "steps" else "rk4"

    def _default_step(self, method):
        """The step ``simulate`` takes when ``max_step`` is None."""
        if self.fit_on == "steps" and method == "avf" and np.isfinite(self.dt_):
            return self.dt_
        return STEP_FRACTION[method] * self.time_scale_

    def simulate(self, x0, t, *, method=None, max_step=None, on_failure="raise"):
        """Integrate the learned system from one or several initial states.

        Parameters
        ----------
        x0 : array-like of shape (n_states,) or (n_initial, n_states)
            Initial state(s), taken at time ``t[0]``.
        t : array-like of shape (n_times,)
            Strictly increasing output times.
        method : {"rk4", "avf", "leapfrog", "yoshida4"}, default=None
            ``"rk4"``: classical Runge-Kutta (the paper's solver).
            ``"avf"``: averaged vector field, which conserves the learned
            Hamiltonian to round-off at any step size (and dissipates it
            exactly as the model does, with damping);
            :class:`HamiltonianRegressor` only. ``"leapfrog"`` (order 2) and
            ``"yoshida4"`` (order 4): explicit symplectic methods for
            separable models (``separable=True``). None: ``"avf"`` for a model
            fitted with ``fit_on="steps"``, else ``"rk4"``.
        max_step : float, default=None
            Largest integration step; each interval of ``t`` is split into the
            fewest equal steps no longer than this. None chooses it from the
            fitted model: the training step ``dt_`` for the AVF method of a
            model fitted on steps, else a fraction of the learned system's
            time scale ``time_scale_`` (0.1 for the fourth-order methods, 0.02
            for the second-order ones), which keeps the integration error far
            below the model's error. ``numpy.inf`` steps from one output time
            to the next.
        on_failure : {"raise", "nan"}, default="raise"
            What happens when a trajectory becomes non-finite or an implicit
            step does not converge: ``"raise"`` a :class:`SimulationError`;
            ``"nan"`` fill that trajectory with NaN from the first output time
            it could not reach on (the other trajectories are unaffected), for
            studies of where and when models fail.

        Returns
        -------
        X : ndarray of shape (n_times, n_states) or (n_initial, n_times, n_states)
            The trajectories, sampled at ``t``; periodic variables are wrapped
            into their period.

        Raises
        ------
        SimulationError
            If a trajectory became non-finite or an implicit step did not
            converge, with ``on_failure="raise"``.
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
        if max_step is not None and not (
            isinstance(max_step, Real) and not isinstance(max_step, bool) and max_step > 0
        ):
            raise ValueError(
                f"max_step must be a positive number, numpy.inf, or None; got {max_step!r}."
            )
        integrator = self._integrator(method)
        if max_step is None:
            max_step = self._default_step(integrator.name)
        if on_failure not in ("raise", "nan"):
            raise ValueError(f"on_failure must be 'raise' or 'nan'; got {on_failure!r}.")
        # Many small products: one BLAS thread.
        with limit_blas(0):
            Y, failed_at = integrate(integrator, x0, t, max_step)
        if on_failure == "raise":
            raise_on_failure(failed_at, t, what=f"the learned system ({type(self).__name__})")
        Y = np.swapaxes(Y, 0, 1)
        reached = np.arange(t.shape[0])[None, :] < failed_at[:, None]
        Y[~reached] = np.nan
        self._warn_outside(Y[reached], what="the simulated states", stacklevel=3)
        return Y[0] if single else Y

    # --------------------------------------------------------------- scoring
    def score(self, X, y=None, sample_weight=None):
        """Accuracy of rollouts against observed trajectories (or R² of derivatives).

        With the derivative layout (what a pipeline passes on), each held-out
        trajectory's initial state is fitted under the model by least squares
        to its observations (one Gauss-Newton step from its first observation,
        kept only if it fits better), and the rollout from it over the time
        stamps is compared with the observations. Its error ``e_k`` is the
        root-mean-square difference, each state variable divided by its
        standard deviation over the training states (``state_scale_``). From
        it the score subtracts a noise floor ``f_k``, estimated from the raw
        observations alone by polynomial fits in time, and is
        ``1 - mean_k (min(1, e_k) - f_k)``: a model as good as the noise lets
        the data tell scores about 1 (a little more, by chance), and a rollout
        that fails or strays by more than the spread of the data costs 1. The floor is the same for every candidate on a
        fold, so it changes no
        ranking; it removes from the fold scores the spread that comes from
        how noisy each fold's trajectories are, so that the standard errors of
        a search show model differences. The score does not change when the
        data are translated or the clock is shifted, and neither
        the derivatives nor the smoothed states enter, so tuning the
        derivative estimator cannot game it. With 2-D states ``X`` and
        derivatives ``y``, the usual :func:`~sklearn.metrics.r2_score` of the
        predicted derivatives.

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
            Greater is better; about 1 at the noise floor.
        """
        if not is_trajectory_container(X):
            if y is None:
                raise ValueError(
                    "score needs y, the time derivatives of X, for 2-D states X; or pass "
                    "trajectories in the derivative layout (the DerivativeTransformer "
                    "output), whose rollouts are scored."
                )
            return super().score(X, y, sample_weight=sample_weight)
        check_is_fitted(self)
        return rollout_score(self, X, sample_weight)

    # ------------------------------------------------------------------ hooks
    def _check_dimensions(self, n_states):
        """Hook: reject state dimensions the model cannot handle."""

    def _check_size(self, data):
        """Hook: reject problems the model cannot fit."""

    def _rows_per_sample(self, n_states):
        raise NotImplementedError

    def _design_blocks(self, data, grouped=False):
        """Row blocks of the design (grouped: ``(A, b, group)`` for the accumulator)."""
        raise NotImplementedError

    def _design_operator(self, data):
        """The design as a :class:`~sk_hamiltonian._design_operator.DesignOperator`."""
        raise NotImplementedError

    def _column_groups(self):
        """Columns each group of rows of the grouped design touches; None: one group of all."""
        raise NotImplementedError

    def _normal_accumulator(self):
        """An empty accumulator of the design's normal equations (see :meth:`_normal_blocks`).

        Here a :class:`~sk_hamiltonian._solvers.NormalEquations` with the
        design's groups.
        """
        return NormalEquations(self._n_unknowns(), self._column_groups())

    def _factored_maps(self):
        """The maps of a design whose normal equations are factored (:mod:`._factored`), or None."""
        return None

    def _normal_blocks(self, data, accumulator):
        """The blocks of ``data`` that ``accumulator`` (from :meth:`_normal_accumulator`) takes."""
        return self._design_blocks(data, grouped=True)

    def _n_unknowns(self):
        """Columns of the design."""
        raise NotImplementedError

    def _n_nonnegative(self):
        """How many of the last unknowns are constrained to be >= 0."""
        return 0

    def _set_coef(self, coef):
        """Set the fitted coefficients from the solution vector."""
        raise NotImplementedError

    def _vector_field(self, X):
        raise NotImplementedError

    def _jacobian(self, X):
        """Jacobians of the learned field at ``X`` (None where there is none)."""
        return None

    def _dynamics(self):
        raise NotImplementedError

    def _after_fit(self, data):
        """Hook: checks of the fitted model against its training data."""

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.three_d_array = True
        tags.target_tags.required = True
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = False
        return tags
