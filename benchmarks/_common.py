"""Shared pieces of the benchmarks: scenes, the three methods, rollouts, metrics.

The scripts pin BLAS to one thread *before* importing this module (and so
numpy); this module assumes that has been done.

Methods compared
----------------
``SP``
    :class:`sk_hamiltonian.HamiltonianRegressor`, the structure-preserving fit.
``non-SP``
    :class:`sk_hamiltonian.VectorFieldRegressor`, the same polynomial space
    fitted component by component (the paper's baseline).
``SP-sparse``, ``non-SP-STLSQ``
    The same two regressors with ``threshold > 0`` (sequentially thresholded
    least squares in the readable basis), the threshold chosen by
    :func:`fit_sparse`: ``GridSearchCV`` over ``SPARSE_THRESHOLDS`` with the
    estimator's default score (5 folds of whole trajectories).
``PySINDy-best``
    ``pysindy.SINDy`` as an expert would set it up for the scene
    (:func:`fit_sindy_best`): a library fitted to the scene (sines and cosines
    of the angles times a polynomial in the momenta), PySINDy's own
    ``SmoothedFiniteDifference`` on noisy data, bagging with
    ``EnsembleOptimizer`` and the STLSQ threshold chosen by cross-validation
    (:func:`cv_sindy_threshold`).
``PySINDy-poly``
    The labelled extra row: ``PolynomialLibrary`` of the scene's degree and
    plain ``STLSQ``, fed our states and derivatives (finite differences, or
    the paper's Q = 5 de-noising).

PySINDy is optional: when it is not importable, its rows are skipped and the
reason printed.

Scenes beyond the paper fit SP and non-SP in the same model space (periodic
angles, degree in the momenta, separable, pairwise), see :class:`Scene`.

All three see identical states and time derivatives, from one
:class:`sk_hamiltonian.DerivativeTransformer` call whose time is charged to each
method's fit time, so the comparison is between the regressions.
"""

import csv
import itertools
import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from sklearn.model_selection import GridSearchCV

from sk_hamiltonian import DerivativeTransformer, SimulationError, unpack_derivatives
from sk_hamiltonian.datasets import PAPER_DT, load_system, make_trajectories

# Reference solutions: RK4 with this step, 10x finer than the sampling step.
# Its error (~1e-12 relative) is far below every learning error measured here,
# and it is 10x cheaper than the system's default (dt/100).
REFERENCE_STEP = PAPER_DT / 10
# Rollouts are chopped into chunks of this many output times, so that one
# failing initial state costs one chunk of single-state simulation rather than
# a rerun of the whole batch.
CHUNK = 50
# The learned state is "out of the domain" beyond this relative slack.
DOMAIN_SLACK = 1e-9
# Candidate fresh initial states are drawn in a box around u0* whose half-widths
# are this fraction of the domain's; farther away, most true trajectories of
# Henon-Heiles and Cherry leave the domain (measured: Cherry keeps 0 of 200
# states drawn in the whole domain, Henon-Heiles 7%).
FRESH_BOX_FRACTION = 0.25
# Threshold grid of the sparse rows, searched by GridSearchCV (the grid of
# issue 16's acceptance test); 0 is the dense fit, so the search may keep it.
SPARSE_THRESHOLDS = (0.0, 1e-3, 1e-2, 3e-2, 0.1)
# PySINDy-best: STLSQ thresholds (absolute, in coefficient units, its
# convention) searched by cross-validation, and the bagged models.
SINDY_BEST_THRESHOLDS = (0.0, 1e-3, 1e-2, 3e-2, 0.1, 0.3)
SINDY_ENSEMBLE_MODELS = 20


def sindy_status():
    """Whether pysindy can be used, and why not.

    Returns
    -------
    module : module or None
        ``pysindy``, or None when it is unavailable.
    reason : str
        Version, or why it was skipped.
    """
    try:
        import pysindy
    except Exception as error:  # ImportError, or a broken install
        return None, f"pysindy not importable ({type(error).__name__}: {error})"
    return pysindy, f"pysindy {getattr(pysindy, '__version__', '?')}"


@dataclass
class Scene:
    """One learning problem: a system, its data and the model degree.

    Attributes
    ----------
    label : str
        Name in tables and charts.
    system : str
        Name accepted by :func:`sk_hamiltonian.datasets.load_system`.
    degree : int
        Polynomial degree ``n`` shared by all methods.
    n_trajectories, n_intervals : int
        ``M`` and ``J``.
    noise : float
        Relative noise level.
    dt : float
        Sampling step.
    seed : int
        Seed of the trajectories.
    params : dict
        Parameters of the system's factory (e.g. ``n_particles``).
    space : dict
        Model-space parameters shared by SP and non-SP (``momentum_degree``,
        ``separable``, ``max_interaction``); ``periodic=True`` stands for the
        system's own ``periodic`` flags.
    data_fraction : float
        Initial states of the training trajectories are drawn in the system's
        box shrunk by this factor about its centre (1: the whole box).
    test_domain : list of (low, high) or None
        Box the true test trajectories must stay in (None: the training box).
    sindy_degree : int or None
        Degree of PySINDy's polynomial library (None: ``degree``).
    sindy_fourier : int or None
        Also fit PySINDy with a trigonometric library of this many frequencies
        per angle (:func:`sindy_library`); None: polynomial only.
    sindy_one_array : bool
        Give PySINDy the states as one array rather than a list of
        trajectories (see :func:`fit_sindy`).
    sindy_predict_steps : int or None
        Time RK4 through ``SINDy.predict`` on this many steps and scale to the
        horizon (None: the whole horizon); for libraries whose ``predict``
        costs tens of milliseconds a call.
    sindy_lsoda : bool
        Whether to run PySINDy's own ``simulate`` (LSODA), which calls
        ``predict`` at every function evaluation (only with ``--lsoda``).
    sparse_degree : int or None
        Degree of the sparse rows (None: ``degree``).
    sparse_space : dict or None
        Model space of the sparse rows (None: ``space``); e.g. the pendulum's
        periodic mechanical space, in which its Hamiltonian has two terms.
    sindy_best : dict
        PySINDy-best's library: ``degree`` (polynomial degree, in the momenta
        when ``fourier`` is set) and ``fourier`` (frequencies per angle, or
        None), see :func:`sindy_library`; ``periodic`` (which variables are
        angles; default the system's flags).
    """

    label: str
    system: str
    degree: int
    n_trajectories: int
    n_intervals: int
    noise: float = 0.0
    dt: float = PAPER_DT
    seed: int = 0
    params: dict = field(default_factory=dict)
    space: dict = field(default_factory=dict)
    data_fraction: float = 1.0
    test_domain: list = None
    sindy_degree: int = None
    sindy_fourier: int = None
    sindy_one_array: bool = False
    sindy_predict_steps: int = None
    sindy_lsoda: bool = True
    sparse_degree: int = None
    sparse_space: dict = None
    sindy_best: dict = field(default_factory=dict)

    @property
    def derivative(self):
        """The paper's rule: finite differences if clean, Q = 5 polynomials if noisy."""
        if self.noise == 0:
            return DerivativeTransformer(dt=self.dt, method="finite_difference")
        return DerivativeTransformer(dt=self.dt, method="polynomial", degree=5)

    def load(self):
        """The system, with this scene's parameters."""
        return load_system(self.system, **self.params)

    def data_domain(self, system):
        """Box the training trajectories start in."""
        centre = system.domain.mean(axis=1, keepdims=True)
        return centre + self.data_fraction * (system.domain - centre)

    def model_params(self, system, sparse=False):
        """Keyword arguments of SP and non-SP: the scene's model space (or the sparse rows')."""
        params = dict(self.space if not sparse or self.sparse_space is None
                      else self.sparse_space)
        if params.get("periodic") is True:
            params["periodic"] = system.periodic
        return params


def make_data(scene, raw=False):
    """Trajectories of a scene and their derivative layout.

    Returns
    -------
    system : HamiltonianSystem
    Xt : ndarray
        Derivative layout (states, derivatives, observations).
    derivative_time : float
        Seconds spent estimating derivatives (charged to every method's fit).
    X : ndarray of shape (M, J + 1, n_states)
        The raw (noisy) trajectories; only with ``raw=True``.
    """
    system = scene.load()
    X = make_trajectories(
        system, scene.n_trajectories, scene.n_intervals, scene.dt,
        noise=scene.noise, random_state=scene.seed, domain=scene.data_domain(system),
    )
    start = time.perf_counter()
    Xt = scene.derivative.fit_transform(X)
    elapsed = time.perf_counter() - start
    return (system, Xt, elapsed, X) if raw else (system, Xt, elapsed)


def sindy_library(ps, degree, fourier=None, periodic=None, mixed=False):
    """PySINDy's feature library: polynomial, or polynomial in ``p`` times trigonometric in angles.

    Parameters
    ----------
    ps : module
        ``pysindy``.
    degree : int
        Degree of the ``PolynomialLibrary``; with ``fourier``, its degree in
        the non-periodic variables (the momenta).
    fourier : int or None
        None: ``PolynomialLibrary(degree)`` in all variables. Else each angle
        gets a ``FourierLibrary(fourier)`` (``sin k x, cos k x``, ``k <=
        fourier``), tensored with the polynomial library of the other
        variables and with each other: the features are ``m(p) * f1(q1) *
        f2(q2) * ...`` with ``m`` a monomial of degree ``<= degree`` and each
        ``f`` either 1 or a sine or cosine. That holds the double pendulum's
        vector field, ``p``-quadratic with coefficients periodic in both angles,
        the way the Fourier-mechanical space of our regressors holds its ``H``.
    periodic : array-like of bool or None
        Which variables are angles (needed with ``fourier``).
    mixed : bool, default=False
        With ``fourier``: also the polynomial of degree ``degree`` in *all*
        variables, angles included, so that an angle can carry both kinds of
        terms (a torsion pendulum, ``V = k q**2 / 2 - g cos q``). The features
        are then that polynomial plus the products above with at least one
        sine or cosine.
    """
    if fourier is None:
        return ps.PolynomialLibrary(degree=degree)
    periodic = np.asarray(periodic, dtype=bool)
    angles = np.flatnonzero(periodic)
    libraries = [ps.PolynomialLibrary(degree=degree)] + [
        ps.FourierLibrary(n_frequencies=fourier) for _ in angles]
    inputs = [np.flatnonzero(~periodic).tolist()] + [[a] for a in angles]
    # Every product of the polynomial library with a non-empty set of angle
    # libraries; the angle libraries alone are excluded (the polynomial
    # library's constant already makes them part of the products).
    tensors = [[1] + [int(b) for b in mask]
               for mask in itertools.product((0, 1), repeat=angles.size) if any(mask)]
    excluded = list(range(1, 1 + angles.size))
    if mixed:
        # Library 0 is the polynomial in all variables, kept alone; the one in
        # the momenta only enters the products (alone it would repeat columns).
        libraries = [ps.PolynomialLibrary(degree=degree)] + libraries
        inputs = [list(range(periodic.size))] + inputs
        tensors = [[0] + row for row in tensors]
        excluded = [1] + [k + 1 for k in excluded]
    return ps.GeneralizedLibrary(
        libraries, tensor_array=tensors, inputs_per_library=inputs,
        exclude_libraries=excluded,
    )


class SindyField:
    """Vectorized evaluation of a fitted PySINDy model.

    ``SINDy.predict`` costs about 3 ms per call whatever the batch size
    (input validation and axis bookkeeping), which makes long or many rollouts
    through it impractical. The model itself is ``Theta(x) @ coef.T``; this
    class evaluates exactly that -- monomial features ``prod(x ** powers_)``
    for a ``PolynomialLibrary``, and for :func:`sindy_library`'s trigonometric
    variant the same products computed here, matched column by column to the
    library's own -- and checks it against ``predict`` on the fitted data.

    Parameters
    ----------
    model : pysindy.SINDy
        Fitted, with a ``PolynomialLibrary`` or a library of
        :func:`sindy_library` with ``fourier``.
    check_states : ndarray of shape (n, n_states)
        States on which to compare with ``predict``.
    fourier, periodic : optional
        As given to :func:`sindy_library`.
    """

    def __init__(self, model, check_states, fourier=None, periodic=None):
        self.coef = np.asarray(model.coefficients())
        self.n_params = int(np.count_nonzero(self.coef))
        self.fourier = fourier
        if fourier is None:
            self.powers = np.asarray(model.feature_library.powers_)
        else:
            self.periodic = np.asarray(periodic, dtype=bool)
            self.powers = np.asarray(
                model.feature_library.libraries[0].powers_)  # fitted on the momenta
            ours = self.features(check_states, order=None)
            theirs = np.asarray(model.feature_library.transform([check_states])[0])
            # Column j of theirs is column order[j] of ours.
            distance = np.abs(theirs[:, :, None] - ours[:, None, :]).max(axis=0)
            self.order = np.argmin(distance, axis=1)
            if theirs.shape[1] != ours.shape[1] or distance.min(axis=1).max() > 1e-12 \
                    or np.unique(self.order).size != self.order.size:
                raise RuntimeError("SindyField cannot match the trigonometric library.")
        ours = self(check_states)
        theirs = np.asarray(model.predict(check_states))
        scale = max(1.0, float(np.abs(theirs).max()))
        if not np.allclose(ours, theirs, rtol=1e-9, atol=1e-9 * scale):
            raise RuntimeError("SindyField disagrees with SINDy.predict; library changed?")

    def features(self, X, order=True):
        """Library matrix ``Theta(X)`` (columns in the library's order unless ``order=None``)."""
        if self.fourier is None:
            with np.errstate(over="ignore", invalid="ignore"):
                return np.prod(X[:, None, :] ** self.powers[None], axis=2)
        k = np.arange(1, self.fourier + 1)
        poly = np.prod(X[:, ~self.periodic][:, None, :] ** self.powers[None], axis=2)
        trig = []
        for a in np.flatnonzero(self.periodic):
            angle = X[:, a, None] * k
            trig.append(np.stack([np.sin(angle), np.cos(angle)], axis=2).reshape(X.shape[0], -1))
        blocks = [poly]
        for mask in itertools.product((0, 1), repeat=len(trig)):
            if any(mask):
                block = poly
                for use, T in zip(mask, trig):
                    if use:
                        block = (block[:, :, None] * T[:, None, :]).reshape(X.shape[0], -1)
                blocks.append(block)
        Theta = np.concatenate(blocks, axis=1)
        return Theta if order is None else Theta[:, self.order]

    def __call__(self, X):
        with np.errstate(over="ignore", invalid="ignore"):
            return self.features(X) @ self.coef.T


def split_layout(Xt):
    """States and derivatives of a derivative layout, as lists per trajectory."""
    data = unpack_derivatives(Xt)
    return list(data.states), list(data.derivatives)


def fit_sindy(ps, Xt, degree, threshold, dt, fourier=None, periodic=None, one_array=False):
    """Fit PySINDy on the layout's states and derivatives (list of trajectories).

    ``fourier`` and ``periodic`` choose the library, see :func:`sindy_library`.
    ``one_array=True`` passes all states as one array instead: with ``x_dot``
    given, PySINDy does not differentiate, so the least-squares problem is the
    same, but its library is evaluated once instead of once per trajectory
    (measured: a degree-10 polynomial library over 3 000 three-state
    trajectories took about 400 s as a list).
    """
    states, derivatives = split_layout(Xt)
    if one_array:
        states, derivatives = [np.concatenate(states)], [np.concatenate(derivatives)]
    model = ps.SINDy(
        optimizer=ps.STLSQ(threshold=threshold),
        feature_library=sindy_library(ps, degree, fourier, periodic),
    )
    with warnings.catch_warnings():
        # STLSQ warns when a threshold zeroes everything; that shows in the error.
        warnings.simplefilter("ignore")
        model.fit(states, t=dt, x_dot=derivatives)
    return model


def tune_sindy_threshold(ps, Xt, degree, dt, thresholds, tolerance=1.25, seed=0,
                         fourier=None, periodic=None, one_array=False):
    """Pick the STLSQ threshold by derivative error on held-out trajectories.

    The classic SINDy criterion, on 20 % of the trajectories held out (whole
    trajectories, so no state is in both parts), with a parsimony rule: the
    *largest* threshold whose held-out mean squared error is within
    ``tolerance`` times the best one. Plain "best error" picks 0 (no sparsity,
    i.e. the non-SP least-squares fit in a monomial basis) on every scene here,
    because extra terms absorb derivative-estimation error. The rule is blind
    to the test rollouts.

    Returns
    -------
    threshold : float
    scores : dict
        Held-out MSE per threshold.
    """
    states, derivatives = split_layout(Xt)
    order = np.random.default_rng(seed).permutation(len(states))
    n_val = max(1, len(states) // 5)
    val, train = order[:n_val], order[n_val:]
    train_layout = [Xt[k] for k in train]
    X_val = np.concatenate([states[k] for k in val])
    Y_val = np.concatenate([derivatives[k] for k in val])
    scores = {}
    for threshold in thresholds:
        model = fit_sindy(ps, train_layout, degree, threshold, dt, fourier, periodic, one_array)
        with np.errstate(all="ignore"):
            mse = float(np.mean((np.asarray(model.predict(X_val)) - Y_val) ** 2))
        scores[threshold] = mse if np.isfinite(mse) else np.inf
    best = min(scores.values())
    return max(thr for thr, mse in scores.items() if mse <= tolerance * best), scores


def fit_sparse(estimator, Xt, thresholds=SPARSE_THRESHOLDS, cv=5):
    """Choose ``threshold`` by ``GridSearchCV`` with the default score, and refit.

    The estimator's own ``score`` (rollouts against the held-out observations)
    on ``cv`` folds of whole trajectories; the best mean score wins, ties going
    to the first (smallest) threshold, as ``GridSearchCV`` ranks them. Nothing
    about the test rollouts enters.

    Returns
    -------
    model : fitted estimator
        Refitted on all the data with the chosen threshold.
    threshold : float
    select_s : float
        Seconds of the search (all folds and the refit).
    refit_s : float
        Seconds of the final fit alone (``refit_time_``).
    note : str
        The mean CV score of every threshold.
    """
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = GridSearchCV(estimator, {"threshold": list(thresholds)}, cv=cv).fit(Xt)
    select_s = time.perf_counter() - start
    refit_s = search.refit_time_
    threshold = search.best_params_["threshold"]
    scores = search.cv_results_["mean_test_score"]
    note = f"threshold={threshold:g} by GridSearchCV (mean CV score " + ", ".join(
        f"{thr:g}: {score:.6f}" for thr, score in zip(thresholds, scores)) + ")"
    return search.best_estimator_, threshold, select_s, refit_s, note


def sindy_best_data(ps, scene, X, Xt):
    """States and derivatives for PySINDy-best, as lists of trajectories.

    Clean data: our second-order finite differences (PySINDy's
    ``FiniteDifference(order=2)`` gives the same to 1e-13). Noisy data:
    PySINDy's own ``SmoothedFiniteDifference`` on the raw trajectories, with
    the smoothed states as the library's input (what ``SINDy.fit`` does with
    that differentiation method). Its Savitzky-Golay window spans the whole
    trajectory (order 3): on the noisy pendulum (8 %, 41 points) the RMS error
    of the derivatives against the true field is 3.94 with its default window
    11, 1.86 with 21, 1.14 with 31 and 0.84 with 41 (ours, Q = 5: 1.93), so
    the widest window is what an expert would pick. That choice looked at the
    truth, which favours PySINDy.

    Returns
    -------
    states, derivatives : list of ndarray
    seconds : float
        Time of the differentiation.
    label : str
    """
    if scene.noise == 0:
        states, derivatives = split_layout(Xt)
        return states, derivatives, 0.0, "finite differences (ours = PySINDy's order 2)"
    start = time.perf_counter()
    X = np.asarray(X)
    window = X.shape[1] if X.shape[1] % 2 else X.shape[1] - 1
    states, derivatives = [], []
    for x in X:
        method = ps.SmoothedFiniteDifference(
            smoother_kws=dict(window_length=window, polyorder=3))
        derivatives.append(np.asarray(method(x, t=scene.dt)))
        states.append(np.asarray(method.smoothed_x_))
    return (states, derivatives, time.perf_counter() - start,
            f"SmoothedFiniteDifference (Savitzky-Golay window {window}, order 3)")


def _sindy_fit_lists(ps, states, derivatives, dt, optimizer, library, one_array):
    if one_array:
        states, derivatives = [np.concatenate(states)], [np.concatenate(derivatives)]
    model = ps.SINDy(optimizer=optimizer, feature_library=library)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(states, t=dt, x_dot=derivatives)
    return model


def fit_sindy_best(ps, states, derivatives, dt, threshold, degree, fourier=None, periodic=None,
                   n_models=SINDY_ENSEMBLE_MODELS, one_array=False, seed=0):
    """PySINDy with the scene's library and a bagged STLSQ (``EnsembleOptimizer``).

    ``n_models`` bootstrap resamples of the samples, each fitted by
    ``STLSQ(threshold)``; the median coefficients are the model (PySINDy's
    default aggregation). ``n_models=0`` fits plain STLSQ (used while the
    threshold is cross-validated). The global NumPy seed is set, as
    ``EnsembleOptimizer`` draws from it.
    """
    np.random.seed(seed)
    optimizer = ps.STLSQ(threshold=threshold)
    if n_models:
        optimizer = ps.EnsembleOptimizer(optimizer, bagging=True, n_models=n_models)
    return _sindy_fit_lists(ps, states, derivatives, dt, optimizer,
                            sindy_library(ps, degree, fourier, periodic), one_array)


def cv_sindy_threshold(ps, states, derivatives, dt, degree, fourier=None, periodic=None,
                       thresholds=SINDY_BEST_THRESHOLDS, folds=3, tolerance=1.25,
                       one_array=False, seed=0):
    """STLSQ threshold by K-fold cross-validation over whole trajectories.

    Held-out mean squared error of the derivatives, averaged over ``folds``
    folds, with the parsimony rule of :func:`tune_sindy_threshold`: the
    largest threshold whose mean error is within ``tolerance`` times the best
    (plain "best error" keeps threshold 0, the least-squares fit). Plain STLSQ
    during the search, for its cost; the chosen threshold is then bagged.

    Returns
    -------
    threshold : float
    scores : dict
        Mean held-out MSE per threshold.
    """
    order = np.random.default_rng(seed).permutation(len(states))
    parts = np.array_split(order, folds)
    scores = {}
    for threshold in thresholds:
        errors = []
        for k in range(folds):
            val = parts[k]
            train = np.concatenate([parts[j] for j in range(folds) if j != k])
            model = fit_sindy_best(ps, [states[i] for i in train],
                                   [derivatives[i] for i in train], dt, threshold, degree,
                                   fourier, periodic, n_models=0, one_array=one_array)
            X_val = np.concatenate([states[i] for i in val])
            Y_val = np.concatenate([derivatives[i] for i in val])
            with np.errstate(all="ignore"):
                errors.append(float(np.mean((np.asarray(model.predict(X_val)) - Y_val) ** 2)))
        mse = float(np.mean(errors))
        scores[threshold] = mse if np.isfinite(mse) else np.inf
    best = min(scores.values())
    return max(thr for thr, mse in scores.items() if mse <= tolerance * best), scores


def design_condition(ps_model, Xt, field=None):
    """Condition number of PySINDy's library matrix, columns scaled to unit norm.

    Column equilibration matches what ``cond_`` reports for our regressors, so
    the numbers compare; raw monomials on a wide box are far worse unscaled.
    ``field``, a :class:`SindyField` of the model, evaluates the library
    (needed for the trigonometric one).
    """
    states, _ = split_layout(Xt)
    if field is not None:
        Theta = field.features(np.concatenate(states))
    else:
        powers = ps_model.feature_library.powers_
        Theta = np.prod(np.concatenate(states)[:, None, :] ** powers[None], axis=2)
    norms = np.linalg.norm(Theta, axis=0)
    norms[norms == 0] = 1.0
    return float(np.linalg.cond(Theta / norms))


def rk4_step(fun, y, h):
    """One classical RK4 step (the same scheme as sk_hamiltonian's)."""
    k1 = fun(y)
    k2 = fun(y + (0.5 * h) * k1)
    k3 = fun(y + (0.5 * h) * k2)
    k4 = fun(y + h * k3)
    return y + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)


def rk4_rollout(fun, x0, t, substeps=1):
    """RK4 on the output grid for a vector field callable; NaN after failure.

    Parameters
    ----------
    fun : callable
        Vector field, ``(n, n_states) -> (n, n_states)``.
    x0 : array-like of shape (n_initial, n_states)
    t : ndarray of shape (n_times,)
    substeps : int, default=1
        RK4 steps per output interval.

    Returns
    -------
    Y : ndarray of shape (n_initial, n_times, n_states)
    fail_time : ndarray of shape (n_initial,)
        First output time not reached (non-finite state), ``inf`` if none.
    """
    x0 = np.atleast_2d(np.asarray(x0, dtype=float))
    Y = np.full((x0.shape[0], t.size, x0.shape[1]), np.nan)
    Y[:, 0] = x0
    fail_time = np.full(x0.shape[0], np.inf)
    active = np.arange(x0.shape[0])
    y = x0.copy()
    with np.errstate(all="ignore"):
        for k in range(t.size - 1):
            h = (t[k + 1] - t[k]) / substeps
            for _ in range(substeps):
                y = rk4_step(fun, y, h)
            ok = np.isfinite(y).all(axis=1)
            if not ok.all():
                fail_time[active[~ok]] = t[k + 1]
                active, y = active[ok], y[ok]
                if active.size == 0:
                    break
            Y[active, k + 1] = y
    return Y, fail_time


def _failure_interval(error):
    """``(t_last_reached, t_not_reached)`` of a SimulationError."""
    return error.t_reached, error.t_failed


def simulate_chunk(model, x0, t, method):
    """``model.simulate`` of a batch; failures become NaN and a failure time."""
    try:
        return model.simulate(x0, t, method=method), np.full(x0.shape[0], np.inf)
    except SimulationError:
        pass
    Y = np.full((x0.shape[0], t.size, x0.shape[1]), np.nan)
    fail_time = np.full(x0.shape[0], np.inf)
    for i, state in enumerate(x0):
        try:
            Y[i] = model.simulate(state, t, method=method)
        except SimulationError as error:
            reached, failed = _failure_interval(error)
            if np.isfinite(reached):
                # The message rounds times to 6 digits: take the nearest grid time.
                last = int(np.argmin(np.abs(t - reached)))
            elif np.isfinite(failed):
                last = max(0, int(np.argmin(np.abs(t - failed))) - 1)
            else:
                last = 0
            if last > 0:
                Y[i, : last + 1] = model.simulate(state, t[: last + 1], method=method)
            else:
                Y[i, 0] = state
            fail_time[i] = t[min(last + 1, t.size - 1)]
    return Y, fail_time


def rollout(model, x0, t, method="rk4"):
    """Simulate a fitted model from several initial states, surviving failures.

    Parameters
    ----------
    model : HamiltonianRegressor, VectorFieldRegressor or SindyField
        Package estimators go through their public ``simulate`` (one step per
        output interval); a :class:`SindyField` through :func:`rk4_rollout`.
    x0 : ndarray of shape (n_initial, n_states)
    t : ndarray of shape (n_times,)
        Output grid, which is also the step grid.
    method : {"rk4", "avf", "leapfrog", "yoshida4"}

    Returns
    -------
    Y : ndarray of shape (n_initial, n_times, n_states)
        NaN from the failure of a trajectory on.
    fail_time : ndarray of shape (n_initial,)
        First output time a trajectory did not reach (``inf``: none).
    """
    x0 = np.atleast_2d(np.asarray(x0, dtype=float))
    if isinstance(model, SindyField):
        return rk4_rollout(model, x0, t)
    Y = np.full((x0.shape[0], t.size, x0.shape[1]), np.nan)
    Y[:, 0] = x0
    fail_time = np.full(x0.shape[0], np.inf)
    active = np.arange(x0.shape[0])
    with warnings.catch_warnings():
        # Leaving the domain is measured (escape_time), not warned about.
        warnings.simplefilter("ignore")
        for start in range(0, t.size - 1, CHUNK):
            stop = min(start + CHUNK, t.size - 1)
            piece, failed = simulate_chunk(model, Y[active, start], t[start : stop + 1], method)
            Y[active, start : stop + 1] = piece
            fail_time[active] = failed
            active = active[~np.isfinite(failed)]
            if active.size == 0:
                break
    return Y, fail_time


def escape_time(Y, t, domain):
    """First output time at which each trajectory is outside ``domain`` (``inf``: never)."""
    domain = np.asarray(domain)
    slack = DOMAIN_SLACK * (domain[:, 1] - domain[:, 0])
    with np.errstate(invalid="ignore"):
        out = np.any((Y < domain[:, 0] - slack) | (Y > domain[:, 1] + slack), axis=2)
    out |= ~np.isfinite(Y).all(axis=2)
    first = np.where(out.any(axis=1), out.argmax(axis=1), -1)
    return np.where(first >= 0, t[np.maximum(first, 0)], np.inf)


def relative_error(Y, truth, t, horizon, periodic=None):
    """``||Y - U||_F / ||U||_F`` over ``t <= horizon``, per trajectory; inf if it failed.

    The paper plots ``||u~(t) - u(t)|| / ||u(t)||`` pointwise; this is its
    root-mean-square over ``[0, horizon]``, which is stable where the
    pointwise ratio oscillates with the phase. Differences of the
    ``periodic`` components (angles with period ``2 pi``) are taken the short
    way round the circle: periodic models return wrapped angles, the truth
    does not.
    """
    window = t <= horizon + 1e-9
    diff = Y[:, window] - truth[:, window]
    if periodic is not None and np.any(periodic):
        angles = np.asarray(periodic, dtype=bool)
        with np.errstate(invalid="ignore"):
            diff[..., angles] = (diff[..., angles] + np.pi) % (2 * np.pi) - np.pi
    with np.errstate(invalid="ignore", over="ignore"):
        err = np.linalg.norm(diff.reshape(diff.shape[0], -1), axis=1) / np.linalg.norm(
            truth[:, window].reshape(diff.shape[0], -1), axis=1
        )
    return np.where(np.isfinite(err), err, np.inf)


def reference(system, x0, t):
    """True trajectories by RK4 with steps of at most ``REFERENCE_STEP``.

    Returns
    -------
    Y : ndarray of shape (n_initial, n_times, n_states)
        NaN after a blow-up.
    fail_time : ndarray of shape (n_initial,)
        First output time not reached (``inf``: none).
    """
    substeps = max(1, math.ceil((t[1] - t[0]) / REFERENCE_STEP - 1e-9)) if t.size > 1 else 1
    return rk4_rollout(system.vector_field, x0, t, substeps)


def test_states(system, n_fresh, horizon, step, seed=1, domain=None):
    """The paper's ``u0*`` plus fresh states, the output grid and the truth.

    Fresh candidates are uniform in a box around ``u0*`` (half-widths
    ``FRESH_BOX_FRACTION`` times the domain's, clipped to it); a candidate is
    kept when its true solution stays finite and inside the domain up to
    ``horizon``, so that "the learned model failed" never means "the truth
    left the box the model was trained on". Candidates are screened with RK4
    at ``step``, then the survivors are checked again on the fine reference
    (on chaotic Henon-Heiles orbits the two can disagree). ``domain``
    replaces the system's box (e.g. the smaller box a scene trains in).

    Returns
    -------
    x0 : ndarray of shape (1 + n_found, n_states)
        ``u0*`` first; ``n_found <= n_fresh`` if too few candidates qualify.
    t : ndarray of shape (n_times,)
        Output grid ``0, step, ..., horizon``, also the models' step grid.
    truth : ndarray of shape (1 + n_found, n_times, n_states)
    """
    t = np.arange(0.0, horizon + step / 2, step)
    domain = system.domain if domain is None else np.asarray(domain, dtype=float)
    half = FRESH_BOX_FRACTION * 0.5 * (domain[:, 1] - domain[:, 0])
    low = np.maximum(system.initial_state - half, domain[:, 0])
    high = np.minimum(system.initial_state + half, domain[:, 1])
    candidates = np.random.default_rng(seed).uniform(
        low, high, (max(50, 40 * n_fresh), low.size))
    Y, fail_time = rk4_rollout(system.vector_field, candidates, t)
    keep = np.isinf(fail_time) & np.isinf(escape_time(Y, t, domain))
    x0 = np.vstack([system.initial_state, candidates[keep][: 2 * n_fresh]])
    truth, fail_time = reference(system, x0, t)
    if not np.isinf(fail_time[0]):
        raise RuntimeError(f"the true {system.name} solution from u0* fails before {horizon}")
    keep = np.isinf(fail_time) & np.isinf(escape_time(truth, t, domain))
    keep[0] = True  # u0* always: it is the paper's test state
    rows = np.flatnonzero(keep)[: 1 + n_fresh]
    return x0[rows], t, truth[rows]


def best_time(fun, repeats):
    """Smallest wall time of ``repeats`` calls, and the last result."""
    best, result = math.inf, None
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        result = fun()
        best = min(best, time.perf_counter() - start)
    return best, result


def write_csv(path, rows, columns):
    """Write dict rows; floats with full precision, non-finite as inf/nan."""
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: (repr(float(v)) if isinstance(v, (float, np.floating)) else v)
                             for k, v in row.items()})


def fmt(value, digits=3, inf="FAIL"):
    """Compact number for printed tables; ``inf`` is how +inf reads in that column."""
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, (int, np.integer)):
        return str(value)
    if math.isinf(value):
        return inf if value > 0 else "-inf"
    return f"{value:.{digits}g}"


def print_table(rows, columns, headers=None, file=None):
    """Plain fixed-width table (what the README pastes)."""
    headers = headers or columns
    # +inf is a failed rollout in error columns, "did not happen" in time columns.
    cells = [[fmt(row.get(c, ""), digits=4 if c.endswith("_time") else 3,
                  inf="never" if c.endswith("_time") else "FAIL")
              for c in columns] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h)
              for i, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths))
    print(line, file=file)
    print("  ".join("-" * w for w in widths), file=file)
    for r in cells:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)), file=file)
