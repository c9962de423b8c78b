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
    # The model's own method: RK4 for a derivative fit (stepped a quarter of a
    # sampling interval), AVF at the training step for a fit on steps.
    integrator = model._integrator()
    starts, targets, rel_times, owner = [], [], [], []
    for k, (t, O) in enumerate(zip(times, observed)):
        horizon = t.shape[0] - 1 if n_steps is None else min(n_steps, t.shape[0] - 1)
        for j in range(0, t.shape[0] - horizon, stride):
            starts.append(O[j])
            targets.append(O[j : j + horizon + 1])
            rel_times.append(t[j : j + horizon + 1] - t[j])
            owner.append(k)
    owner = np.array(owner)
    squared_error = np.zeros(len(observed))
    count = np.zeros(len(observed))
    failed = np.zeros(len(observed), dtype=bool)
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
        T = np.zeros_like(Y)
        for row, i in enumerate(members):
            T[row, : lengths[row]] = targets[i]
        inside = np.arange(grid.shape[0])[None, :] < lengths[:, None]
        who = owner[members]
        # A failed prediction holds its last finite, possibly huge, state; its
        # error is set to inf below, so an overflow here changes nothing.
        with np.errstate(over="ignore", invalid="ignore"):
            scaled = model._space.wrap_difference(Y - T) / model.state_scale_
            per_time = np.where(inside, np.sum(scaled**2, axis=2), 0.0)
            np.add.at(squared_error, who, np.sum(per_time, axis=1))
        np.add.at(count, who, lengths * Y.shape[2])
        failed[who[failed_early]] = True
    with np.errstate(invalid="ignore", divide="ignore"):
        errors = np.sqrt(squared_error / np.maximum(count, 1))
    errors[failed] = np.inf
    return errors


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
