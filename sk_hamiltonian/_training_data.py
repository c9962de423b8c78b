"""Training data of a fit: validated input, its trajectories, and the quadrature of its rows.

:func:`training_data` validates what a regressor's ``fit`` takes (2-D
states with derivatives, or the derivative layout of trajectories) into a
:class:`TrainingData`; :meth:`TrainingData.quadrature` says where each row
group of a fit evaluates the basis and what it is fitted to (see
:mod:`sk_hamiltonian._design` for the designs built on it).
"""

import numpy as np
from sklearn.utils.validation import _check_sample_weight, validate_data

from ._space.legendre import gauss_on_unit
from ._trajectories import is_trajectory_container, unpack_derivatives

# The weak form's windows: samples per window, windows per window length
# (the stride is the length over this), and the power of the test function.
WEAK_WINDOW = 21
WEAK_OVERLAP = 4
WEAK_POWER = 4
# Largest magnitude of a training state or derivative: squares of 1e100
# summed over any number of rows, and H~ ~ 1e100 * 1e100, stay far below the
# float64 overflow at 1.8e308 (see check_magnitude).
LARGEST_VALUE = 1e100


def training_data(estimator, X, y, sample_weight, reset=True):
    """Validate a regressor's input (``validate_data`` on ``estimator``) and gather what the fit needs.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        The estimator whose ``n_features_in_`` (and feature names) the
        validation sets (``reset=True``) or checks.
    X, y, sample_weight
        As ``fit`` takes them.
    reset : bool, default=True
        Whether this is a new fit (see :func:`sklearn.utils.validation.validate_data`).

    Returns
    -------
    data : TrainingData
    """
    if not is_trajectory_container(X):
        # float64 throughout: one dtype for every fitted array (and model file).
        X, y = validate_data(estimator, X, y, multi_output=True, y_numeric=True, reset=reset,
                             dtype=np.float64)
        weight = None if sample_weight is None else _checked_weight(sample_weight, X, "state")
        check_magnitude(X, y, type(estimator).__name__)
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
        estimator, np.concatenate(states), np.concatenate(derivatives), multi_output=True,
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
        trajectory_weight = _checked_weight(trajectory_weight, states, "trajectory")
        weight = np.repeat(trajectory_weight, lengths)
    check_magnitude(X2, y2, type(estimator).__name__)
    pieces = np.split(X2, np.cumsum(lengths)[:-1])
    return TrainingData(
        X2, y2, weight, trajectories=list(zip(times, pieces)),
        trajectory_weight=trajectory_weight,
    )


def _checked_weight(sample_weight, X, unit):
    """scikit-learn's check of ``sample_weight``, and a message for negative weights.

    A negative weight makes the weighted least squares indefinite: the fit
    fails in LAPACK ("SVD did not converge") or, with every weight negative,
    finds no sample left; neither names the argument.
    """
    weight = _check_sample_weight(sample_weight, X)
    negative = np.flatnonzero(weight < 0)
    if negative.size:
        first = negative[0]
        raise ValueError(
            f"sample_weight must be non-negative (one weight per {unit}; 0 leaves it out); "
            f"got {weight[first]:g} at index {first}"
            + (f" and {negative.size - 1} more negative" if negative.size > 1 else "")
            + ". Drop the sign, or leave those out with 0."
        )
    return weight


def check_magnitude(states, targets, name="estimator"):
    """Refuse states or targets so large that the fit would overflow float64.

    The fit sums squares of the targets and of the basis' derivatives (which
    scale as one over the box's width), and the learned ``H~`` is of the
    order of the states times their derivatives: beyond
    :data:`LARGEST_VALUE` these overflow (or underflow) and the coefficients
    come out inf, NaN or wrong. An error names the scale and the fix.
    """
    for what, values in (("states X", states), ("time derivatives y", targets)):
        largest = float(np.max(np.abs(values))) if values.size else 0.0
        if largest > LARGEST_VALUE:
            raise ValueError(
                f"{name}: the {what} reach {largest:.3g} in magnitude, beyond "
                f"{LARGEST_VALUE:g}: at this scale the fit's sums of squares overflow float64 "
                f"(the learned H~ is of the order of the states times their derivatives), "
                f"and its coefficients would be inf, NaN or wrong. Rescale the data to units "
                f"in which each variable spans about 1 (divide it by a power of ten; its time "
                f"derivative scales with it, and inversely with the unit of time)."
            )


class TrainingData:
    """States, targets and (optionally) steps and weights of one fit.

    Parameters
    ----------
    states : ndarray of shape (n_samples, n_states)
        States the derivative fit evaluates the basis at.
    derivatives : ndarray of shape (n_samples, n_targets) or None
        Targets of the derivative fit.
    sample_weight : ndarray of shape (n_samples,) or None
        Weights of the states.
    trajectories : list of (times, states) or None
        The trajectories the states came from (derivative layout input), for
        the steps fit and the energy check.
    trajectory_weight : ndarray of shape (n_trajectories,) or None
        Weights of the trajectories, applied to their steps.
    """

    def __init__(self, states, derivatives, sample_weight=None, trajectories=None,
                 trajectory_weight=None):
        self.states = states
        self.derivatives = derivatives
        self.sample_weight = sample_weight
        self.trajectories = trajectories
        self.trajectory_weight = trajectory_weight

    def take_trajectories(self, indices):
        """The training data of some of the trajectories, in the order of ``indices``.

        What a fit on those trajectories alone would see (e.g. the training
        folds of a cross-validation): their states, derivatives, weights and
        steps. Needs trajectories (the derivative layout).

        Parameters
        ----------
        indices : array-like of int
            Trajectory numbers.

        Returns
        -------
        data : TrainingData
        """
        if self.trajectories is None:
            raise ValueError(
                "take_trajectories needs trajectories: these training data are 2-D "
                "states with derivatives. Build them from the derivative layout."
            )
        indices = np.asarray(indices, dtype=np.intp).ravel()
        lengths = np.array([S.shape[0] for _, S in self.trajectories], dtype=np.intp)
        starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
        rows = np.concatenate(
            [np.arange(starts[k], starts[k] + lengths[k]) for k in indices]
        ) if indices.size else np.zeros(0, dtype=np.intp)

        def take(a):
            return None if a is None else a[rows]

        return TrainingData(
            self.states[rows], self.derivatives[rows], take(self.sample_weight),
            trajectories=[self.trajectories[k] for k in indices],
            trajectory_weight=(None if self.trajectory_weight is None
                               else self.trajectory_weight[indices]),
        )

    def median_step(self):
        """Median sampling step of the trajectories (NaN without them)."""
        if self.trajectories is None:
            return float("nan")
        steps = np.concatenate([np.diff(t) for t, _ in self.trajectories])
        return float(np.median(steps)) if steps.size else float("nan")

    def steps(self, space):
        """Observed steps ``(x0, dx, dt, weight)`` of every trajectory.

        ``dx`` takes periodic variables the short way round the circle, so a
        trajectory given with wrapped angles still has small steps.
        """
        if self.trajectories is None:
            raise ValueError(
                "fit_on='steps' fits the observed steps of trajectories: pass the "
                "output of DerivativeTransformer (trajectories with their times), not "
                "2-D states with derivatives."
            )
        starts, moves, dts, weights = [], [], [], []
        for k, (t, S) in enumerate(self.trajectories):
            starts.append(S[:-1])
            moves.append(space.wrap_difference(np.diff(S, axis=0)))
            dts.append(np.diff(t))
            w = 1.0 if self.trajectory_weight is None else self.trajectory_weight[k]
            weights.append(np.full(S.shape[0] - 1, w))
        x0 = np.concatenate(starts)
        if x0.shape[0] == 0:
            raise ValueError(
                "fit_on='steps' needs trajectories with at least two samples; every "
                "trajectory here has one."
            )
        return x0, np.concatenate(moves), np.concatenate(dts), np.concatenate(weights)

    def pairs(self, space):
        """Pairs of consecutive steps ``(x0, x1, x2, h1, h2, weight)`` of every trajectory."""
        self._check_pairs()
        parts = []
        for k, (t, S) in enumerate(self.trajectories):
            moves = space.wrap_difference(np.diff(S, axis=0))
            h = np.diff(t)
            w = 1.0 if self.trajectory_weight is None else self.trajectory_weight[k]
            parts.append((S[:-2], S[1:-1], S[2:], moves[:-1] + moves[1:], h[:-1], h[1:],
                          np.full(S.shape[0] - 2, w)))
        return tuple(np.concatenate(column) for column in zip(*parts))

    def _check_pairs(self):
        if self.trajectories is None:
            raise ValueError(
                "fit_on='simpson' fits pairs of observed steps of trajectories: pass "
                "the output of DerivativeTransformer (trajectories with their times), "
                "not 2-D states with derivatives."
            )
        short = [k for k, (_, S) in enumerate(self.trajectories) if S.shape[0] < 3]
        if short:
            raise ValueError(
                f"fit_on='simpson' needs at least three samples per trajectory (one pair "
                f"of steps); {len(short)} of {len(self.trajectories)} trajectories have "
                f"fewer (the first is number {short[0]}). Drop them, or fit with "
                f"fit_on='steps'."
            )

    def windows(self, space, length=None, stride=None):
        """Weak-form windows of every trajectory: the points, weights and rates of their rows.

        Each window of ``length`` consecutive samples (``stride`` apart; a
        shorter trajectory is one window) gives one row group: the test
        function ``phi(s) = (1 - s**2)**WEAK_POWER`` over the window (``s``
        from -1 to 1), integrated by the trapezoid rule on the samples'
        times, so that ``int phi f(x) dt = -int phi' x dt`` holds without any
        derivative estimate, ``phi`` vanishing at both ends. Rows are
        normalized by ``int phi dt``: the weights of the points sum to one
        and the rate is a weighted mean of ``dx/dt``. Periodic variables are
        unwrapped within a window.

        Returns
        -------
        points : ndarray of shape (n_windows, length, n_states)
        weights : ndarray of shape (n_windows, length)
            Zero beyond a short trajectory's samples.
        rate : ndarray of shape (n_windows, n_states)
        group_weight : ndarray of shape (n_windows,)
        """
        width, stride = self._window_layout(length, stride)
        points, weights, rates, group = [], [], [], []
        for k, (t, S) in enumerate(self.trajectories):
            size = min(width, S.shape[0])
            starts = _window_starts(S.shape[0], width, stride)
            unwrapped = S[0] + np.concatenate(
                [np.zeros((1, S.shape[1])), np.cumsum(space.wrap_difference(np.diff(S, axis=0)),
                                                      axis=0)])
            w_traj = 1.0 if self.trajectory_weight is None else self.trajectory_weight[k]
            for a in starts:
                tt, X = t[a : a + size], unwrapped[a : a + size]
                span = tt[-1] - tt[0]
                s = 2.0 * (tt - tt[0]) / span - 1.0
                phi = (1.0 - s**2) ** WEAK_POWER
                dphi = -2.0 * WEAK_POWER * s * (1.0 - s**2) ** (WEAK_POWER - 1) * (2.0 / span)
                trapezoid = np.zeros(size)
                h = np.diff(tt)
                trapezoid[:-1] += h / 2
                trapezoid[1:] += h / 2
                mass = np.sum(trapezoid * phi)
                pad = width - size
                points.append(np.concatenate([X, np.repeat(X[-1:], pad, axis=0)]))
                weights.append(np.concatenate([trapezoid * phi / mass, np.zeros(pad)]))
                rates.append(-(trapezoid * dphi) @ X / mass)
                group.append(w_traj)
        return (np.array(points), np.array(weights), np.array(rates), np.array(group))

    def quadrature(self, space, fit_on, n_nodes):
        """The :class:`Quadrature` of the fit's row groups."""
        if fit_on == "weak":
            X, w, rate, group = self.windows(space)
            points = [(X[:, i], w[:, i]) for i in range(X.shape[1])]
            return Quadrature(points, rate, None if self.trajectory_weight is None else group)
        if fit_on == "steps":
            x0, dx, dt, weight = self.steps(space)
            nodes, node_weights = gauss_on_unit(n_nodes)
            points = [(x0 + s * dx, w) for s, w in zip(nodes, node_weights)]
            return Quadrature(points, dx / dt[:, None], weight)
        if fit_on == "simpson":
            x0, x1, x2, move, h1, h2, weight = self.pairs(space)
            # Simpson's rule on two intervals of any lengths, normalized to sum to one.
            points = [
                (x0, (2.0 - h2 / h1) / 6.0),
                (x1, (h1 + h2) ** 2 / (6.0 * h1 * h2)),
                (x2, (2.0 - h1 / h2) / 6.0),
            ]
            return Quadrature(points, move / (h1 + h2)[:, None], weight)
        return Quadrature([(self.states, 1.0)], self.derivatives, self.sample_weight)

    def windows_count(self, length=None, stride=None):
        """Number of weak-form windows (row groups) of :meth:`windows`."""
        return int(self._windows_per_trajectory(length, stride).sum())

    def _windows_per_trajectory(self, length=None, stride=None):
        """Windows of each trajectory in :meth:`windows`."""
        width, stride = self._window_layout(length, stride)
        return np.array([len(_window_starts(S.shape[0], width, stride))
                         for _, S in self.trajectories], dtype=np.intp)

    def _window_layout(self, length, stride):
        """The weak form's window width (capped at the longest trajectory) and stride."""
        self._check_trajectories("weak", 3)
        length = WEAK_WINDOW if length is None else length
        stride = max(1, length // WEAK_OVERLAP) if stride is None else stride
        return min(length, max(S.shape[0] for _, S in self.trajectories)), stride

    def _check_trajectories(self, fit_on, fewest):
        if self.trajectories is None:
            raise ValueError(
                f"fit_on={fit_on!r} fits trajectories: pass the output of "
                f"DerivativeTransformer (trajectories with their times), not 2-D states with "
                f"derivatives."
            )
        short = [k for k, (_, S) in enumerate(self.trajectories) if S.shape[0] < fewest]
        if short:
            raise ValueError(
                f"fit_on={fit_on!r} needs at least {fewest} samples per trajectory; "
                f"{len(short)} of {len(self.trajectories)} trajectories have fewer (the first "
                f"is number {short[0]}). Drop them, or fit with fit_on='steps'."
            )

    def groups_per_trajectory(self, fit_on):
        """Row groups of each trajectory in :meth:`quadrature`, whose groups run trajectory by trajectory.

        A state each (``"derivatives"``), a step each (``"steps"``), a pair
        of steps each (``"simpson"``) or a window each (``"weak"``). Needs
        trajectories.

        Returns
        -------
        counts : ndarray of shape (n_trajectories,) of int
        """
        if self.trajectories is None:
            raise ValueError(
                "groups_per_trajectory needs trajectories: these training data are 2-D "
                "states with derivatives. Build them from the derivative layout."
            )
        lengths = np.array([S.shape[0] for _, S in self.trajectories], dtype=np.intp)
        if fit_on == "steps":
            return np.maximum(lengths - 1, 0)
        if fit_on == "simpson":
            self._check_pairs()
            return lengths - 2
        if fit_on == "weak":
            return self._windows_per_trajectory()
        return lengths

    def n_rows(self, fit_on):
        """Number of state (or step) row groups the fit will have."""
        if fit_on == "steps" and self.trajectories is not None:
            return sum(max(0, S.shape[0] - 1) for _, S in self.trajectories)
        if fit_on == "simpson":
            self._check_pairs()
            return sum(S.shape[0] - 2 for _, S in self.trajectories)
        if fit_on == "weak":
            return self.windows_count()
        return self.states.shape[0]


def _window_starts(n, width, stride):
    """First samples of the windows of a trajectory of ``n`` samples (one if it is shorter)."""
    if n <= width:
        return [0]
    starts = list(range(0, n - width + 1, stride))
    if starts[-1] != n - width:
        starts.append(n - width)  # the trajectory's end in a window too
    return starts


class Quadrature:
    """Where a fit's row groups evaluate the basis, and what they are fitted to.

    Row group ``r`` fits ``sum_k w_k[r] f(X_k[r]) ≈ rate[r]`` for the model's
    field (or its gradient) ``f``.

    Parameters
    ----------
    points : list of (ndarray of shape (n_groups, n_states), float or ndarray of shape (n_groups,))
        The points ``X_k`` and their weights ``w_k``.
    rate : ndarray of shape (n_groups, n_states) or (n_groups, n_targets)
        The time derivative (or mean rate of change) each group fits.
    weight : ndarray of shape (n_groups,) or None
        Weights of the row groups.
    """

    def __init__(self, points, rate, weight):
        self.points = points
        self.rate = rate
        self.weight = weight
        self.n_groups = rate.shape[0]

    def scale(self, values, w, rows):
        """Multiply ``values`` (rows on the last axis) in place by a point's weights."""
        if np.isscalar(w):
            if w != 1.0:
                values *= w
        else:
            values *= w[rows]
        return values

    def weighted_sum(self, function, rows):
        """``sum_k w_k function(X_k[rows])``, each result with the rows on its last axis."""
        total = None
        for X, w in self.points:
            part = self.scale(function(X[rows]), w, rows)
            total = part if total is None else total + part
        return total
