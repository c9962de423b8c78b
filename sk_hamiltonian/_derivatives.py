"""Time derivatives (and de-noised states) estimated from sampled trajectories."""

from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from ._differentiation import (
    finite_difference,
    finite_difference_at,
    fit_operators,
    is_uniform,
    noise_level,
    polynomial_operators,
    windowed_irregular,
    windowed_uniform,
)
from ._trajectories import (
    check_n_states,
    check_time_stamps,
    check_trajectories,
    pack_derivatives,
)
from ._outliers import MIN_TRAJECTORIES, NUMBERING, listed, robust_limit
from ._warnings import warn
from .exceptions import OutlierWarning, SmoothingWarning

# Samples per local polynomial with window="auto", per coefficient: enough to
# average the noise, few enough that a degree-5 polynomial follows a
# pendulum sampled at the paper's step (48 samples of dt = 0.01 are a quarter
# of its period) ...
AUTO_WINDOW_PER_COEFFICIENT = 8
# ... and never fewer than this, so that trajectories of up to 48 samples
# (the paper's have 41) keep one polynomial each, as before windows existed,
# whatever the degree.
AUTO_WINDOW_MIN = 48
# The local fits are reported as too stiff when their residuals exceed this
# multiple of what the noise alone leaves ...
MISFIT_RATIO = 3.0
# ... and this fraction of the variable's spread (on clean data the noise
# estimate is round-off, and tiny residuals are no misfit).
MISFIT_FLOOR = 1e-3
# A misfitting trajectory whose log misfit ratio lies more than this many
# (scaled) median absolute deviations above the median trajectory's is named
# as an outlier (OutlierWarning) rather than blamed on the window. Measured
# on the pendulum (200 trajectories of 41 samples, degree 3 or 5): clean or
# noisy trajectories (relative noise 0, 0.02, 0.08) reach at most 1.9; three
# spikes of twice the data's spread put a trajectory at 5.2 or more
# (docs/measurements.rst).
OUTLIER_MADS = 3.5
# Entries of the per-trajectory operators formed at once (float64: 160 MB).
OPERATOR_ENTRIES = 20_000_000


class DerivativeTransformer(TransformerMixin, BaseEstimator):
    """Estimate time derivatives of trajectories, optionally de-noising them.

    Two estimators from Section 2.2 of Wu, Qin & Xiu: second-order finite
    differences for clean data, and for noisy data a least-squares polynomial in
    time, differentiated analytically, whose fitted values also replace the
    noisy states (the paper's de-noising filter). A trajectory no longer than
    ``window`` samples gets one polynomial (the paper's fit); a longer record
    gets a local polynomial over the window centred on each sample.

    The output keeps one sample per trajectory and carries the raw observations
    and their time stamps alongside, so that
    :meth:`HamiltonianRegressor.score` can compare against what was observed
    rather than against this step's own estimates.

    Parameters
    ----------
    dt : float, default=None
        Uniform sampling step of the trajectories. None: each trajectory
        carries its own time stamps in its *first column* (``1 + n_states``
        columns, times strictly increasing, at any spacing), and the
        derivatives and polynomials are computed in those times.
    method : {"polynomial", "finite_difference"}, default="polynomial"
        ``"polynomial"``: least-squares polynomials of degree ``degree`` in
        time (see ``window``). ``"finite_difference"``: second-order
        differences, central inside and one-sided at the ends (the three-point
        formulas of a non-uniform grid when ``dt`` is None); needs at least 3
        samples per trajectory and ignores ``degree``, ``window`` and
        ``smooth_states``.
    degree : int, default=5
        Degree ``Q`` of the time polynomial. It must be smaller than the number
        of samples per trajectory (equal to ``n_times - 1`` interpolates).
    window : int or "auto", default="auto"
        Samples per polynomial fit, larger than ``degree``. A trajectory with
        at most ``window`` samples is fitted by one polynomial; in a longer
        one every sample gets the polynomial fitted to the ``window`` samples
        centred on it (the first and last windows at the ends), a
        Savitzky-Golay filter on uniform grids. ``"auto"``: ``8 * (degree +
        1)`` samples, and at least 48, so that trajectories of up to 48
        samples (the paper's have 41) get one polynomial each whatever the
        degree.
    smooth_states : bool, default=True
        With ``method="polynomial"``, replace the states by the fitted values.

    Attributes
    ----------
    n_features_in_ : int
        Number of state variables ``2d`` seen during :meth:`fit` (the time
        column, with ``dt=None``, is not counted).
    window_ : int
        Samples per polynomial fit (``window``, with ``"auto"`` resolved).

    See Also
    --------
    HamiltonianRegressor : Fits a Hamiltonian to the output of this transformer.
    unpack_derivatives : Splits the output into times, states, derivatives and
        observations.
    sk_hamiltonian.model_selection.segment_trajectories : Cuts long records
        into segments for cross-validation.

    Notes
    -----
    The output is the *derivative layout*: the input container (3-D array or
    list) with a last axis ``[t, states, derivatives, observed]`` of width
    ``1 + 3 * n_states``, with ``t = 0, dt, 2 dt, ...`` or the given time
    stamps. Fitting is stateless: every trajectory is processed on its own.

    With ``method="polynomial"``, the residuals of the fits are compared with
    the noise level estimated from the sixth differences of the samples. A
    few trajectories far above it and far above the rest are named in an
    :class:`~sk_hamiltonian.OutlierWarning` (they are likely corrupt:
    spikes, jumps); a :class:`~sk_hamiltonian.SmoothingWarning` says when the
    others are far above it (the polynomials cannot follow the trajectories,
    and their derivatives are biased).

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import DerivativeTransformer
    >>> t = np.arange(50) * 0.1
    >>> X = np.stack([np.column_stack([-np.sin(t + s), np.cos(t + s)]) for s in (0, 1)])
    >>> Xt = DerivativeTransformer(dt=0.1, degree=8).fit_transform(X)
    >>> Xt.shape
    (2, 50, 7)

    Irregular time stamps go in the first column:

    >>> t = np.cumsum(np.random.default_rng(0).uniform(0.05, 0.15, size=50))
    >>> T = np.column_stack([t, -np.sin(t), np.cos(t)])
    >>> Xt = DerivativeTransformer(method="finite_difference").fit_transform([T])
    >>> bool(np.abs(Xt[0][:, 3] + np.cos(t)).max() < 0.01)  # dp/dt = -cos t
    True
    """

    _parameter_constraints = {
        "dt": [Interval(Real, 0, None, closed="neither"), None],
        "method": [StrOptions({"polynomial", "finite_difference"})],
        "degree": [Interval(Integral, 1, None, closed="left")],
        "window": [StrOptions({"auto"}), Interval(Integral, 2, None, closed="left")],
        "smooth_states": ["boolean"],
    }

    def __init__(
        self, dt=None, *, method="polynomial", degree=5, window="auto", smooth_states=True
    ):
        self.dt = dt
        self.method = method
        self.degree = degree
        self.window = window
        self.smooth_states = smooth_states

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Check the parameters against the trajectories.

        Parameters
        ----------
        X : array-like of shape (n_trajectories, n_times, n_columns) or list of 2-D arrays
            Trajectories: the states sampled every ``dt``, or with ``dt=None``
            the time stamps followed by the states.
        y : None
            Ignored.

        Returns
        -------
        self : DerivativeTransformer
            The transformer.
        """
        self.window_ = self._resolve_window()
        self._check(X)
        return self

    def transform(self, X):
        """Estimate derivatives (and smoothed states) of each trajectory.

        Parameters
        ----------
        X : array-like of shape (n_trajectories, n_times, n_columns) or list of 2-D arrays
            Trajectories: the states sampled every ``dt``, or with ``dt=None``
            the time stamps followed by the states.

        Returns
        -------
        Xt : ndarray of shape (n_trajectories, n_times, 1 + 3 * n_states) or list
            The derivative layout ``[t, states, derivatives, observed]``; a list
            of 2-D arrays if ``X`` was a list.
        """
        check_is_fitted(self)
        times, observed, is_array = self._check(X, reset=False)
        fitted, derivatives = self._estimate(times, observed)
        states = observed
        if self.method == "polynomial":
            self._warn_on_misfit(observed, fitted)
            if self.smooth_states:
                states = fitted
        return pack_derivatives(times, states, derivatives, observed, is_array)

    # -------------------------------------------------------------- estimates
    def _estimate(self, times, observed):
        """Fitted states and derivatives of every trajectory."""
        by_length = {}
        for k, S in enumerate(observed):
            by_length.setdefault(S.shape[0], []).append(k)
        fitted = [None] * len(observed)
        derivatives = [None] * len(observed)
        # Trajectories of one length share the same operators (a uniform step)
        # or the same array shapes (time stamps): one batch per length.
        for n_times, members in by_length.items():
            batch = np.stack([observed[k] for k in members])
            if self.dt is not None:
                smoothed, dXdt = self._estimate_uniform(batch, n_times)
            else:
                smoothed, dXdt = self._estimate_stamped(
                    batch, np.stack([times[k] for k in members])
                )
            for i, k in enumerate(members):
                fitted[k], derivatives[k] = smoothed[i], dXdt[i]
        return fitted, derivatives

    def _estimate_uniform(self, batch, n_times):
        if self.method == "finite_difference":
            return batch, finite_difference(batch, self.dt)
        if n_times <= self.window_:
            smooth, differentiate = polynomial_operators(n_times, self.dt, self.degree)
            return (
                np.einsum("ij,bjk->bik", smooth, batch),
                np.einsum("ij,bjk->bik", differentiate, batch),
            )
        steps = np.full(batch.shape[0], float(self.dt))
        return windowed_uniform(batch, steps, self.degree, self.window_)

    def _estimate_stamped(self, batch, t):
        if self.method == "finite_difference":
            return batch, finite_difference_at(batch, t)
        n_times = t.shape[1]
        if n_times <= self.window_:
            smoothed, dXdt = np.empty_like(batch), np.empty_like(batch)
            # Each trajectory has its own operators: bound their memory.
            chunk = max(1, OPERATOR_ENTRIES // (2 * n_times * n_times))
            for i in range(0, batch.shape[0], chunk):
                smooth, differentiate = fit_operators(t[i : i + chunk], self.degree)
                smoothed[i : i + chunk] = smooth @ batch[i : i + chunk]
                dXdt[i : i + chunk] = differentiate @ batch[i : i + chunk]
            return smoothed, dXdt
        pieces = []
        for S, times in zip(batch, t):
            if is_uniform(times):
                step = (times[-1] - times[0]) / (n_times - 1)
                smoothed, dXdt = windowed_uniform(S[None], [step], self.degree, self.window_)
                pieces.append((smoothed[0], dXdt[0]))
            else:
                pieces.append(windowed_irregular(S, times, self.degree, self.window_))
        return np.stack([p[0] for p in pieces]), np.stack([p[1] for p in pieces])

    def _warn_on_misfit(self, observed, fitted):
        """Warn when the polynomials leave residuals far above the noise level.

        Trajectories whose misfit is far above the others' are named in an
        :class:`~sk_hamiltonian.OutlierWarning` (they are likely corrupt, and
        no window or degree fixes them); a misfit over the rest is a
        :class:`~sk_hamiltonian.SmoothingWarning` with the remedy for the
        polynomials.
        """
        sigma = noise_level(observed)
        if sigma is None:
            return
        samples = np.concatenate(observed)
        spread = _scaled(lambda a: np.std(a, axis=0), samples)
        # Noise alone leaves sigma * sqrt(1 - leverage); a fit of Q + 1
        # coefficients to m samples has mean leverage (Q + 1) / m.
        kept = np.array([
            np.sqrt(max(1.0 - (self.degree + 1) / min(S.shape[0], self.window_), 0.0))
            for S in observed
        ])
        # Root mean square per trajectory and variable (scaled, so that data
        # near the ends of the float range neither overflow nor underflow).
        rms = np.array([
            _scaled(lambda a: np.sqrt(np.mean(a**2, axis=0)), O - F)
            for O, F in zip(observed, fitted)
        ])
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            ratio = rms / (sigma * kept[:, None])
        misfit = (ratio > MISFIT_RATIO) & (rms > MISFIT_FLOOR * spread)
        outliers = self._misfit_outliers(ratio, misfit)
        if outliers.size:
            warn(
                OutlierWarning(
                    f"DerivativeTransformer: the least-squares polynomials leave "
                    f"{outliers.size} of {len(observed)} trajectories with residuals far "
                    f"above the rest, trajectories {listed(outliers)} ({NUMBERING}): "
                    f"up to {np.nanmax(ratio[outliers]):.3g} times the noise level estimated "
                    f"from all the data, against {np.nanmedian(ratio.max(axis=1)):.3g} for "
                    f"the median trajectory. Such trajectories are often corrupt (spikes, jumps, "
                    f"samples out of order, or another system), which no window or degree "
                    f"fits, but may be sound and move much faster than the rest. Inspect "
                    f"them, and drop or repair those that are corrupt before fitting (their "
                    f"indices are in this warning's `trajectories` attribute).",
                    trajectories=outliers,
                ),
                OutlierWarning,
            )
        rest = np.ones(len(observed), dtype=bool)
        rest[outliers] = False
        n_samples = np.array([S.shape[0] for S in observed])[rest]
        if not rest.any():
            return
        # Over the other trajectories together, as root mean squares of all their samples.
        pooled = _scaled(
            lambda a: np.sqrt(np.sum(a**2 * n_samples[:, None], axis=0) / n_samples.sum()),
            rms[rest],
        )
        pooled_kept = np.sqrt(np.sum(kept[rest] ** 2 * n_samples) / n_samples.sum())
        with np.errstate(divide="ignore", invalid="ignore"):
            overall = pooled / (sigma * pooled_kept)
        misfit = (overall > MISFIT_RATIO) & (pooled > MISFIT_FLOOR * spread)
        if not misfit.any():
            return
        worst = int(np.flatnonzero(misfit)[np.argmax(overall[misfit])])
        size = "far" if not np.isfinite(overall[worst]) else f"{overall[worst]:.3g} times"
        warn(
            SmoothingWarning(
                f"DerivativeTransformer: the least-squares polynomials (degree={self.degree}, "
                f"window={self.window_} samples) leave residuals {size} above the noise level "
                f"estimated from the data (state variable {worst}): they cannot follow the "
                f"trajectories, and their derivatives are biased. Use a smaller `window` or a "
                f"larger `degree` (a cross-validated search over both finds the balance), or "
                f"method='finite_difference' for clean data.",
                ratio=overall[worst] if np.isfinite(overall[worst]) else np.inf,
            ),
            SmoothingWarning,
        )

    def _misfit_outliers(self, ratio, misfit):
        """Trajectories that misfit and whose misfit ``ratio`` is far above the others'.

        Far above: the logarithm of a trajectory's largest ratio lies more
        than ``OUTLIER_MADS`` (scaled) median absolute deviations above the
        median over all trajectories. None among fewer than
        ``MIN_TRAJECTORIES``: too few to say what is typical.
        """
        if ratio.shape[0] < MIN_TRAJECTORIES:
            return np.zeros(0, dtype=np.intp)
        with np.errstate(divide="ignore", invalid="ignore"):
            worst = np.log(np.nanmax(np.where(np.isnan(ratio), 0.0, ratio), axis=1))
        typical = worst[np.isfinite(worst)]
        if typical.size < MIN_TRAJECTORIES:
            return np.zeros(0, dtype=np.intp)
        return np.flatnonzero(misfit.any(axis=1) & (worst > robust_limit(typical, OUTLIER_MADS)))

    # ------------------------------------------------------------- validation
    def _resolve_window(self):
        if self.window == "auto":
            return max(AUTO_WINDOW_MIN, AUTO_WINDOW_PER_COEFFICIENT * (self.degree + 1))
        if self.method == "polynomial" and self.window <= self.degree:
            raise ValueError(
                f"window={self.window} must exceed degree={self.degree}: a polynomial of "
                f"degree {self.degree} needs at least {self.degree + 1} samples (several "
                f"times as many to average out noise). Raise `window` or lower `degree`."
            )
        return int(self.window)

    def _check(self, X, reset=True):
        """Validated trajectories: lists of times and of states, and the container kind."""
        if self.method == "finite_difference":
            min_times, why = 3, "second-order finite differences need at least 3 samples"
        else:
            min_times = self.degree + 1
            why = (
                f"a polynomial of degree={self.degree} needs at least {min_times} "
                f"samples; lower `degree` or use method='finite_difference'"
            )
        try:
            trajectories, is_array = check_trajectories(X, min_times=min_times)
        except ValueError as error:
            if "sample(s)" in str(error):
                raise ValueError(f"{error} Here {why}.") from None
            raise
        if self.dt is None:
            times, states = self._split_times(trajectories)
        else:
            states = trajectories
            times = [self.dt * np.arange(S.shape[0]) for S in states]
        n_states = states[0].shape[1]
        check_n_states(n_states)
        if reset:
            self.n_features_in_ = n_states
        elif n_states != self.n_features_in_:
            raise ValueError(
                f"X has {n_states} state variables, but DerivativeTransformer was "
                f"fitted with {self.n_features_in_}."
            )
        return times, states, is_array

    def _split_times(self, trajectories):
        width = trajectories[0].shape[1]
        if width % 2 == 0:
            raise ValueError(
                f"DerivativeTransformer(dt=None) reads each trajectory's time stamps from "
                f"its first column, followed by the states (1 + n_states columns, an odd "
                f"number); X has {width} columns. Either pass the sampling step of "
                f"uniformly sampled states, e.g. DerivativeTransformer(dt=0.01), or "
                f"prepend the time stamps as the first column."
            )
        check_time_stamps(trajectories)
        return [T[:, 0] for T in trajectories], [T[:, 1:] for T in trajectories]

    def set_output(self, *, transform=None):
        """Refuse DataFrame output: the derivative layout is 3-D (or ragged).

        scikit-learn's ``set_output`` API turns a transformer's 2-D output into
        a pandas or polars DataFrame. The output of this transformer is the
        derivative layout, one 2-D block per trajectory (a 3-D array, or a list
        of 2-D arrays of different lengths), which a DataFrame cannot hold
        without losing the trajectories; so only the default output exists.
        Use :func:`unpack_derivatives` to get the times, states and
        derivatives of each trajectory as arrays, and build frames from those.

        Parameters
        ----------
        transform : {"default"} or None, default=None
            ``"default"`` or None: keep the default output (nothing changes).

        Returns
        -------
        self : DerivativeTransformer
            The transformer, unchanged.

        Raises
        ------
        ValueError
            For ``transform="pandas"`` or ``"polars"`` (also when a
            :class:`~sklearn.pipeline.Pipeline` holding this transformer is
            asked for them).

        See Also
        --------
        unpack_derivatives : Splits the output into times, states, derivatives
            and observations.

        Examples
        --------
        >>> from sk_hamiltonian import DerivativeTransformer
        >>> DerivativeTransformer().set_output(transform="default")
        DerivativeTransformer()
        """
        if transform in (None, "default"):
            return self
        raise ValueError(
            f"DerivativeTransformer cannot output {transform!r}: its output is the derivative "
            f"layout, one 2-D block per trajectory (a 3-D array or a list of arrays), which a "
            f"DataFrame cannot hold. Keep the default output; to look at the result as "
            f"tables, split it with sk_hamiltonian.unpack_derivatives and build frames from "
            f"the times, states and derivatives of each trajectory."
        )

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False
        tags.input_tags.three_d_array = True
        tags.requires_fit = True
        return tags


def _scaled(statistic, values):
    """``statistic(values)`` per column, computed on ``values`` scaled to at most 1.

    For root mean squares and standard deviations: each column is divided
    by its largest magnitude first and the result multiplied back, so that
    the squares neither overflow nor underflow.
    """
    largest = np.abs(values).max(axis=0) if values.size else np.ones(values.shape[1:])
    largest = np.where((largest > 0) & np.isfinite(largest), largest, 1.0)
    return largest * statistic(values / largest)
