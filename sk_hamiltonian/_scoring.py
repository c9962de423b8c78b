"""Errors of predictions from held-out observations: the honest score.

Shared by the regressors' default ``score`` (one rollout per trajectory) and
:func:`sk_hamiltonian.model_selection.multistep_scorer` (short predictions from
every observation). Only the raw observations and their time stamps enter, never
the derivatives or smoothed states of the step being tuned.
"""

import numpy as np

from ._integrate import integrate
from ._trajectories import unpack_derivatives

# Predictions subdivide each sampling interval so that integration error stays
# well below model error.
ROLLOUT_SUBSTEPS = 4
# Relative time stamps whose steps differ by less than this fraction of their
# span form a uniform grid (stamps k * dt differ from it by round-off only).
GRID_TOLERANCE = 1e-9


def multistep_errors(model, Xt, n_steps=None, *, stride=1, substeps=ROLLOUT_SUBSTEPS):
    """Relative errors of ``n_steps``-ahead predictions from observed states.

    From every ``stride``-th observation of each held-out trajectory (that has
    ``n_steps`` observations after it), the model is integrated ``n_steps``
    sampling intervals ahead and compared with the observations it passes.
    Each prediction is compared over its whole segment, its starting
    observation included (where it is exact), as the default score compares
    its single rollout: with ``n_steps`` at least the number of intervals, the
    two coincide. Predictions on uniform grids of one step are integrated in
    one batch whatever their lengths (see :func:`shared_grids`), each over its
    own time stamps only.

    Parameters
    ----------
    model : fitted HamiltonianRegressor or VectorFieldRegressor
        The model to integrate (by RK4).
    Xt : derivative layout
        Held-out trajectories from :class:`DerivativeTransformer`; only their
        times and raw observations are used.
    n_steps : int or None, default=None
        Prediction horizon, in sampling intervals. Trajectories with at most
        ``n_steps`` intervals use one prediction over their whole length; None
        does so for every trajectory (the regressors' default score).
    stride : int, default=1
        Distance between starts, in samples.
    substeps : int, default=4
        Integration steps per sampling interval (per median interval, for
        irregular time stamps).

    Returns
    -------
    errors : ndarray of shape (n_trajectories,)
        Root-mean-square of ``(X_hat - X) / state_scale_`` per trajectory over
        all its predicted segments (periodic variables the short way round):
        errors in units of each variable's spread over the training states,
        so they do not change when the data are translated. ``inf`` where a
        prediction failed.
    """
    data = unpack_derivatives(Xt)
    times, observed = list(data.times), list(data.observed)
    starts, targets, rel_times, owner = [], [], [], []
    for k, (t, O) in enumerate(zip(times, observed)):
        horizon = t.shape[0] - 1 if n_steps is None else min(n_steps, t.shape[0] - 1)
        for j in range(0, t.shape[0] - horizon, stride):
            starts.append(O[j])
            targets.append(O[j : j + horizon + 1])
            rel_times.append(t[j : j + horizon + 1] - t[j])
            owner.append(k)
    predictions, failed_segment = predict_segments(model, starts, rel_times, substeps)
    owner = np.array(owner, dtype=int)
    squared_error = np.zeros(len(observed))
    count = np.zeros(len(observed))
    for i, (Y, T) in enumerate(zip(predictions, targets)):
        if Y is None or failed_segment[i]:
            continue
        squared_error[owner[i]] += np.sum(scaled_difference(model, Y, T) ** 2)
        count[owner[i]] += T.size
    failed = np.zeros(len(observed), dtype=bool)
    failed[owner[failed_segment]] = True
    with np.errstate(invalid="ignore", divide="ignore"):
        errors = np.sqrt(squared_error / np.maximum(count, 1))
    errors[failed] = np.inf
    return errors


def scaled_difference(model, Y, T):
    """``(Y - T) / state_scale_``, periodic variables the short way round.

    A failed prediction holds its last finite, possibly huge, state; callers
    set its error to inf, so an overflow here changes nothing.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        return model._space.wrap_difference(Y - T) / model.state_scale_


def predict_segments(model, starts, rel_times, substeps=ROLLOUT_SUBSTEPS):
    """Integrate each start over its own relative time stamps, in batches.

    Parameters
    ----------
    model : fitted regressor
        Integrated with its own method: RK4 for a derivative fit (stepped a
        ``1 / substeps`` of a sampling interval), AVF at the training step
        for a fit on steps.
    starts : list of ndarray of shape (n_states,)
        Initial states.
    rel_times : list of ndarray of shape (n_times_i,)
        Time stamps of each segment relative to its start.
    substeps : int, default=4
        Integration steps per (median) sampling interval.

    Returns
    -------
    predictions : list of ndarray of shape (n_times_i, n_states) or None
        The predicted states (None for segments of fewer than two samples).
    failed : ndarray of shape (n_segments,) of bool
        Whether a prediction failed before its last time.
    """
    integrator = model._integrator()
    predictions = [None] * len(starts)
    failed = np.zeros(len(starts), dtype=bool)
    for members in shared_grids(rel_times):
        lengths = np.array([rel_times[i].shape[0] for i in members])
        # The longest member's time stamps; the others are its prefixes.
        grid = rel_times[members[int(np.argmax(lengths))]]
        # `substeps` RK4 steps per typical interval (on a uniform grid, per
        # interval): irregular stamps do not make every interval pay for the
        # shortest one.
        max_step = (
            np.median(np.diff(grid)) / substeps
            if integrator.name == "rk4"
            else model._default_step(integrator.name)
        )
        Y, failed_early = integrate_prefixes(
            integrator, np.stack([starts[i] for i in members]), grid, lengths, max_step
        )
        for row, i in enumerate(members):
            predictions[i] = Y[row, : lengths[row]]
        failed[np.asarray(members)[failed_early]] = True
    return predictions, failed


def shared_grids(rel_times):
    """Group segments whose relative time stamps are prefixes of a common grid.

    Segments on uniform grids of one step (to round-off) share a batch
    whatever their lengths, so that ragged data integrate as fast as equal
    lengths; other segments share a batch only with identical time stamps.
    Segments with fewer than two samples have nothing to predict and are left
    out.

    Parameters
    ----------
    rel_times : list of ndarray of shape (n_times_i,)
        Time stamps of each segment relative to its start.

    Returns
    -------
    batches : list of list of int
        Indices into ``rel_times``, one list per batch, in first-seen order.
    """
    batches = {}
    for i, rel in enumerate(rel_times):
        if rel.shape[0] < 2:
            continue
        steps = np.diff(rel)
        if np.ptp(steps) <= GRID_TOLERANCE * rel[-1]:
            key = ("uniform", float(np.round(np.log(rel[-1] / steps.shape[0]), 9)))
        else:
            shape = np.round(rel / rel[-1], 9).tobytes()
            key = (rel.shape[0], shape, float(np.round(np.log(rel[-1]), 9)))
        batches.setdefault(key, []).append(i)
    return list(batches.values())


def integrate_prefixes(integrator, y0, grid, lengths, max_step):
    """Integrate a batch, each initial state over its own prefix of one time grid.

    The batch is integrated in stages between the distinct lengths, and a
    member leaves it at its own last time: a failure after a member's end
    neither costs steps nor counts against it. A fixed-step integration
    restarted at an output time takes the same steps, so each member gets
    exactly what integrating it alone over ``grid[:length]`` would give.

    Parameters
    ----------
    integrator : FixedStepIntegrator
        The method.
    y0 : ndarray of shape (n_members, n_states)
        Initial states, at ``grid[0]``.
    grid : ndarray of shape (n_times,)
        Strictly increasing output times.
    lengths : ndarray of shape (n_members,)
        Output times of each member, from 2 to ``n_times``.
    max_step : float
        Largest integration step.

    Returns
    -------
    Y : ndarray of shape (n_members, n_times, n_states)
        Each member's solution at its own output times (NaN past its end).
    failed : ndarray of shape (n_members,) of bool
        Whether a member failed (became non-finite, or an implicit step did
        not converge) before its own last time.
    """
    Y = np.full((y0.shape[0], grid.shape[0], y0.shape[1]), np.nan)
    failed = np.zeros(y0.shape[0], dtype=bool)
    active, state, begin = np.arange(y0.shape[0]), np.asarray(y0, dtype=float), 0
    for end in np.unique(lengths):
        if end - 1 > begin:
            part, failed_at = integrate(integrator, state, grid[begin:end], max_step)
            Y[active, begin:end] = np.swapaxes(part, 0, 1)
            stopped = failed_at < end - begin
            failed[active[stopped]] = True
            active, state = active[~stopped], part[-1][~stopped]
            begin = end - 1
        going = lengths[active] > end
        active, state = active[going], state[going]
        if active.size == 0:
            break
    return Y, failed


# Forward-difference step of the shooting Jacobian, in units of each state
# variable's spread: far above round-off of the rollouts, far below the noise.
SHOOTING_STEP = 1e-6


def shooting_errors(model, Xt, *, fit_intervals=None, iterations=1,
                    substeps=ROLLOUT_SUBSTEPS):
    """Errors of rollouts from least-squares initial states (shooting).

    Each held-out trajectory's initial state is fitted under the model to its
    first ``fit_intervals + 1`` observations (all of them by default) by
    Gauss-Newton steps from its first observation, with a forward-difference
    Jacobian; the rollout from the fitted state is then compared with all the
    observations. A step is kept only if it lowers the misfit over the fitted
    observations, so the fitted start is never worse than the first
    observation.

    Parameters
    ----------
    model : fitted HamiltonianRegressor or VectorFieldRegressor
        The model to integrate (with its own method, as the default score).
    Xt : derivative layout
        Held-out trajectories; only their times and raw observations are used.
    fit_intervals : int or None, default=None
        Sampling intervals the initial state is fitted to; None fits it to the
        whole trajectory.
    iterations : int, default=1
        Gauss-Newton steps.
    substeps : int, default=4
        Integration steps per sampling interval.

    Returns
    -------
    errors : ndarray of shape (n_trajectories,)
        Root-mean-square of ``(X_hat - X) / state_scale_`` over each whole
        trajectory, from its fitted initial state; ``inf`` where the rollout
        from the first observation failed.
    """
    data = unpack_derivatives(Xt)
    times, observed = list(data.times), list(data.observed)
    n_traj, n_states = len(observed), observed[0].shape[1]
    rel_times = [t - t[0] for t in times]
    window = [
        t.shape[0] if fit_intervals is None else min(fit_intervals + 1, t.shape[0])
        for t in rel_times
    ]
    x = [O[0].astype(float) for O in observed]
    steps = SHOOTING_STEP * model.state_scale_
    base, failed = predict_segments(model, x, rel_times, substeps)
    misfit = [_misfit(model, Y, O, w) for Y, O, w in zip(base, observed, window)]
    for _ in range(iterations):
        # One batch: every trajectory perturbed along every state variable,
        # over its fitting window only.
        starts, segment_times = [], []
        for k in range(n_traj):
            for i in range(n_states):
                starts.append(x[k] + np.eye(n_states)[i] * steps[i])
                segment_times.append(rel_times[k][: window[k]])
        perturbed, perturbed_failed = predict_segments(model, starts, segment_times, substeps)
        trial = []
        for k in range(n_traj):
            w = window[k]
            if failed[k] or w < 2:
                trial.append(x[k])
                continue
            rows = slice(k * n_states, (k + 1) * n_states)
            if perturbed_failed[rows].any():
                trial.append(x[k])
                continue
            Y0 = base[k][:w]
            jac = np.stack(
                [scaled_difference(model, perturbed[j][:w], Y0).ravel() / steps[i]
                 for i, j in enumerate(range(rows.start, rows.stop))],
                axis=1,
            )
            residual = scaled_difference(model, Y0, observed[k][:w]).ravel()
            delta = np.linalg.lstsq(jac, -residual, rcond=None)[0]
            trial.append(x[k] + delta)
        rolled, rolled_failed = predict_segments(model, trial, rel_times, substeps)
        for k in range(n_traj):
            if rolled_failed[k] or failed[k]:
                continue
            m = _misfit(model, rolled[k], observed[k], window[k])
            if m < misfit[k]:
                x[k], base[k], misfit[k] = trial[k], rolled[k], m
    errors = np.array([
        np.inf if failed[k] else np.sqrt(np.mean(scaled_difference(model, base[k], observed[k]) ** 2))
        if base[k] is not None else 0.0
        for k in range(n_traj)
    ])
    return errors


def _misfit(model, Y, O, w):
    if Y is None:
        return 0.0
    return float(np.sum(scaled_difference(model, Y[:w], O[:w]) ** 2))


def noise_floor(model, Xt, order=3):
    """Per-trajectory estimate of the observation noise, in the score's units.

    The ``order``-th differences of a smooth signal sampled finely are nearly
    zero, while those of white noise of variance ``s**2`` have variance
    ``C(2 order, order) s**2``; so the mean square of the scaled differences,
    divided by that binomial, estimates the mean square noise per variable.

    Returns
    -------
    floor : ndarray of shape (n_trajectories,)
        Root-mean-square noise of each trajectory's scaled observations
        (0 for trajectories too short to tell).
    """
    from math import comb

    data = unpack_derivatives(Xt)
    out = []
    for O in data.observed:
        if O.shape[0] <= order:
            out.append(0.0)
            continue
        D = np.diff(model._space.wrap_difference(O - O[0]), n=order, axis=0)
        out.append(float(np.sqrt(np.mean((D / model.state_scale_) ** 2) / comb(2 * order, order))))
    return np.array(out)
