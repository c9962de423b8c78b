"""PySINDy at its best, honestly cross-validated: the anchor of the search study (issue 33).

:func:`fit_sindy_cv` fits PySINDy 2.x as an expert would for a scene -- a
library chosen for the scene, hyperparameters chosen by cross-validation on
held-out trajectories, bagging for the final fit -- and returns a
:class:`SindyAnchor` that evaluates and integrates the learned vector field
fast. It sees only the raw trajectories, their sampling step, the library and
the folds: no system, no truth.

Forms
-----
strong (``weak=False``)
    PySINDy's ``SmoothedFiniteDifference`` (Savitzky-Golay smoothing, order 3,
    then second-order finite differences) on each trajectory; the library is
    evaluated at the *smoothed* states (what ``SINDy.fit`` does with that
    differentiation method) and regressed on the derivatives by ``STLSQ``.
    Cross-validated: the window (``WINDOWS``, capped at the trajectory length;
    window 1 is PySINDy's default, plain ``FiniteDifference``) and the STLSQ
    threshold (``THRESHOLDS``).
weak (``weak=True``)
    PySINDy's weak form: the test functions of ``WeakPDELibrary`` (``K``
    subdomains of half-width ``H_xt`` at random places on the time grid,
    ``(1 - x**2)**4`` bumps), the library integrated against them over the
    raw noisy states and the states' weak derivatives as targets, regressed by
    ``STLSQ``. It learns the coefficients of the same ODE ``dx/dt = Theta(x)
    Xi``, whose right-hand side is rebuilt from them and the library.
    Cross-validated: ``K`` and the half-width (as a fraction of the
    trajectory's span; PySINDy's default is 1/20) over ``WEAK_GRID``, and
    the threshold.

The criterion (the same for both forms)
---------------------------------------
For each fold, the candidate is fitted on the other trajectories (plain
STLSQ) and scored on the held-out ones against their **raw observations**
only, as the package's default ``score`` does: each held-out trajectory's
initial state is fitted under the candidate to all its observations (one
Gauss-Newton step from its first observation, forward-difference Jacobian,
kept only if it lowers the misfit), the candidate is integrated from it over
the trajectory's time stamps (RK4, 4 steps per sampling interval), and its
error ``e_k`` is the root-mean-square difference from the observations, each
variable divided by its standard deviation over the fold's *raw training
observations* (angles compared the short way round). The fold's score is
``mean_k min(1, e_k)`` (a failed or runaway rollout costs 1); lower is
better. Neither the smoothed states nor the derivatives nor the weak
integrals of the held-out trajectories enter, and the scale is the same for
every candidate, so a smoothing window cannot win by smoothing its own
targets. (Derivative MSE against each candidate's own smoothed derivatives
rewards over-smoothing, and is not used.)

Selection: ``rule="1se"`` (default), the one-standard-error rule with a
paired standard error: candidates whose mean score is within one standard
error of the fold-wise differences to the best candidate's are eligible, and
the one with the fewest terms (nonzero coefficients, mean over folds) is
chosen, ties to the lower mean score. ``rule="min"``: the lowest mean score.

The final model is refitted on all trajectories with the chosen settings by
``EnsembleOptimizer(STLSQ(threshold), bagging=True, n_models=20)``:
bootstrap resamples of the rows (time samples), median coefficients.

PySINDy quirks handled here (an honest comparison should mention them)
--------------------------------------------------------------------
- ``WeakPDELibrary`` cannot take a ``GeneralizedLibrary`` or
  ``TensoredLibrary`` as its function library (``KeyError`` in pysindy 2.1:
  it fits the function library on one time slice), and its ``transform``
  loops over subdomains and trajectories in Python (22 s for the pendulum's
  500 trajectories at K = 100). The weak matrices are therefore assembled
  here from the library's own test-function weights (``fullweights0``,
  ``fulltweights``, ``inds_k``) as one matrix product; the smoke test checks
  them against ``WeakPDELibrary.transform`` on a polynomial library. The
  regression itself is PySINDy's (``SINDy`` with an ``IdentityLibrary`` on
  the weak features, so ``model.predict`` of a weak anchor expects weak
  features, not states: use :meth:`SindyAnchor.rhs`).
- The weak subdomains are drawn from NumPy's *global* random state, as are
  ``EnsembleOptimizer``'s bootstraps: both are seeded here with ``seed``.
- ``STLSQ`` has a ridge penalty ``alpha=0.05`` by default and refits the
  kept terms by least squares (``unbias=True``); thresholds are absolute, in
  coefficient units. ``EnsembleOptimizer`` sets ``n_subset`` on its first fit
  (a fresh optimizer is made per fit).
- The cross-validation's plain-STLSQ fits run on the ``R`` factor of a thin
  QR of the design and ``Q.T`` times the targets, which define the same
  least-squares problems (same Gram matrix and right-hand side, so the same
  ridge steps and unbiased refits); the smoke test checks the coefficients
  against STLSQ on the full design.
- ``SmoothedFiniteDifference`` is applied to all trajectories at once (time
  axis first), which equals the per-trajectory call to round-off (checked in
  the smoke test) at a fraction of the cost.
- ``GeneralizedLibrary.n_output_features_`` counts the excluded libraries'
  columns too; the transform's shape is right.

Run the demo: ``PYTHONPATH=. python benchmarks/sindy_anchor.py`` (see
:func:`main`).
"""

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import itertools  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

import _common as C  # noqa: E402

# Savitzky-Golay windows tried by the strong form (odd, capped at the
# trajectory length; 1 is no smoothing, PySINDy's default FiniteDifference),
# and the polynomial order of the smoother. The short ones matter where
# trajectories are fast: on Henon-Heiles at dt = 0.05 the escaping orbits
# make window 11 bias the coefficients by 5 % even on clean data, and the
# cross-validation picks 5 there.
WINDOWS = (1, 5, 7, 11, 21, 31, 41)
POLYORDER = 3
# STLSQ thresholds, absolute (PySINDy's convention); 0 is the dense fit.
THRESHOLDS = (0.0, 1e-3, 3e-3, 0.01, 0.03, 0.1, 0.2, 0.5, 1.0)
# Weak form: numbers of test functions K, and subdomain half-widths as
# fractions of the trajectory's time span (PySINDy's default is 1/20).
WEAK_GRID = dict(K=(50, 100, 200), width=(0.05, 0.125, 0.25))
# Degree of the weak test functions (1 - x**2)**p, PySINDy's default.
WEAK_P = 4
N_MODELS = 20
# Entries of the temporary difference array when matching PySINDy's library
# to ours column by column (8 bytes each).
MATCH_ENTRIES = 8_000_000
# RK4 steps per sampling interval in the CV rollouts (the package's score's).
CV_SUBSTEPS = 4
# Forward-difference step of the shooting Jacobian, in units of each
# variable's spread (the package's SHOOTING_STEP).
SHOOTING_STEP = 1e-6
# Default RK4 step of SindyAnchor.simulate, as a fraction of the sampling step.
SIMULATE_STEP_FRACTION = 0.1


# --------------------------------------------------------------- the library
@dataclass(frozen=True)
class LibrarySpec:
    """A scene's library, as an expert would describe it.

    Attributes
    ----------
    poly_degree : int
        Degree of the polynomial (in the non-angle variables when ``fourier``
        is set and ``mixed`` is not, in all variables with ``mixed``).
    fourier : int or None
        Frequencies of the sines and cosines of each angle (None: none).
    angles : tuple of int
        Indices of the angle variables in the state.
    mixed : bool
        Whether the angles also carry polynomial terms.
    """

    poly_degree: int
    fourier: int = None
    angles: tuple = ()
    mixed: bool = False

    @classmethod
    def parse(cls, library, n_states):
        """Check a ``library`` dict of :func:`fit_sindy_cv` and make the spec."""
        if not isinstance(library, dict):
            raise ValueError(
                f"library must be a dict such as dict(poly_degree=3) or "
                f"dict(poly_degree=2, fourier=1, angles=[1]); got {library!r}.")
        unknown = set(library) - {"poly_degree", "fourier", "angles", "mixed"}
        if unknown:
            raise ValueError(f"library has unknown keys {sorted(unknown)}; use poly_degree, "
                             "fourier, angles and mixed.")
        degree = library.get("poly_degree")
        if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
            raise ValueError(f"library['poly_degree'] must be an integer >= 1; got {degree!r}.")
        fourier = library.get("fourier")
        angles = tuple(int(a) for a in library.get("angles", ()))
        mixed = bool(library.get("mixed", False))
        if fourier is not None and (isinstance(fourier, bool)
                                    or not isinstance(fourier, (int, np.integer)) or fourier < 1):
            raise ValueError(
                f"library['fourier'] must be None or an integer >= 1; got {fourier!r}.")
        if bool(angles) != (fourier is not None):
            raise ValueError("library needs both 'fourier' and 'angles' (the angle variables' "
                             f"indices), or neither; got {library!r}.")
        if mixed and not angles:
            raise ValueError("library['mixed'] needs 'fourier' and 'angles'.")
        if any(a < 0 or a >= n_states for a in angles) or len(set(angles)) != len(angles):
            raise ValueError(f"library['angles'] must be distinct indices in [0, {n_states}); "
                             f"got {list(angles)}.")
        if len(angles) == n_states:
            raise ValueError("library['angles'] cannot hold every variable: the polynomial "
                             "part needs at least one non-angle variable.")
        return cls(int(degree), None if fourier is None else int(fourier), angles, mixed)

    def periodic(self, n_states):
        """Boolean mask of the angles."""
        mask = np.zeros(n_states, dtype=bool)
        mask[list(self.angles)] = True
        return mask

    def pysindy(self, ps, n_states):
        """The PySINDy library (:func:`_common.sindy_library`)."""
        if self.fourier is None:
            return C.sindy_library(ps, self.poly_degree)
        return C.sindy_library(ps, self.poly_degree, self.fourier, self.periodic(n_states),
                               mixed=self.mixed)

    def terms(self, n_states):
        """Each feature as (monomial exponents, trigonometric index per angle).

        The trigonometric index of an angle is 0 for the factor 1, ``2k - 1``
        for ``sin(k a)`` and ``2k`` for ``cos(k a)``. Order: ours, matched to
        PySINDy's by :class:`LibraryFeatures`.
        """
        periodic = self.periodic(n_states)
        n_angles = len(self.angles)

        def monomials(variables):
            out = []
            for total in range(self.poly_degree + 1):
                for combo in itertools.combinations_with_replacement(variables, total):
                    powers = np.zeros(n_states, dtype=int)
                    for v in combo:
                        powers[v] += 1
                    out.append(powers)
            return out

        terms = []
        if self.fourier is None or self.mixed:
            terms += [(m, (0,) * n_angles) for m in monomials(range(n_states))]
        if self.fourier is not None:
            trig = itertools.product(range(2 * self.fourier + 1), repeat=n_angles)
            trig = [c for c in trig if any(c)]
            base = monomials(np.flatnonzero(~periodic))
            if not self.mixed:
                terms += [(m, (0,) * n_angles) for m in base]
            terms += [(m, c) for c in trig for m in base]
        return terms


class LibraryFeatures:
    """The library's features, vectorized, in PySINDy's column order.

    Each feature is a monomial times one trigonometric factor per angle
    (see :meth:`evaluator`). Built from a :class:`LibrarySpec`
    and matched column by column to the fitted PySINDy library's
    ``transform`` on ``check_states`` (a permutation, found numerically).

    Parameters
    ----------
    spec : LibrarySpec
    library : fitted pysindy feature library
        The library whose column order to follow.
    check_states : ndarray of shape (n, n_states)
        States on which the two are compared.
    """

    def __init__(self, spec, library, check_states):
        n_states = check_states.shape[1]
        terms = spec.terms(n_states)
        self.n_states = n_states
        self.angles = np.asarray(spec.angles, dtype=int)
        self.powers = np.array([t[0] for t in terms], dtype=int).reshape(len(terms), n_states)
        self.trig = np.array([t[1] for t in terms], dtype=int).reshape(len(terms),
                                                                     self.angles.size)
        ours = self(check_states)
        theirs = np.asarray(library.transform(check_states))
        if theirs.shape != ours.shape:
            raise RuntimeError(f"LibraryFeatures has {ours.shape[1]} columns, PySINDy's library "
                               f"{theirs.shape[1]}: the spec and the library disagree.")
        scale = np.maximum(1.0, np.abs(theirs).max(axis=0))
        # Their columns in blocks, so that the differences stay near 64 MB
        # (all at once: 52 GB for the 6 545 functions of 32 variables).
        block = max(1, MATCH_ENTRIES // (ours.shape[0] * ours.shape[1]))
        order = np.empty(theirs.shape[1], dtype=int)
        nearest = np.empty(theirs.shape[1])
        for start in range(0, theirs.shape[1], block):
            part = slice(start, start + block)
            distance = (np.abs(theirs[:, part, None] - ours[:, None, :]).max(axis=0)
                        / scale[part, None])
            order[part], nearest[part] = np.argmin(distance, axis=1), distance.min(axis=1)
        if nearest.max() > 1e-10 or np.unique(order).size != order.size:
            raise RuntimeError("LibraryFeatures cannot match PySINDy's library column by column.")
        self.powers, self.trig = self.powers[order], self.trig[order]

    @property
    def n_features(self):
        return self.powers.shape[0]

    def __call__(self, X, columns=None):
        """``Theta(X)``, shape (n, n_features) (or only ``columns``)."""
        with np.errstate(over="ignore", invalid="ignore"):
            return self.evaluator(columns)(np.asarray(X, dtype=float))

    def evaluator(self, columns=None):
        """A fast callable ``X -> Theta(X)[:, columns]``.

        Each feature is a product of factors (a variable to a power, a sine or
        cosine of a multiple of an angle); the callable computes each factor
        the features use once per call, on 1-D columns, and multiplies them
        per feature: a few array operations per feature, which is what
        matters for RK4 on batches of a few hundred states.
        """
        powers = self.powers if columns is None else self.powers[columns]
        trig = self.trig if columns is None else self.trig[columns]
        keys = []
        for row, trow in zip(powers, trig):
            keys.append(tuple([("x", v, int(e)) for v, e in enumerate(row) if e]
                              + [("sin" if i % 2 else "cos", int(a), (int(i) + 1) // 2)
                                 for a, i in zip(self.angles, trow) if i]))

        def theta(X):
            cache = {}

            def factor(key):
                value = cache.get(key)
                if value is None:
                    kind, v, e = key
                    if kind == "x":
                        value = X[:, v] if e == 1 else factor((kind, v, e - 1)) * X[:, v]
                    else:
                        value = getattr(np, kind)(X[:, v] if e == 1 else e * X[:, v])
                    cache[key] = value
                return value

            out = np.empty((X.shape[0], len(keys)))
            for i, feature in enumerate(keys):
                if not feature:
                    out[:, i] = 1.0
                    continue
                value = factor(feature[0])
                for key in feature[1:]:
                    value = value * factor(key)
                out[:, i] = value
            return out

        return theta


class _Field:
    """``x -> Theta(x)[:, active] @ coef[:, active].T``: the vector field of coefficients."""

    def __init__(self, features, coef):
        self.features = features
        self.coef = np.asarray(coef, dtype=float)
        self.active = np.flatnonzero(np.any(self.coef != 0, axis=0))
        self.coef_active = self.coef[:, self.active].T.copy()
        self.theta = features.evaluator(self.active)

    def __call__(self, X):
        if self.active.size == 0:
            return np.zeros_like(X, dtype=float)
        return self.theta(X) @ self.coef_active


# -------------------------------------------------------------------- the anchor
@dataclass
class SindyAnchor:
    """A cross-validated PySINDy model and what the study needs of it.

    Attributes
    ----------
    model : pysindy.SINDy
        The final fit (bagged). For the weak form, a ``SINDy`` with an
        ``IdentityLibrary`` fitted on the weak features: its ``predict``
        expects weak features; use :meth:`rhs`.
    library : fitted pysindy feature library
        The function library (the strong form's feature library).
    coef : ndarray of shape (n_states, n_features)
        ``dx/dt = Theta(x) @ coef.T``, columns in ``library``'s order.
    feature_names : list of str
    weak : bool
    params : dict
        The chosen hyperparameters (``window`` or ``K`` and ``width``, and
        ``threshold``).
    cv_table : list of dict
        One row per candidate: its hyperparameters, ``mean_score``,
        ``se`` (paired, against the best), ``fold_scores``, ``n_terms``
        (mean over folds), ``eligible`` and ``chosen``.
    fit_time : float
        Seconds of the whole cross-validation and the final fit.
    dt : float
        Sampling step of the data.
    """

    model: object
    library: object
    coef: np.ndarray
    feature_names: list
    weak: bool
    params: dict
    cv_table: list
    fit_time: float
    dt: float
    _field: object = field(default=None, repr=False)

    @property
    def n_terms(self):
        """Number of nonzero coefficients."""
        return int(np.count_nonzero(self.coef))

    def rhs(self, X):
        """The learned vector field ``dX/dt``, vectorized over rows of ``X``."""
        X = np.asarray(X, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):
            return self._field(X.reshape(-1, X.shape[-1])).reshape(X.shape)

    def simulate(self, x0, t, max_step=None):
        """Integrate the learned field by RK4; failures give NaN, never an exception.

        Parameters
        ----------
        x0 : array-like of shape (n_states,) or (n_initial, n_states)
        t : array-like of shape (n_times,)
            Increasing output times, ``t[0]`` the time of ``x0``.
        max_step : float or None
            Largest RK4 step; None: a tenth of the sampling step.

        Returns
        -------
        X : ndarray of shape (n_times, n_states) or (n_initial, n_times, n_states)
            NaN from the first output time a trajectory did not reach finitely.
        """
        x0 = np.asarray(x0, dtype=float)
        single = x0.ndim == 1
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.size < 1 or np.any(np.diff(t) <= 0):
            raise ValueError("t must be a 1-D array of increasing times.")
        step = SIMULATE_STEP_FRACTION * self.dt if max_step is None else float(max_step)
        substeps = max(1, math.ceil(np.max(np.diff(t), initial=0.0) / step - 1e-9))
        Y, _ = C.rk4_rollout(self._field, np.atleast_2d(x0), t, substeps)
        return Y[0] if single else Y

    def equations(self, names=None, precision=3):
        """The learned right-hand sides as text, one per state variable."""
        names = list(names or [f"x{i}" for i in range(self.coef.shape[0])])
        features = self.library.get_feature_names(names)
        out = []
        for i, row in enumerate(self.coef):
            terms = [f"{c:+.{precision}g} {features[j]}"
                     for j, c in enumerate(row) if c != 0]
            out.append(f"d{names[i]}/dt = " + (" ".join(terms) if terms else "0"))
        return out


# ------------------------------------------------------------------ the score
def _wrap(diff, angles):
    if angles.size:
        diff = diff.copy()
        diff[..., angles] = (diff[..., angles] + np.pi) % (2 * np.pi) - np.pi
    return diff


def _rk4_grid(fun, y0, n_intervals, h, substeps):
    """RK4 on a uniform grid of ``n_intervals`` steps of ``h``; non-finite stays non-finite."""
    Y = np.empty((y0.shape[0], n_intervals + 1, y0.shape[1]))
    Y[:, 0] = y = y0
    step = h / substeps
    with np.errstate(all="ignore"):
        for k in range(n_intervals):
            for _ in range(substeps):
                y = C.rk4_step(fun, y, step)
            Y[:, k + 1] = y
    return Y


def shooting_errors(fun, O, dt, scale, angles, substeps=CV_SUBSTEPS):
    """Rollout errors of a vector field against raw observed trajectories.

    The package's default score, for any vector field: each trajectory's
    initial state is fitted to all its observations by one Gauss-Newton step
    from its first observation (forward-difference Jacobian, one batch with
    the base rollouts), kept only if it lowers the misfit; the error is the
    root-mean-square over the trajectory of ``(X_hat - O) / scale``, angles
    the short way round.

    Parameters
    ----------
    fun : callable
        Vector field, ``(n, n_states) -> (n, n_states)``.
    O : ndarray of shape (n_traj, n_times, n_states)
        Raw observations, sampled every ``dt``.
    dt : float
    scale : ndarray of shape (n_states,)
    angles : ndarray of int
    substeps : int
        RK4 steps per sampling interval.

    Returns
    -------
    errors : ndarray of shape (n_traj,)
        ``inf`` where the rollout from the first observation is not finite.
    """
    n_traj, n_times, n_states = O.shape
    steps = SHOOTING_STEP * scale
    starts = np.concatenate([O[:, 0]] + [O[:, 0] + steps[i] * np.eye(n_states)[i]
                                         for i in range(n_states)])
    Y = _rk4_grid(fun, starts, n_times - 1, dt, substeps)
    base = Y[:n_traj]
    with np.errstate(all="ignore"):
        residual = _wrap(base - O, angles) / scale
        misfit = np.sum(residual ** 2, axis=(1, 2))
        jac = np.stack([_wrap(Y[(i + 1) * n_traj:(i + 2) * n_traj] - base, angles)
                        / scale / steps[i] for i in range(n_states)], axis=-1)
        jac = jac.reshape(n_traj, n_times * n_states, n_states)
    ok = np.isfinite(misfit) & np.isfinite(jac).all(axis=(1, 2))
    if ok.any():
        with np.errstate(all="ignore"):
            delta = np.einsum("kij,kj->ki", np.linalg.pinv(jac[ok]),
                              -residual[ok].reshape(ok.sum(), -1))
            moved = _rk4_grid(fun, O[ok, 0] + delta, n_times - 1, dt, substeps)
            moved_misfit = np.sum((_wrap(moved - O[ok], angles) / scale) ** 2, axis=(1, 2))
        better = np.isfinite(moved_misfit) & (moved_misfit < misfit[ok])
        rows = np.flatnonzero(ok)[better]
        misfit[rows] = moved_misfit[better]
    errors = np.sqrt(misfit / (n_times * n_states))
    return np.where(np.isfinite(errors), errors, np.inf)


def fold_score(fun, O, dt, scale, angles):
    """``mean_k min(1, e_k)`` over held-out trajectories; lower is better."""
    return float(np.mean(np.minimum(1.0, shooting_errors(fun, O, dt, scale, angles))))


# ----------------------------------------------------------- data and fits
def _check_inputs(X, dt, folds):
    X = np.asarray(X, dtype=float)
    if X.ndim != 3 or X.shape[0] < 2 or X.shape[1] < 5 or X.shape[2] < 1:
        raise ValueError("X must have shape (n_traj >= 2, n_times >= 5, n_states); got "
                         f"{X.shape}.")
    if not np.isfinite(X).all():
        raise ValueError("X contains NaN or infinity; drop or repair those trajectories.")
    if not (isinstance(dt, (int, float, np.floating)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number; got {dt!r}.")
    if not isinstance(folds, (list, tuple)) or len(folds) < 2:
        raise ValueError("folds must be a list of at least 2 arrays of held-out trajectory "
                         "indices (e.g. [test for _, test in KFold(5).split(X)]).")
    out = []
    for k, fold in enumerate(folds):
        fold = np.unique(np.asarray(fold, dtype=int))
        if fold.size == 0 or fold.size >= X.shape[0] or fold.min() < 0 \
                or fold.max() >= X.shape[0]:
            raise ValueError(f"folds[{k}] must hold between 1 and n_traj - 1 indices in "
                             f"[0, {X.shape[0]}); got {fold.size} indices.")
        out.append(fold)
    return X, float(dt), out


def _windows(n_times, windows):
    capped = sorted({min(w, n_times if n_times % 2 else n_times - 1) for w in windows})
    capped = [w for w in capped if w == 1 or (w > POLYORDER and w % 2 == 1)]
    if not capped:
        raise ValueError(f"no odd Savitzky-Golay window in {tuple(windows)} fits "
                         f"{n_times} samples (need > {POLYORDER}).")
    return capped


def smooth(ps, X, dt, window):
    """PySINDy's ``SmoothedFiniteDifference`` on every trajectory at once.

    Returns
    -------
    states, derivatives : ndarray of shape (n_traj, n_times, n_states)
        Smoothed states and their derivatives.
    """
    if window == 1:
        # No smoothing: PySINDy's default, second-order finite differences.
        derivatives = np.asarray(ps.FiniteDifference()(np.swapaxes(X, 0, 1), t=dt))
        return X, np.swapaxes(derivatives, 0, 1)
    method = ps.SmoothedFiniteDifference(
        smoother_kws=dict(window_length=int(window), polyorder=POLYORDER))
    derivatives = np.asarray(method(np.swapaxes(X, 0, 1), t=dt))
    return np.swapaxes(np.asarray(method.smoothed_x_), 0, 1), np.swapaxes(derivatives, 0, 1)


def weak_library(ps, function_library, n_times, dt, K, width, seed):
    """PySINDy's ``WeakPDELibrary`` on the trajectories' time grid (subdomains seeded)."""
    t = dt * np.arange(n_times)
    np.random.seed(seed)  # the subdomains are drawn from the global state
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ps.WeakPDELibrary(function_library=function_library, spatiotemporal_grid=t,
                                 K=int(K), H_xt=float(width) * t[-1], p=WEAK_P)


def weak_weights(weak_lib, n_times):
    """Dense test-function weights of a 1-D ``WeakPDELibrary``.

    Returns
    -------
    W0 : ndarray of shape (K, n_times)
        ``W0 @ f`` is the library's integral of ``f`` against each test function.
    Wt : ndarray of shape (K, n_times)
        ``-Wt @ x`` is the weak time derivative (``convert_u_dot_integral``).
    """
    K = weak_lib.K
    W0, Wt = np.zeros((K, n_times)), np.zeros((K, n_times))
    for k in range(K):
        idx = np.asarray(weak_lib.inds_k[k][0])
        W0[k, idx] = np.asarray(weak_lib.fullweights0[k]).ravel()
        Wt[k, idx] = np.asarray(weak_lib.fulltweights[k]).ravel()
    return W0, Wt


def weak_system(W0, Wt, Theta, X):
    """Weak features and targets of each trajectory.

    ``Theta`` (n_traj, n_times, n_features) is the library at the raw states.
    Returns arrays of shape (n_traj, K, n_features) and (n_traj, K, n_states).
    """
    return np.einsum("kt,ntf->nkf", W0, Theta), -np.einsum("kt,nts->nks", Wt, X)


def _stlsq(ps, threshold, n_models=0):
    optimizer = ps.STLSQ(threshold=threshold)
    if n_models:
        optimizer = ps.EnsembleOptimizer(optimizer, bagging=True, n_models=n_models)
    return optimizer


def _reduced(A, B):
    """``(R, Q.T @ B)`` from a thin QR of ``A``: the same least-squares problems.

    ``||A xi - b||**2 = ||R xi - Q.T b||**2 + const`` for every ``xi``, and
    ``R.T R = A.T A``, so STLSQ's ridge steps and its final unbiasing give the
    same coefficients (to round-off) on the few rows of ``R`` as on the many
    of ``A``, at a fraction of the cost of PySINDy's per-call validation.
    Used for the plain-STLSQ fits of the cross-validation only; the bagged
    final fit resamples the rows of ``A`` itself.
    """
    Q, R = np.linalg.qr(A)
    return R, Q.T @ B


def _coefficients(ps, A, B, threshold):
    """Plain STLSQ of ``B ~ A @ coef.T`` (PySINDy's optimizer, as ``SINDy.fit`` calls it)."""
    with warnings.catch_warnings():
        # STLSQ warns when a threshold zeroes everything; the score shows it.
        warnings.simplefilter("ignore")
        return np.asarray(_stlsq(ps, threshold).fit(A, B).coef_, dtype=float)


# ------------------------------------------------------------------ selection
def select(table, rule="1se"):
    """Index of the chosen candidate in ``table`` (rows with ``fold_scores``, ``n_terms``).

    Marks ``se``, ``eligible`` and ``chosen`` in the rows (see the module docstring).
    """
    scores = np.array([row["fold_scores"] for row in table])
    means = scores.mean(axis=1)
    best = int(np.argmin(means))
    diffs = scores - scores[best]
    n_folds = scores.shape[1]
    se = diffs.std(axis=1, ddof=1) / np.sqrt(n_folds)
    if rule == "min":
        eligible = np.arange(len(table)) == best
    elif rule == "1se":
        eligible = diffs.mean(axis=1) <= se
        eligible[best] = True
    else:
        raise ValueError(f"rule must be '1se' or 'min'; got {rule!r}.")
    candidates = np.flatnonzero(eligible)
    chosen = int(min(candidates, key=lambda i: (table[i]["n_terms"], means[i])))
    for i, row in enumerate(table):
        row.update(mean_score=float(means[i]), se=float(se[i]), eligible=bool(eligible[i]),
                   chosen=i == chosen)
    return chosen


# --------------------------------------------------------------------- the fit
def fit_sindy_cv(X, dt, *, library, folds, weak=False, seed=0, thresholds=THRESHOLDS,
                 windows=WINDOWS, weak_grid=None, n_models=N_MODELS, rule="1se"):
    """PySINDy fitted as an expert would, hyperparameters cross-validated honestly.

    Parameters
    ----------
    X : array-like of shape (n_traj, n_times, n_states)
        Raw (noisy) trajectories sampled every ``dt``; states ``(p, q)``.
    dt : float
    library : dict
        ``poly_degree`` (int), and optionally ``fourier`` (frequencies) with
        ``angles`` (indices of the angle variables), and ``mixed`` (angles
        also carry polynomial terms). E.g. ``dict(poly_degree=3)``,
        ``dict(poly_degree=2, fourier=1, angles=[1])``,
        ``dict(poly_degree=2, fourier=1, angles=[1], mixed=True)``.
    folds : list of array-like of int
        Held-out trajectory indices of each fold.
    weak : bool, default=False
        PySINDy's weak form instead of smoothed finite differences.
    seed : int, default=0
        Seeds the weak subdomains and the bagging.
    thresholds : sequence of float
        STLSQ thresholds searched.
    windows : sequence of int
        Savitzky-Golay windows searched (strong form), capped at ``n_times``.
    weak_grid : dict or None
        ``K`` and ``width`` (half-width / time span) searched (weak form);
        None: ``WEAK_GRID``.
    n_models : int, default=20
        Bagged models of the final fit (0: plain STLSQ).
    rule : {"1se", "min"}, default="1se"
        Selection rule, see the module docstring.

    Returns
    -------
    SindyAnchor
    """
    ps, reason = C.sindy_status()
    if ps is None:
        raise ImportError(f"fit_sindy_cv needs pysindy: {reason}")
    X, dt, folds = _check_inputs(X, dt, folds)
    n_traj, n_times, n_states = X.shape
    spec = LibrarySpec.parse(library, n_states)
    angles = np.asarray(spec.angles, dtype=int)
    if rule not in ("1se", "min"):
        raise ValueError(f"rule must be '1se' or 'min'; got {rule!r}.")
    thresholds = [float(v) for v in thresholds]
    if not thresholds or min(thresholds) < 0:
        raise ValueError("thresholds must be a non-empty sequence of numbers >= 0.")
    start = time.perf_counter()
    with threadpool_limits(1):
        lib = spec.pysindy(ps, n_states).fit(X[0])
        features = LibraryFeatures(spec, lib, X.reshape(-1, n_states)[:: max(1, n_traj // 4)])
        # Each fold's scale: the spread of its raw training observations,
        # shared by every candidate.
        scales = []
        for fold in folds:
            train = np.setdiff1d(np.arange(n_traj), fold)
            s = X[train].reshape(-1, n_states).std(axis=0)
            scales.append(np.where(s > 0, s, 1.0))
        if weak:
            grid = dict(WEAK_GRID if weak_grid is None else weak_grid)
            settings = [dict(K=int(K), width=float(w))
                        for K, w in itertools.product(grid["K"], grid["width"])]
            Theta_raw = features(X.reshape(-1, n_states)).reshape(n_traj, n_times, -1)

            def system_of(setting):
                weak_lib = weak_library(ps, lib, n_times, dt, setting["K"], setting["width"],
                                        seed)
                W0, Wt = weak_weights(weak_lib, n_times)
                return weak_system(W0, Wt, Theta_raw, X)
        else:
            settings = [dict(window=w) for w in _windows(n_times, windows)]

            def system_of(setting):
                states, derivatives = smooth(ps, X, dt, setting["window"])
                Theta = features(states.reshape(-1, n_states)).reshape(n_traj, n_times, -1)
                return Theta, derivatives

        table = []
        for setting in settings:
            A, B = system_of(setting)
            rows = {thr: dict(setting, threshold=thr, fold_scores=[], fold_terms=[])
                    for thr in thresholds}
            for fold, scale in zip(folds, scales):
                train = np.setdiff1d(np.arange(n_traj), fold)
                A_train, B_train = _reduced(A[train].reshape(-1, A.shape[-1]),
                                            B[train].reshape(-1, n_states))
                seen = {}
                for thr in thresholds:
                    coef = _coefficients(ps, A_train, B_train, thr)
                    key = coef.tobytes()
                    if key not in seen:
                        seen[key] = fold_score(_Field(features, coef), X[fold], dt, scale, angles)
                    rows[thr]["fold_scores"].append(seen[key])
                    rows[thr]["fold_terms"].append(int(np.count_nonzero(coef)))
            for row in rows.values():
                row["n_terms"] = float(np.mean(row["fold_terms"]))
                table.append(row)
        chosen = table[select(table, rule)]
        params = {k: chosen[k] for k in ("window", "K", "width", "threshold") if k in chosen}

        # The final fit, bagged, on every trajectory.
        setting = {k: v for k, v in params.items() if k != "threshold"}
        np.random.seed(seed)  # EnsembleOptimizer draws from the global state
        model = ps.SINDy(optimizer=_stlsq(ps, params["threshold"], n_models),
                         feature_library=ps.IdentityLibrary() if weak
                         else spec.pysindy(ps, n_states))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if weak:
                A, B = system_of(setting)
                model.fit(A.reshape(-1, A.shape[-1]), t=dt, x_dot=B.reshape(-1, n_states))
            else:
                # One array: with x_dot given the least-squares problem is the
                # same as with a list of trajectories, and the library is
                # evaluated once instead of once per trajectory.
                states, derivatives = smooth(ps, X, dt, params["window"])
                model.fit(states.reshape(-1, n_states), t=dt,
                          x_dot=derivatives.reshape(-1, n_states))
        coef = np.asarray(model.coefficients(), dtype=float)
        anchor = SindyAnchor(
            model=model, library=lib, coef=coef,
            feature_names=lib.get_feature_names([f"x{i}" for i in range(n_states)]),
            weak=weak, params=params,
            cv_table=table, fit_time=0.0, dt=dt, _field=_Field(features, coef))
        # The vectorized field against PySINDy's own evaluation, once.
        check = X.reshape(-1, n_states)[:: max(1, (n_traj * n_times) // 200)]
        theirs = (np.asarray(model.predict(check)) if not weak
                  else np.asarray(lib.transform(check)) @ coef.T)
        ours = anchor.rhs(check)
        if not np.allclose(ours, theirs, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(theirs).max())):
            raise RuntimeError("SindyAnchor.rhs disagrees with PySINDy's evaluation.")
    anchor.fit_time = time.perf_counter() - start
    return anchor


# ----------------------------------------------------------------- the demo
def duffing():
    """A double-well Duffing oscillator, ``H = p**2 / 2 - q**2 / 2 + q**4 / 4``."""
    from sk_hamiltonian.datasets import HamiltonianSystem  # noqa: PLC0415

    def hamiltonian(X):
        p, q = np.moveaxis(X, -1, 0)
        return 0.5 * p**2 - 0.5 * q**2 + 0.25 * q**4

    def gradient(X):
        p, q = np.moveaxis(X, -1, 0)
        return np.stack([p, -q + q**3], axis=-1)

    return HamiltonianSystem("duffing", hamiltonian, gradient,
                             domain=[[-1.0, 1.0], [-1.5, 1.5]], initial_state=[0.2, 1.0])


def torsion_pendulum(k=1.0, g=4.0):
    """``H = p**2 / 2 + k q**2 / 2 - g cos q``: polynomial and trigonometric in ``q``."""
    from sk_hamiltonian.datasets import HamiltonianSystem  # noqa: PLC0415

    def hamiltonian(X):
        p, q = np.moveaxis(X, -1, 0)
        return 0.5 * p**2 + 0.5 * k * q**2 - g * np.cos(q)

    def gradient(X):
        p, q = np.moveaxis(X, -1, 0)
        return np.stack([p, k * q + g * np.sin(q)], axis=-1)

    return HamiltonianSystem("torsion_pendulum", hamiltonian, gradient,
                             domain=[[-3.0, 3.0], [-3.0, 3.0]], initial_state=[0.5, 1.0])


def demo_scenes():
    """The demo's scenes: data, library and which variables are angles."""
    from sk_hamiltonian.datasets import henon_heiles, single_pendulum  # noqa: PLC0415

    return {
        "pendulum": dict(system=single_pendulum, n_traj=500, n_intervals=40, dt=0.01,
                         noise=0.08, library=dict(poly_degree=2, fourier=1, angles=[1]),
                         wrap=[1], names=["p", "q"]),
        "henon_heiles": dict(system=henon_heiles, n_traj=300, n_intervals=40, dt=0.05,
                             noise=0.02, library=dict(poly_degree=3), wrap=[],
                             names=["p1", "p2", "q1", "q2"]),
        "duffing": dict(system=duffing, n_traj=300, n_intervals=40, dt=0.05, noise=0.05,
                        library=dict(poly_degree=4), wrap=[], names=["p", "q"]),
        "torsion": dict(system=torsion_pendulum, n_traj=300, n_intervals=40, dt=0.02,
                        noise=0.05, library=dict(poly_degree=2, fourier=1, angles=[1],
                                                 mixed=True), wrap=[], names=["p", "q"]),
    }


def fresh_states(system, seed, n=10, horizon=20.0, bound=3.0):
    """Initial states uniform in the system's domain, and the truth at ``horizon``.

    Drawn from ``np.random.default_rng(1000 + seed)``; a state is kept when
    its true solution stays finite and within ``bound`` times the domain's
    half-widths of its centre up to ``horizon`` (Henon-Heiles orbits above
    the escape energy blow up; every pendulum state is kept), until ``n``.
    """
    rng = np.random.default_rng(1000 + seed)
    domain = system.domain
    centre, half = domain.mean(axis=1), 0.5 * (domain[:, 1] - domain[:, 0])
    t = np.linspace(0.0, horizon, 201)
    kept_x0, kept_end = [], []
    for _ in range(100):
        x0 = rng.uniform(domain[:, 0], domain[:, 1], size=(n, domain.shape[0]))
        truth = system.solve(x0, t, max_step=C.REFERENCE_STEP, on_failure="nan")
        with np.errstate(invalid="ignore"):
            ok = np.isfinite(truth).all(axis=(1, 2)) & (
                np.abs(truth - centre) <= bound * half).all(axis=(1, 2))
        kept_x0 += list(x0[ok])
        kept_end += list(truth[ok, -1])
        if len(kept_x0) >= n:
            return np.array(kept_x0[:n]), t, np.array(kept_end[:n])
    raise RuntimeError(f"fewer than {n} bounded fresh states for {system.name}")


def fresh_state_error(anchor, x0, t, end, wrap=()):
    """Median over the states of ``||x_model(T) - x_true(T)|| / ||x_true(T)||``."""
    Y = anchor.simulate(x0, t)[:, -1]
    diff = _wrap(Y - end, np.asarray(wrap, dtype=int))
    err = np.linalg.norm(diff, axis=1) / np.linalg.norm(end, axis=1)
    return float(np.median(np.where(np.isfinite(err), err, np.inf)))


def run_demo(scene, seed, weak, n_folds=5, quick=False):
    """Fit one scene and seed; the printed row's values."""
    from sklearn.model_selection import KFold  # noqa: PLC0415

    from sk_hamiltonian.datasets import make_trajectories  # noqa: PLC0415

    cfg = demo_scenes()[scene]
    system = cfg["system"]()
    n_traj = min(cfg["n_traj"], 100) if quick else cfg["n_traj"]
    X = make_trajectories(system, n_traj, cfg["n_intervals"], dt=cfg["dt"], noise=cfg["noise"],
                          random_state=seed)
    folds = [test for _, test in KFold(n_folds, shuffle=True, random_state=seed).split(X)]
    anchor = fit_sindy_cv(X, cfg["dt"], library=cfg["library"], folds=folds, weak=weak,
                          seed=seed)
    x0, t, end = fresh_states(system, seed)
    return anchor, fresh_state_error(anchor, x0, t, end, cfg["wrap"])


def main(argv=None):
    """Print the fresh-state errors of the strong and weak anchors, per scene and seed."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", default=["pendulum", "henon_heiles"],
                        choices=sorted(demo_scenes()))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--forms", nargs="+", default=["strong", "weak"],
                        choices=["strong", "weak"])
    parser.add_argument("--quick", action="store_true", help="100 trajectories per scene")
    parser.add_argument("--equations", action="store_true", help="print the learned fields")
    args = parser.parse_args(argv)
    ps, reason = C.sindy_status()
    if ps is None:
        raise SystemExit(f"# needs pysindy: {reason}")
    print(f"# {reason}; fresh-state error = median over 10 states of the relative state "
          "error at T = 20")
    print(f"{'scene':13s} {'seed':>4s} {'form':6s} {'terms':>5s} {'chosen':28s} "
          f"{'fit s':>6s} {'fresh err':>9s}")
    summary = {}
    for scene in args.scenes:
        for form in args.forms:
            for seed in args.seeds:
                anchor, err = run_demo(scene, seed, form == "weak", quick=args.quick)
                chosen = ", ".join(f"{k}={v:g}" for k, v in anchor.params.items())
                print(f"{scene:13s} {seed:4d} {form:6s} {anchor.n_terms:5d} {chosen:28s} "
                      f"{anchor.fit_time:6.1f} {err:9.4f}", flush=True)
                if args.equations:
                    for line in anchor.equations(demo_scenes()[scene].get("names")):
                        print("    " + line)
                summary.setdefault((scene, form), []).append(err)
    print()
    for (scene, form), errs in summary.items():
        print(f"{scene:13s} {form:6s} median {np.median(errs):.4f}  "
              f"range {min(errs):.4f}-{max(errs):.4f}")


if __name__ == "__main__":
    main()
