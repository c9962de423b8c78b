"""Observed trajectories as the trajectory fit takes them: short segments, grouped by sample times.

Over many periods a small error of frequency becomes a large error of phase,
and near a separatrix (or in a chaotic region) a small error of the state
grows exponentially: the output-error cost of a whole long record then has
many minima. The fit therefore simulates each record in *segments*, each from
an initial state of its own (the segments partition the samples; no sample
is counted twice). A record longer than :data:`SEGMENT_PERIODS` periods of
the model (``2 pi time_scale``) is cut into pieces of equal span, as few as
keep each within that many periods, and a segment also ends
(:func:`shooting_segments`) where the model's local instability would have
grown an error of its initial state more than :data:`MAX_GROWTH` times (the
integral over the segment of the largest real part of the eigenvalues of the
field's Jacobian, at the observed states, stays below ``log(MAX_GROWTH)``);
no segment has fewer than :data:`MIN_SEGMENT_SAMPLES` samples. Short
trajectories, such as the paper's 0.4-second bursts, stay whole.

Each segment's initial state is a free parameter, and what a segment tells
about the coefficients grows with its span (a frequency shows in the phase
it accumulates): half-period pieces left the fit of an anharmonic spring's
single record worse than its least-squares start (coefficient error 0.0047
against 0.00076), where pieces of up to two periods give 9.7e-5; on
Henon-Heiles' three records of 2 001 samples they bring the coefficients
closer to the truth on every seed (0.0014, 0.0010, 0.0008 against 0.0025,
0.0016, 0.0010), though least squares stays closer on two of the three.

Segments of similar lengths are integrated side by side
(:func:`group_by_times`), each with RK4 steps of its own when their time
stamps differ; Python's cost per step, not the arithmetic, is what a
segment integrated alone would pay.
"""

import math

import numpy as np

from .solver import TrajectoryFitError

# A segment spans at most this many periods (2 pi time_scale) of the model
# (a trajectory up to that long stays whole, a longer one is cut into equal
# pieces) ...
SEGMENT_PERIODS = 2.0
# ... and ends before the model's instability grows an error of its initial
# state more than this many times.
MAX_GROWTH = 10.0
# ... and never fewer samples than this, so that its initial state is
# well determined by the samples that follow it.
MIN_SEGMENT_SAMPLES = 11
# Segments integrated side by side have at least this fraction of the samples
# of the longest among them (the others are padded: their work is wasted).
PADDED_FRACTION = 0.7
# A model that needs more RK4 steps than this between two samples is too
# stiff for its trajectories to be fitted (its time scale is far below the
# data's: degenerate data, or a fit that went wrong).
MAX_SUBSTEPS = 200


def split_times(trajectories, dt):
    """Time stamps and states of each trajectory.

    Parameters
    ----------
    trajectories : list of ndarray of shape (n_times_k, n_columns)
        With their time stamps in the first column when ``dt`` is None.
    dt : float or None

    Returns
    -------
    times : list of ndarray of shape (n_times_k,)
    states : list of ndarray of shape (n_times_k, n_states)
    """
    if dt is None:
        return [T[:, 0] for T in trajectories], [T[:, 1:] for T in trajectories]
    return [dt * np.arange(len(T)) for T in trajectories], list(trajectories)


def shooting_segments(times, states, max_duration, rates=None):
    """Cut each trajectory into contiguous segments of bounded span and growth.

    Parameters
    ----------
    times : list of ndarray of shape (n_times_k,)
    states : list of ndarray of shape (n_times_k, n_states)
    max_duration : float
        Longest span of a segment; ``inf`` for none.
    rates : list of ndarray of shape (n_times_k,), default=None
        The model's local growth rate at each sample (the largest real part
        of its Jacobian's eigenvalues, at least zero); None: no bound on the
        growth.

    Returns
    -------
    times, states : list of ndarray
        The segments.
    owner : ndarray of int
        The trajectory each segment comes from.
    """
    budget = np.log(MAX_GROWTH)
    out_times, out_states, owner = [], [], []
    for k, (t, Y) in enumerate(zip(times, states)):
        # Equal pieces, as few as keep each within max_duration: a piece
        # just past the bound would leave a short remainder with an initial
        # state of its own and little to tell about the coefficients.
        total = t[-1] - t[0]
        span = total / math.ceil(total / max_duration) if total > max_duration else np.inf
        growth = np.zeros(len(t))
        if rates is not None:
            r = rates[k]
            growth[1:] = np.cumsum(np.diff(t) * (r[1:] + r[:-1]) / 2)
        start = 0
        for stop in _cuts(t, growth, span, budget):
            out_times.append(t[start:stop])
            out_states.append(Y[start:stop])
            owner.append(k)
            start = stop
    return out_times, out_states, np.array(owner, dtype=np.intp)


def _cuts(t, growth, max_duration, budget):
    """Ends of the segments of one trajectory (exclusive), greedily from its start."""
    n = len(t)
    cuts, start = [], 0
    while n - start >= 2 * MIN_SEGMENT_SAMPLES:
        inside = (t[start:] - t[start] <= max_duration) & (growth[start:] - growth[start] <= budget)
        stop = start + max(int(np.argmin(inside)) if not inside.all() else n - start,
                           MIN_SEGMENT_SAMPLES)
        if stop >= n or n - stop < MIN_SEGMENT_SAMPLES:
            break
        cuts.append(stop)
        start = stop
    return cuts + [n]


def growth_rates(jacobian, states):
    """The largest real part of the Jacobian's eigenvalues at each state, at least zero.

    Parameters
    ----------
    jacobian : callable
        ``jacobian(X)``: ndarray of shape (n_samples, n_states, n_states).
    states : list of ndarray of shape (n_times_k, n_states)

    Returns
    -------
    rates : list of ndarray of shape (n_times_k,)
    """
    stacked = np.concatenate(states)
    with np.errstate(all="ignore"):
        J = jacobian(stacked)
        finite = np.isfinite(J).all(axis=(1, 2))
        rate = np.zeros(len(stacked))
        rate[finite] = np.max(np.linalg.eigvals(J[finite]).real, axis=1)
    rate = np.where(finite, np.maximum(rate, 0.0), np.inf)
    return np.split(rate, np.cumsum([len(Y) for Y in states])[:-1])


def group_by_times(times, states, max_step):
    """Segments grouped to be integrated side by side, with the RK4 steps between their samples.

    Segments are sorted by length; a group holds segments of at least
    :data:`PADDED_FRACTION` of its longest one's samples, the shorter ones
    padded at their end with their last observation, which does not count
    (the group's ``mask``) and which steps of zero leave unchanged. Each
    interval between samples is cut into equal steps of at most
    ``max_step``, each segment with steps of its own when their sample times
    differ.

    Parameters
    ----------
    times : list of ndarray of shape (n_times_k,)
    states : list of ndarray of shape (n_times_k, n_states)
    max_step : float

    Returns
    -------
    groups : list of (ndarray, list of ndarray, ndarray)
        ``(Y, steps, mask)`` as :func:`~.solver.fit_trajectories` takes them.
    members : list of ndarray of int
        The segments of each group, in its order.
    """
    lengths = np.array([len(t) for t in times])
    order = np.argsort(-lengths, kind="stable")
    groups, members = [], []
    start = 0
    while start < len(order):
        longest = lengths[order[start]]
        stop = start
        while stop < len(order) and lengths[order[stop]] >= PADDED_FRACTION * longest:
            stop += 1
        indices = order[start:stop]
        groups.append(_padded_group([times[k] for k in indices],
                                    [states[k] for k in indices], longest, max_step))
        members.append(indices.astype(np.intp))
        start = stop
    return groups, members


def _padded_group(times, states, n_times, max_step):
    """``(Y, steps, mask)`` of segments padded to ``n_times`` samples."""
    n, d = len(times), states[0].shape[1]
    Y = np.empty((n, n_times, d))
    mask = np.zeros((n, n_times), dtype=bool)
    intervals = np.zeros((n, n_times - 1))
    for i, (t, S) in enumerate(zip(times, states)):
        m = len(t)
        Y[i, :m], Y[i, m:] = S, S[-1]
        mask[i, :m] = True
        intervals[i, : m - 1] = np.diff(t)
    if np.allclose(intervals, intervals[:1], rtol=1e-12, atol=0.0):
        intervals = intervals[:1]  # one step for every segment
    steps = []
    for h in intervals.T:
        count = max(1, math.ceil(np.max(h) / max_step - 1e-9))
        if count > MAX_SUBSTEPS:
            raise TrajectoryFitError(
                f"the model needs {count} integration steps between two samples (its time "
                f"scale is far below the data's sampling)")
        steps.append(np.repeat((h / count)[np.newaxis], count, axis=0) if len(h) > 1
                     else np.full(count, h[0] / count))
    return Y, steps, mask
