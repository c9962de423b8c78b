"""Structure-preserving regression: learn the Hamiltonian, not the vector field."""

import numpy as np
from sklearn.utils._param_validation import StrOptions

from . import _fit_trajectories
from . import _hamiltonian_dynamics as dynamics
from ._base import BaseTrajectoryRegressor
from ._conservation import (
    conservation_message,
    decorrelated,
    energy_trend,
    trend_verdict,
)
from ._inspection.terms import check_state_names
from ._least_squares import HamiltonianDesign
from ._state_order import ORDER_WORDS, STATE_ORDERS, warn_if_order_looks_swapped
from ._trajectories import check_n_states
from ._validation import check_equation_count
from ._warnings import warn
from .exceptions import ConservationWarning
from .inspection import format_hamiltonian

# A fitted damping is "not backed" by the data when H~ does not fall along
# them by even one standard error (cluster-robust z above -1).
UNBACKED_Z = 1.0


class HamiltonianRegressor(BaseTrajectoryRegressor):
    """Structure-preserving regression of an unknown Hamiltonian system.

    Fits a Hamiltonian ``H~`` in a space of tensor-product functions so that
    ``J dx/dt ≈ grad H~(x)`` in the least-squares sense (Wu, Qin & Xiu,
    Section 3), with ``x = (p_1..p_d, q_1..q_d)`` and ``J = [[0, I], [-I, 0]]``.
    The learned system ``dx/dt = J^{-1} grad H~(x)`` is Hamiltonian by
    construction, so it conserves ``H~`` exactly along its trajectories. The
    default space is the paper's: Legendre polynomials of total degree
    ``degree`` on a box; the other parameters fit the space to the scene.

    Parameters
    ----------
    degree : int, default=3
        Largest total degree ``n`` of a basis function (a frequency counts
        like a degree). With the defaults the number of unknowns is
        ``C(n + 2d, 2d) - 1``; it is counted before anything is built, and a
        fit that would need more memory than ``memory_limit``
        (:func:`~sk_hamiltonian.set_config`) is refused with the sizes.
    domain : array-like of shape (n_states, 2), default=None
        The box carrying the basis, one ``(low, high)`` row per state
        variable; for a periodic variable, one full period ``[low, high)``.
        None uses the bounding box of the training states, and ``[-pi, pi)``
        for periodic variables.
    periodic : array-like of shape (n_states,) of bool, default=None
        True marks an angle: its basis is trigonometric (``1, cos k theta,
        sin k theta`` with ``theta = 2 pi (x - low) / (high - low)``), and states
        outside its period are wrapped, not extrapolated, everywhere. None:
        no periodic variable. A fit on trajectories refuses a periodic (or
        mixed) variable whose median step between consecutive samples
        exceeds a quarter period: the samples cannot resolve the angle (wrong
        units, e.g. degrees over ``[-pi, pi)``); rescale it to radians, give
        its period through ``domain``, or set the flag to False.
    mixed : array-like of shape (n_states,) of bool, default=None
        True gives a non-periodic variable ``x`` the Fourier terms ``cos k x``,
        ``sin k x`` (period ``2 pi``, in the variable's own units) beside its
        Legendre polynomials, and products with the other variables as
        usual (a frequency counts like a degree). So laws that are neither
        polynomial nor periodic in ``x`` are sparse: a torsion pendulum's
        ``p**2 / 2 + k q**2 / 2 - g cos q`` has three terms. Mixed variables
        are not wrapped; their box is their interval, as for polynomials, and
        ``H~`` has zero mean over the box only up to its Fourier terms. None:
        no mixed variable.
    momentum_degree : int, default=None
        Largest total degree in the momenta ``p``. 2 spans every mechanical
        Hamiltonian ``p^T M(q) p / 2 + b(q)^T p + V(q)`` with far fewer terms.
        None: only ``degree`` limits it.
    separable : bool, default=False
        ``H~ = T(p) + V(q)``: no basis function mixes momenta and positions.
        Separable models can be simulated with the explicit symplectic
        methods ``"leapfrog"`` and ``"yoshida4"``, as can any fit whose kept
        terms each hold momenta only or positions only.
    max_interaction : int, default=None
        Most state variables one basis function depends on (2: pairwise
        couplings, as in lattices). None: no limit.
    couplings : list of sequences of int, default=None
        Which state variables may be coupled: a basis function of two or more
        variables enters only if they all lie in one group (indices into the
        state, momenta first). Nearest neighbours on a chain of ``d``
        particles coupled through their positions are
        ``[(d + i, d + i + 1) for i in range(d - 1)]``; add ``(2 * d - 1, d)``
        for a ring. Functions of one variable always enter. It combines with
        ``separable`` and ``max_interaction``. None: any variables may be
        coupled.
    fit_on : {"derivatives", "steps", "simpson", "weak", "trajectories"}, default="derivatives"
        What the model is fitted to. ``"derivatives"``: the paper's fit, the
        gradient against the estimated time derivatives. ``"steps"``: the
        observed steps ``x0 -> x1`` of the trajectories, so that the
        averaged-vector-field map of ``H~`` at each pair's own time step
        reproduces them; no derivative estimate enters (the layout's states
        are used: the raw observations with finite differences, the smoothed
        ones with the polynomial method). Such an ``H~`` is the *modified*
        Hamiltonian of the AVF method at the data step, within ``O(dt**2)`` of
        the true one; :meth:`simulate` then uses AVF at the training step by
        default. ``"simpson"``: each pair of consecutive steps ``x0 -> x1 ->
        x2``, so that Simpson's rule for the integral of ``J grad H~`` over
        the pair reproduces ``x2 - x0`` (any two step lengths). Also free of
        derivative estimates, and exact to ``O(dt**4)``: ``H~`` approximates
        the true Hamiltonian, not a modified one, and :meth:`simulate` uses
        RK4 as after a derivative fit. Needs at least three samples per
        trajectory. ``"weak"``: the weak form, windows of 21 consecutive
        samples (a shorter trajectory is one window; windows overlap by three
        quarters), each multiplied by a smooth bump ``phi`` that vanishes at
        its ends and integrated by the trapezoid rule, so that
        ``int phi J grad H~(x) dt`` matches ``-int phi' J x dt``. No
        derivative or step difference enters, and the noise of the states
        barely biases the fit (the bump's integral against its own
        derivative vanishes); like Simpson's it learns ``H~`` itself, and
        :meth:`simulate` uses RK4. Needs at least three samples per
        trajectory. The last three need the derivative layout as input (its
        states: raw with finite differences, smoothed with the polynomial
        method). ``"trajectories"``: the derivative fit, then the kept terms'
        coefficients (and the friction) fitted to the raw observed
        trajectories the layout carries, each simulated from an initial
        state of its own (the output-error estimate, free of the derivative
        estimate's bias and as precise as the data allow; see
        :ref:`fit_targets`). It is first checked on data it was not fitted
        on (every other training trajectory held out, then the rest) and
        kept only where it explains them as well as the least-squares fit;
        ``trajectory_fit_status_`` says what happened. Needs the derivative
        layout, takes no ``sample_weight``, and fits at most 40 kept terms,
        or 10 per state variable beyond four (use a ``threshold``).
    threshold : float, default=0.0
        Sparsity threshold. 0 fits every basis function (the paper's fit).
        A positive value runs sequentially thresholded least squares (STLSQ)
        in the *readable* basis, the monomials and angles of
        :func:`~sk_hamiltonian.inspection.hamiltonian_terms`: terms whose
        coefficient, scaled by the norm of its design column, is below
        ``threshold`` times the largest are dropped, the rest refitted, until
        no term is dropped. So ``p**2 / 2 - 9.81 cos q`` can come back as two
        terms (in the fitting basis ``p**2`` needs its lower-degree Legendre
        companions, which stay). Friction coefficients are never dropped.
        Choose it by cross-validation (see
        :func:`~sk_hamiltonian.model_selection.threshold_path`); typical values
        are ``1e-3`` to ``0.1``. Sparsity is judged in the variables as given,
        about their zero.
    damping : bool, default=False
        Add linear friction, ``dp/dt = -dH~/dq - gamma * dq/dt``, with one
        ``gamma >= 0`` per degree of freedom fitted jointly with ``H~`` by the
        same least squares (the friction term uses the observed ``dq/dt``).
    solver : {"auto", "lstsq", "normal", "iterative", "sketch"}, default="auto"
        ``"lstsq"`` factorizes the whole (column-equilibrated) design with an
        SVD. ``"normal"`` streams it in blocks into the normal equations
        (memory independent of the number of samples), solves them by
        Cholesky and refines the solution against the design, which matches
        ``"lstsq"`` unless the condition number exceeds about 1e7; where the
        basis depends on every variable, the gradients are linear maps of
        one smaller basis's values, and the normal equations come from that
        basis's one Gram matrix, ``n_states`` times less work.
        ``"iterative"`` never forms the normal matrix: conjugate gradients with
        the design applied as an operator, preconditioned by the basis' Gram
        matrix under the uniform measure on the box (fast when the samples
        cover the box evenly). ``"sketch"`` runs the same iteration
        preconditioned by a random sketch of the design (three rows per
        unknown), which converges in about 50 iterations however the samples
        are spread; it pays for many unknowns and many samples. ``"auto"``
        picks ``"lstsq"`` while the design holds at most 5e7 entries,
        ``"normal"`` beyond, ``"sketch"`` from 5 000 unknowns and 50 rows per
        unknown on where the normal equations cannot take the shorter route
        above, and ``"iterative"`` from 10 000 unknowns on (falling back to
        ``"normal"`` if an iteration does not converge). See
        :ref:`scaling`.
    verbose : int, default=0
        Print the progress of long fits (blocks accumulated, iterations and
        their residual) when positive; silent by default.
    n_resamples : int, default=0
        With a positive value and trajectories as input (the derivative
        layout), ``fit`` also refits the model on this many resamples of
        whole trajectories, each with the same ``threshold``, and keeps their
        coefficients (``resampled_coef_``), from which
        :func:`~sk_hamiltonian.inspection.term_intervals` gives each term's
        inclusion frequency and interval and
        :func:`~sk_hamiltonian.inspection.format_hamiltonian` prints them.
        The normal equations of each trajectory are accumulated once and
        every refit solves a weighted sum of them (``solver="normal"``, without
        refinement against the design): on the paper's pendulum 100 resamples
        cost about 2 fits (see :ref:`intervals`). 0: no resampling.
    resample : {"bootstrap", "subsample"}, default="bootstrap"
        How trajectories are resampled: ``"bootstrap"`` draws as many as
        there are, with replacement; ``"subsample"`` takes half of them,
        without (whose spread about the fit is that of the bootstrap).
    random_state : int, RandomState instance or None, default=None
        Seed of the resamples' draws.
    n_jobs : int, default=None
        Threads solving the resamples' refits; None means 1, -1 every
        core. The results do not depend on it.
    state_names : list of str, default=None
        Names of the ``2d`` state variables, momenta first (``["p_theta",
        "theta"]``), used by every formula and report of the model
        (:meth:`equations`, :func:`~sk_hamiltonian.inspection.format_hamiltonian`,
        the command's ``show``) and saved in model files. None: the column
        names of ``X`` if it had them, else ``p, q`` or ``p1.., q1..``. They
        do not reorder anything: they are given in the order of the columns
        of ``X`` (so after ``state_order="qp"``, positions first), and the
        columns are read as ``state_order`` says whatever they are called.
    state_order : {"pq", "qp"}, default="pq"
        The order of the state variables in the columns of ``X`` (and of the
        derivatives ``y``, the states and derivatives of a
        :class:`DerivativeTransformer`'s output, the initial states of
        :meth:`simulate`): ``"pq"`` is ``(p_1..p_d, q_1..q_d)``, ``"qp"`` is
        ``(q_1..q_d, p_1..p_d)``, as in PySINDy and most lab files. Every
        state-shaped input is reordered to ``(p, q)``, in which the model
        works, and every state-shaped output (:meth:`predict`,
        :meth:`simulate`, :meth:`gradient`) back to the columns' order.
        ``domain``, ``periodic``, ``mixed``, ``couplings`` and
        ``state_names`` are given in the columns' order too; the fitted
        attributes (``domain_``, ``periodic_``, ``mixed_``, ``powers_``,
        ``state_scale_``) are in the model's ``(p, q)`` order. Not available
        for a fit on dask arrays.
    terms : array-like of shape (n_named, n_states) of int, default=None
        Fit these terms of the space only: a law of known form, say the
        coupled pendula's ``p1**2, p2**2, cos q1, cos q2, q1**2, q1*q2,
        q2**2`` in a space with ``mixed`` positions. Each row is the
        multi-index of one readable term, in the code and the ``(p, q)``
        order of :func:`~sk_hamiltonian.inspection.hamiltonian_terms`'
        ``powers`` (an exponent per ordinary variable; for a mixed one,
        ``-(2k - 1)`` for ``cos(k x)`` and ``-2k`` for ``sin(k x)``; a
        signed frequency per periodic one). A positive ``threshold`` drops
        among them. Every term must belong to the space the other
        parameters make (a row that does not is refused, with the space).
        None: every term of the space.

    Attributes
    ----------
    coef_ : ndarray of shape (n_basis,)
        Coefficients of ``H~`` in the basis ``powers_``.
    powers_ : ndarray of shape (n_basis, n_states)
        Multi-indices of the basis functions (constant excluded): the
        Legendre degree of each ordinary variable, the signed frequency of
        each periodic one (``+k``: ``cos k theta``, ``-k``: ``sin k theta``).
        :func:`~sk_hamiltonian.inspection.hamiltonian_terms` lists them
        readably.
    periodic_ : ndarray of shape (n_states,) of bool
        Which variables are periodic.
    mixed_ : ndarray of shape (n_states,) of bool
        Which variables are mixed; in ``powers_`` their Fourier factors have
        negative codes: ``-(2k - 1)`` for ``cos k x``, ``-2k`` for ``sin k x``.
    domain_ : ndarray of shape (n_states, 2)
        The box the basis lives on.
    damping_ : ndarray of shape (n_dof,)
        Fitted friction coefficients ``gamma`` (zeros with ``damping=False``).
    resampled_coef_ : ndarray of shape (n_resamples, n_basis)
        With ``n_resamples > 0``: the coefficients of each refit on a
        resample of the trajectories, in the basis ``powers_`` on the same
        box, zero off each refit's own support.
    resampled_damping_ : ndarray of shape (n_resamples, n_dof)
        With ``n_resamples > 0`` and ``damping=True``: each refit's friction
        coefficients.
    cond_ : float
        Condition number of the column-equilibrated least-squares design
        (estimated with ``solver="iterative"`` or ``"sketch"`` and beyond
        1 500 unknowns with ``"normal"``).
    rank_ : int
        Numerical rank of that design.
    support_ : ndarray of shape (n_basis,) of bool
        Basis functions with a coefficient; all True with ``threshold=0``.
        Evaluation and simulation use only these, so their cost follows the
        kept terms.
    n_terms_ : int
        Number of fitted unknowns: ``n_basis`` (with a threshold, the kept
        readable terms), plus ``n_dof`` with damping.
    n_iter_ : int
        Least-squares solves of the thresholded fit (1 with ``threshold=0``).
    solver_ : str
        The solver used (``"normal"`` after :meth:`partial_fit` or a fit on
        dask arrays).
    dt_ : float
        Median time step of the training trajectories (NaN when fitted on
        2-D states); the AVF step of a model fitted on steps.
    time_scale_ : float
        ``1 / rho``, with ``rho`` the 90th percentile of the spectral radius of
        the learned system's Jacobian over the training states; sets the
        default integration step.
    state_scale_ : ndarray of shape (n_states,)
        Standard deviation of each state variable over the training states;
        the rollout score measures errors in these units.
    energy_trend_ : float
        Trend of ``H~`` along the training trajectories: its slope in time
        over the spread of ``H~`` on the data (the larger of its standard
        deviation over the training states and over the same states with
        their variables decorrelated, so that one long conservative
        trajectory has a spread; NaN when fitted on 2-D states).
        Near zero for conservative data, negative when they lose energy.
    trajectory_fit_status_ : str
        With ``fit_on="trajectories"`` (or after the refinement of
        :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV`):
        ``"refined"``, or ``"kept: "`` and why the least-squares coefficients
        were kept.
    noise_ : ndarray of shape (n_states, 2)
        With ``fit_on="trajectories"``, when refined: the noise model of
        each state variable, variance ``a_i + b_i x_i**2`` (additive and
        relative noise), as ``(a_i, b_i)``.
    trajectory_misfit_ : ndarray of shape (n_trajectories,)
        With ``fit_on="trajectories"``, when refined: each training
        trajectory's root-mean-square residual in units of ``noise_`` (about
        1 where the model explains it; far above, a trajectory it does not).
    coef_covariance_ : ndarray of shape (n_coef, n_coef)
        With ``fit_on="trajectories"``, when refined: the covariance of
        ``coef_`` (then ``damping_``, for a damped model: ``n_coef = n_basis
        + n_dof``): a sandwich estimate with the trajectories as clusters
        (robust to a wrong noise model), each variance at least the
        model-based one (see :ref:`intervals`). It covers the
        spread of the estimate from sample to sample, not a wrong set of
        terms.
    energy_trend_z_ : float
        The trend's z-score: slope over its cluster-robust standard error
        (each trajectory, or with fewer than 20 trajectories each stretch of
        one, is an independent unit; samples within one may be correlated).
    n_features_in_ : int
        Number of state variables ``2d``.
    feature_names_in_ : ndarray of shape (`n_features_in_`,)
        Names of the state variables, when ``X`` had string column names.

    See Also
    --------
    VectorFieldRegressor : The non-structure-preserving baseline.
    DerivativeTransformer : Estimates time derivatives from trajectories.

    Notes
    -----
    Every non-constant basis function has zero mean over the box under the
    uniform measure, so the free additive constant of ``H~`` is fixed by the
    rule *H~ has zero mean over the domain*, the constant of the paper's
    Theorem 3.5.

    After fitting on trajectories, ``H~`` is evaluated along each of them. A
    :class:`~sk_hamiltonian.ConservationWarning` says when it trends both
    significantly (``|energy_trend_z_| > 4``) and by more than 2 % of its
    spread per period of the learned system: a loss suggests friction
    (``damping=True``) or a poor fit, a gain driven data or a missing term.
    It also says when a fitted damping is not backed by a loss of energy in
    the data. An :class:`~sk_hamiltonian.OutlierWarning` names trajectories
    whose residuals are far outside the rest. See the user guide
    (Measurements: calibrating the conservation check, outlying
    trajectories). After any fit, a
    :class:`~sk_hamiltonian.StateOrderWarning` says when ``H~`` looks like
    a negated Hamiltonian with its halves exchanged, as states given in
    ``(q, p)`` order give: its Hessian negative definite in the momenta
    (averaged over the training states) and in the positions.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-1, 1, size=(200, 2))              # states (p, q)
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])           # H = (p^2 + q^2) / 2
    >>> model = HamiltonianRegressor(degree=2, domain=[[-1, 1], [-1, 1]]).fit(X, y)
    >>> np.round(model.hamiltonian([[1.0, 0.0]]) - model.hamiltonian([[0.0, 0.0]]), 6)
    array([0.5])
    """

    _parameter_constraints = {
        **BaseTrajectoryRegressor._parameter_constraints,
        "fit_on": [StrOptions({"derivatives", "steps", "simpson", "weak", "trajectories"})],
        "damping": ["boolean"],
        "state_names": ["array-like", None],
        "state_order": [StrOptions(set(STATE_ORDERS))],
        "terms": ["array-like", None],
    }

    def __init__(
        self, degree=3, *, domain=None, periodic=None, mixed=None, momentum_degree=None,
        separable=False, max_interaction=None, couplings=None, fit_on="derivatives",
        threshold=0.0, damping=False, solver="auto", verbose=0, n_resamples=0,
        resample="bootstrap", random_state=None, n_jobs=None, state_names=None,
        state_order="pq", terms=None,
    ):
        super().__init__(
            degree, domain=domain, periodic=periodic, mixed=mixed,
            momentum_degree=momentum_degree,
            separable=separable, max_interaction=max_interaction, couplings=couplings,
            fit_on=fit_on, threshold=threshold, solver=solver, verbose=verbose,
            n_resamples=n_resamples, resample=resample, random_state=random_state,
            n_jobs=n_jobs,
        )
        self.damping = damping
        self.state_names = state_names
        self.state_order = state_order
        self.terms = terms

    # ------------------------------------------------------------------ fit
    def _check_trajectory_input(self, X, y, sample_weight):
        _fit_trajectories.check_input(self, X, y, sample_weight)

    def _fit_trajectories(self, X):
        _fit_trajectories.fit_on_trajectories(self, X)

    def _check_dimensions(self, n_states):
        check_n_states(n_states)

    def _n_terms(self, n_states):
        return super()._n_terms(n_states) + (n_states // 2 if self.damping else 0)

    def _check_size(self, data):
        check_equation_count(self, data)

    def _design(self, space):
        return HamiltonianDesign(space, self._fit_target, self.damping)

    def _set_coef(self, coef):
        space = self._space
        self.coef_ = coef[: space.n_terms]
        self.damping_ = coef[space.n_terms :] if self.damping else np.zeros(space.n_states // 2)

    def _set_resampled(self, coef):
        n_terms = self._space.n_terms
        self.resampled_coef_ = coef[:, :n_terms]
        if self.damping:
            self.resampled_damping_ = coef[:, n_terms:]

    def _resampled_field(self, coef=None, damping=None):
        return dynamics.resampled_field(self, coef, damping)

    def _rebuild_fitted(self):
        super()._rebuild_fitted()
        self._split = dynamics.separable_parts(self)

    def _after_fit(self, data):
        check_state_names(self.state_names, self.n_features_in_,
                          order=f"{ORDER_WORDS[self.state_order]} first")
        super()._after_fit(data)
        warn_if_order_looks_swapped(self, data.states)
        self.energy_trend_, self.energy_trend_z_ = float("nan"), float("nan")
        if data.trajectories is None:
            return
        # H~ at every training state in one batch, then split by trajectory.
        lengths = [S.shape[0] for _, S in data.trajectories]
        values = self._hamiltonian(data.states)
        energies = np.split(values, np.cumsum(lengths)[:-1])
        spread = max(np.std(values), np.std(self._hamiltonian(decorrelated(data.states))))
        self.energy_trend_, self.energy_trend_z_ = energy_trend(
            [(t, H) for (t, _), H in zip(data.trajectories, energies)], spread=spread
        )
        if not np.isfinite(self.energy_trend_z_):
            return
        verdict, change, period = trend_verdict(
            self.energy_trend_, self.energy_trend_z_, self.time_scale_)
        if not self.damping_.any() and verdict is not None:
            warn(conservation_message(verdict, change, period, self.energy_trend_z_),
                 ConservationWarning)
        elif self.damping_.any() and self.energy_trend_z_ > -UNBACKED_Z:
            warn(
                f"HamiltonianRegressor: the fitted damping {np.round(self.damping_, 4).tolist()} "
                f"is not backed by a loss of energy along the training trajectories (trend "
                f"z-score {self.energy_trend_z_:.1f}). A bias of the derivative estimate "
                f"(e.g. one-sided differences lag by half a step) can look like friction; "
                f"check the derivatives, or fit with damping=False.",
                ConservationWarning,
            )

    # ------------------------------------------------------------ evaluation
    def _gradient(self, X):
        space = self._eval_space
        return self._in_blocks(
            X, lambda B: space.gradient_dot(B, self._eval_coef),
            space.n_terms * space.layout.n_slots,
        )

    def _hamiltonian(self, X):
        space = self._eval_space
        return self._in_blocks(
            X, lambda B: space.value_dot(B, self._eval_coef),
            space.n_terms * space.layout.n_slots,
        )

    def _hessian(self, X):
        return self._eval_space.hessian_dot(X, self._eval_coef)

    def _checked_prediction(self, X):
        return dynamics.checked_prediction(self, X)

    def _vector_field(self, X):
        return dynamics.vector_field(self, X)

    def _jacobian(self, X):
        return dynamics.jacobian(self, X)

    def _dynamics(self):
        return dynamics.dynamics(self)

    def hamiltonian(self, X):
        """The learned Hamiltonian ``H~``, normalized to zero mean over the domain.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states) or (..., n_states)
            States, with any leading shape (e.g. the output of
            :meth:`simulate`).

        Returns
        -------
        H : ndarray of shape X.shape[:-1]
            Values of ``H~``.
        """
        self._check_fitted()
        flat, lead = self._check_states(X)
        flat = self._to_model(flat)
        self._warn_outside(flat)
        with np.errstate(over="ignore", invalid="ignore"):
            H = self._hamiltonian(flat)
        self._warn_non_finite(H, flat, "hamiltonian")
        return H.reshape(lead)

    def equations(self, *, state_names=None, max_terms=8, intervals=False):
        """The learned Hamiltonian as a formula, ``"H~ = c1 t1 + c2 t2 + ... + const"``.

        What :func:`sk_hamiltonian.inspection.format_hamiltonian` gives for
        this model: its leading terms in the readable basis (monomials and
        angles of the variables as given), largest first. ``repr(model)``
        stays scikit-learn's, the parameters, fitted or not.

        Parameters
        ----------
        state_names : list of str, default=None
            Names of the state variables; None uses ``feature_names_in_`` if
            the model was fitted on named columns, else ``p, q`` (``p1.., q1..``
            for several degrees of freedom).
        max_terms : int, default=8
            How many terms to show; the rest are summarized.
        intervals : bool or float, default=False
            With ``n_resamples > 0``: each coefficient followed by the half
            width of its interval over the refits (True: 90 %).

        Returns
        -------
        formula : str
            One line.

        Raises
        ------
        sklearn.exceptions.NotFittedError
            Before :meth:`fit`.

        Examples
        --------
        >>> import numpy as np
        >>> from sk_hamiltonian import HamiltonianRegressor
        >>> rng = np.random.default_rng(0)
        >>> X = rng.uniform(-1, 1, size=(200, 2))              # states (p, q)
        >>> y = np.column_stack([-X[:, 1], X[:, 0]])           # H = (p^2 + q^2) / 2
        >>> HamiltonianRegressor(degree=2).fit(X, y).equations()
        'H~ = 0.5 q^2 + 0.5 p^2 + const'
        """
        self._check_fitted()
        return format_hamiltonian(self, state_names=state_names, max_terms=max_terms,
                                  intervals=intervals)

    def gradient(self, X):
        """Gradient of the learned Hamiltonian, ``grad H~``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states) or (..., n_states)
            States, with any leading shape.

        Returns
        -------
        grad : ndarray of the same shape as X
            ``(dH~/dp, dH~/dq)`` at each state.
        """
        self._check_fitted()
        flat, lead = self._check_states(X)
        flat = self._to_model(flat)
        self._warn_outside(flat)
        return self._to_model(self._gradient(flat)).reshape(lead + (self.n_features_in_,))

