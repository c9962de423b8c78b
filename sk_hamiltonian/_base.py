"""What the two regressors share: parameters, input validation, the public methods, the tags.

Each job behind the public methods has a home of its own: the checks of
parameters and inputs, with the warnings about states outside the domain
(:mod:`._validation`), the four steps of a fit (:mod:`._fit_steps`, each
callable without ``fit``), the model space (:mod:`._space.builder`), the
least-squares problem and its support (:mod:`._least_squares`), simulation
(:mod:`._simulate`), scoring (:mod:`._scoring`), ``partial_fit``
(:mod:`._streaming`) and the dask fit (:mod:`._distributed`).
"""

from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, RegressorMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from . import _fit_steps as steps
from . import _simulate
from . import _validation as validation
from ._distributed import fit_distributed, is_dask
from ._least_squares import solve
from ._outliers import warn_residual_outliers
from ._resampling import RESAMPLE_KINDS, check_resampling, fit_resamples
from ._scoring import rollout_score
from ._space import ModelSpace
from ._space.builder import space_size
from ._state_order import swap_couplings, swap_halves, swap_layout
from ._streaming import available_with_domain, partial_fit_chunk
from ._threads import gram_flops, limit_blas
from ._trajectories import is_trajectory_container, unpack_derivatives

# Rows of evaluations done at once, to bound memory (entries of float64).
BLOCK_ENTRIES = 10_000_000


class BaseTrajectoryRegressor(RegressorMixin, BaseEstimator):
    """Linear models of ``dx/dt = f(x)`` in a tensor-product space, fitted by least squares.

    Subclasses say what is fitted through ``_design`` (a
    :class:`~sk_hamiltonian._least_squares.Design`) and ``_set_coef``, how
    the learned field is evaluated (``_vector_field``, ``_jacobian``), and
    which integrators they support through ``_dynamics``. ``fit`` runs the
    four steps of :mod:`sk_hamiltonian._fit_steps`.
    """

    _parameter_constraints = {
        "degree": [Interval(Integral, 1, None, closed="left")],
        "domain": ["array-like", None],
        "periodic": ["array-like", None],
        "mixed": ["array-like", None],
        "momentum_degree": [Interval(Integral, 0, None, closed="left"), None],
        "separable": ["boolean"],
        "max_interaction": [Interval(Integral, 1, None, closed="left"), None],
        "couplings": ["array-like", None],
        "fit_on": [StrOptions({"derivatives", "steps", "simpson", "weak"})],
        "threshold": [Interval(Real, 0, None, closed="left")],
        "solver": [StrOptions({"auto", "lstsq", "normal", "iterative", "sketch"})],
        "verbose": ["verbose"],
        "n_resamples": [Interval(Integral, 0, None, closed="left")],
        "resample": [StrOptions(set(RESAMPLE_KINDS))],
        "random_state": ["random_state"],
        "n_jobs": [Integral, None],
    }

    #: Whether the basis holds the constant (set by subclasses).
    _include_constant = False

    def __init__(
        self, degree=3, *, domain=None, periodic=None, mixed=None, momentum_degree=None,
        separable=False, max_interaction=None, couplings=None, fit_on="derivatives",
        threshold=0.0, solver="auto", verbose=0, n_resamples=0, resample="bootstrap",
        random_state=None, n_jobs=None,
    ):
        self.degree = degree
        self.domain = domain
        self.periodic = periodic
        self.mixed = mixed
        self.momentum_degree = momentum_degree
        self.separable = separable
        self.max_interaction = max_interaction
        self.couplings = couplings
        self.fit_on = fit_on
        self.threshold = threshold
        self.solver = solver
        self.verbose = verbose
        self.n_resamples = n_resamples
        self.resample = resample
        self.random_state = random_state
        self.n_jobs = n_jobs

    # ---------------------------------------------------------- state order
    def _swapped(self):
        """Whether the user's columns are ``(q, p)`` (``state_order="qp"``).

        The model works in ``(p, q)`` order throughout; with ``"qp"`` every
        state-shaped input is exchanged into it and every output back. A
        regressor without the parameter reads states as ``(p, q)``.
        """
        return getattr(self, "state_order", "pq") == "qp"

    def _to_model(self, states):
        """States (last axis) in the user's column order as the model's ``(p, q)``.

        The exchange of the halves is its own inverse, so this also takes the
        model's outputs back to the user's order.
        """
        return swap_halves(states) if self._swapped() else states

    def _layout_to_model(self, Xt):
        """The derivative layout ``Xt`` with its states in the model's order."""
        return swap_layout(Xt) if self._swapped() else Xt

    def _state_parameter(self, name):
        """A per-state parameter (``domain``, ``periodic``, ``mixed``, ``couplings``) in model order.

        They are given in the user's column order, like ``X`` and
        ``state_names``; the fit reads them in the model's ``(p, q)`` order.
        """
        value = getattr(self, name)
        if value is None or not self._swapped():
            return value
        if name == "couplings":
            return swap_couplings(value, getattr(self, "n_features_in_", 0))
        array = np.asarray(value)
        return value if array.ndim == 0 else swap_halves(array, axis=0)

    @property
    def _fit_target(self):
        """What the least-squares fit matches: a fit on trajectories starts from the derivatives."""
        return "derivatives" if self.fit_on == "trajectories" else self.fit_on

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

        Raises
        ------
        ValueError
            Before anything large is built: if the fit would need more memory
            than ``memory_limit`` (:func:`~sk_hamiltonian.set_config`; the
            message names the degree, the unknowns, the memory and the
            remedies), or the states or derivatives exceed ``1e100`` in
            magnitude (rescale them), or a ``periodic`` or ``mixed``
            variable moves more than a quarter period per sample along the
            trajectories (rescale it to radians, or unmark it); and for every
            parameter that does not fit the data.

        Warns
        -----
        OutlierWarning
            After a fit on trajectories, naming those whose residuals are far
            outside the rest (a robust rule on each trajectory's residual).
        """
        self._check_integer_params()
        self._clear_resampled()
        self._clear_trajectory_fit()
        if self.fit_on == "trajectories":
            self._check_trajectory_input(X, y, sample_weight)
        if is_dask(X) or is_dask(y):
            validation.check_no_resampling(self, "a fit on dask arrays")
            validation.check_no_swap(self, "a fit on dask arrays")
            return fit_distributed(self, X, y, sample_weight)
        self._partial = None
        data = self._training_data(X, y, sample_weight)
        if self.n_resamples:
            check_resampling(self, data)
        space = steps.build_space(self, data)
        design = self._design(space)
        solver = steps.choose(self, design, data)
        # Small problems on one BLAS thread: thread start-up and, on a busy
        # machine, oversubscription cost more than they save.
        with limit_blas(gram_flops(design.n_rows(data), design.n_columns)):
            # The solver under the support rule; with "normal", the steps (b)
            # and (c) of _fit_steps.
            solution, solver = solve(
                design.problem(data), solver, steps.support_rule(self, space),
                fall_back=self.solver == "auto", progress=self._progress,
                name=type(self).__name__,
            )
        steps.set_fitted(self, space, solution, data, solver=solver)
        if self.n_resamples:
            # Refits on resampled trajectories, from the normal equations of
            # each trajectory (one more pass over the data; _resampling).
            with limit_blas(gram_flops(design.n_rows(data), design.n_columns)):
                self._set_resampled(fit_resamples(self, space, data))
        if self.fit_on == "trajectories":
            self._fit_trajectories(X)
        return self

    def _check_trajectory_input(self, X, y, sample_weight):
        """Refuse what a fit on trajectories cannot take, before anything is fitted."""
        raise ValueError(
            f"{type(self).__name__} has no fit on trajectories: use fit_on='derivatives', "
            f"'steps', 'simpson' or 'weak', or a HamiltonianRegressor."
        )

    def _fit_trajectories(self, X):
        """The fit on the raw trajectories after the least-squares start (subclasses)."""

    def _clear_trajectory_fit(self):
        """Drop the attributes of an earlier fit on trajectories."""
        for name in ("trajectory_fit_status_", "noise_", "trajectory_misfit_",
                     "coef_covariance_"):
            self.__dict__.pop(name, None)

    def _clear_resampled(self):
        """Drop the resampling of an earlier fit (a refit with ``n_resamples=0`` has none)."""
        for name in ("resampled_coef_", "resampled_damping_"):
            self.__dict__.pop(name, None)

    @available_with_domain
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
        validation.check_no_resampling(self, "partial_fit")
        self._clear_resampled()
        return partial_fit_chunk(self, X, y, sample_weight)

    def _n_terms(self, n_states):
        """Number of basis functions for data with ``n_states`` variables (counted, not built)."""
        return space_size(n_states, **steps.space_parameters(self))

    def _rebuild_fitted(self):
        """Private state derived from the public fitted attributes.

        Called after every fit, and after loading a saved model: the model
        space of ``powers_`` on ``domain_``, and the smaller space of the kept
        terms that evaluation and simulation use, so that their cost follows
        ``support_``.
        """
        if getattr(self, "_space", None) is None:
            self._space = ModelSpace(self.domain_, self.powers_, self.periodic_, self._mixed())
        rows = self.support_ if self.support_.ndim == 1 else self.support_.any(axis=1)
        if rows.all():
            self._eval_space, self._eval_rows = self._space, None
        else:
            self._eval_space = ModelSpace(self.domain_, self.powers_[rows], self.periodic_,
                                          self._mixed())
            self._eval_rows = rows

    def _mixed(self):
        """``mixed_``, or none mixed for a model saved before mixed variables existed."""
        mixed = getattr(self, "mixed_", None)
        return np.zeros(self.n_features_in_, dtype=bool) if mixed is None else mixed

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

    # ----------------------------------------------------------- validation
    def _check_integer_params(self):
        validation.check_integer_params(self)

    def _training_data(self, X, y, sample_weight, reset=True):
        return validation.training_data(self, X, y, sample_weight, reset)

    def _check_fitted(self):
        validation.check_fitted(self)

    def _check_states(self, X):
        return validation.check_states(self, X)

    def _validate_states(self, X):
        return validation.validate_states(self, X)

    def _warn_non_finite(self, values, X, method):
        validation.warn_non_finite(self, values, X, method)

    # Bound, not wrapped: the stacklevels their callers pass count the frames
    # of these two, and a wrapper would add one.
    _warn_outside = validation.warn_outside
    _warn_n_outside = validation.warn_n_outside

    # ----------------------------------------------------------- evaluation
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
        self._check_fitted()
        # The compiled shortcut returns the model's order: only for "pq".
        checked = None if self._swapped() else self._checked_prediction(X)
        if checked is not None:
            dXdt, n_outside = checked
            self._warn_n_outside(n_outside, X.shape[0])
            self._warn_non_finite(dXdt, np.asarray(X), "predict")
            return dXdt
        if is_trajectory_container(X):
            states = unpack_derivatives(X).states
            if isinstance(states, np.ndarray):
                return self.predict(states.reshape(-1, states.shape[-1])).reshape(states.shape)
            return [self.predict(s) for s in states]
        X = self._to_model(self._validate_states(X))
        self._warn_outside(X)
        # numpy's "invalid value in matmul" would name neither X nor the
        # cause: the warning below does.
        with np.errstate(over="ignore", invalid="ignore"):
            dXdt = self._vector_field(X)
        self._warn_non_finite(dXdt, X, "predict")
        return self._to_model(dXdt)

    def _checked_prediction(self, X):
        """``(dXdt, n_outside)`` of a few states in one compiled call, or None.

        What ``predict`` does for a few states (validation, domain check,
        field) costs more in Python than the compiled field itself; a model
        that can do it in one compiled call overrides this. None means the
        general path (and its errors).
        """
        return None

    # ------------------------------------------------------------ simulation
    def _integrator(self, method=None):
        return _simulate.integrator(self, method)

    def _default_method(self):
        return _simulate.default_method(self)

    def _default_step(self, method):
        """The step ``simulate`` takes with ``method`` when ``max_step`` is None."""
        return _simulate.default_step(self, method)

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
            model fitted on steps (the map it learned; once its coefficients
            are fitted to the trajectories, ``trajectory_fit_status_`` is
            ``"refined"``, they describe the flow instead), else a fraction
            of the learned system's time scale ``time_scale_`` (0.1 for the
            fourth-order methods, 0.02 for the second-order ones), which keeps
            the integration error far below the error of a model learned from
            noisy data; a model learned from exact data can be closer to its
            law than that step resolves (the pendulum's RK4 default is about
            1e-5 relative after twenty time units), so pass a smaller step
            there. ``numpy.inf`` steps from one output time to the next.
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
        ValueError
            Before anything runs, if the run would take more than ``10**7``
            integration steps per initial state (``MAX_STEPS``: e.g.
            ``t = [0, 1e12]``, or ``max_step=1e-12``), or its output more
            memory than ``memory_limit`` (:func:`sk_hamiltonian.set_config`);
            the message names ``t``, ``max_step`` and the count.

        Warns
        -----
        UserWarning
            With ``method="avf"`` for more than 10 000 steps per initial state
            when numba is not installed: each AVF step then costs several
            times an RK4 step, and ``pip install "sk_hamiltonian[fast]"``
            removes that cost.
        """
        return _simulate.simulate(self, x0, t, method, max_step, on_failure)

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
        return rollout_score(self, self._layout_to_model(X), sample_weight)

    # ------------------------------------------------------------------ hooks
    def _check_dimensions(self, n_states):
        """Hook: reject state dimensions the model cannot handle."""

    def _check_size(self, data):
        """Hook: reject problems the model cannot fit."""

    def _design(self, space):
        """The least-squares design of this model on ``space`` (a :class:`~sk_hamiltonian._least_squares.Design`)."""
        raise NotImplementedError

    def _set_coef(self, coef):
        """Set the fitted coefficients from the solution vector."""
        raise NotImplementedError

    def _set_resampled(self, coef):
        """Set the resampled refits' coefficients, one solution vector per row."""
        self.resampled_coef_ = coef

    def _vector_field(self, X):
        raise NotImplementedError

    def _jacobian(self, X):
        """Jacobians of the learned field at ``X`` (None where there is none)."""
        return None

    def _dynamics(self):
        raise NotImplementedError

    def _after_fit(self, data):
        """Hook: checks of the fitted model against its training data.

        Here: trajectories whose residuals are far outside the rest are named
        in an :class:`~sk_hamiltonian.OutlierWarning` (see
        :mod:`sk_hamiltonian._outliers`); subclasses add their own checks.
        """
        warn_residual_outliers(self, data)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.three_d_array = True
        tags.target_tags.required = True
        tags.target_tags.multi_output = True
        tags.target_tags.single_output = False
        return tags
