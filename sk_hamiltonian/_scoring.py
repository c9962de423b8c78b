"""Errors of predictions from held-out observations: the honest score.

The regressors' default ``score`` (:func:`rollout_score`: one rollout per
trajectory from a least-squares initial state, less a noise floor) and
:func:`sk_hamiltonian.model_selection.multistep_scorer` (short predictions from
every observation, :func:`multistep_errors`) share the batched integration
here. Only the raw observations and their time stamps enter, never the
derivatives or smoothed states of the step being tuned.
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
    own time stamps only, and those on irregular stamps of one length side by
    side (:func:`integrate_own_grids`).

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
    substeps : int or None, default=4
        Integration steps per (median) sampling interval; None takes the step
        :meth:`simulate` takes by default, but at least one per interval.

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
    batches, own = shared_grids(rel_times), []
    if integrator.name in ("rk4", "avf"):
        batches, own = _own_grids(batches, rel_times)

    def largest_step(grid):
        # `substeps` RK4 steps per typical interval (on a uniform grid, per
        # interval): irregular stamps do not make every interval pay for the
        # shortest one.
        if integrator.name != "rk4":
            return model._default_step(integrator.name)
        if substeps is None:
            # The step `simulate` takes by default (a tenth of the learned
            # system's time scale), but at least one per interval: accurate
            # far below the model error, and cheapest where the sampling is
            # fine.
            return min(model._default_step("rk4"), np.median(np.diff(grid)))
        return np.median(np.diff(grid)) / substeps

    for members in batches:
        lengths = np.array([rel_times[i].shape[0] for i in members])
        # The longest member's time stamps; the others are its prefixes.
        grid = rel_times[members[int(np.argmax(lengths))]]
        Y, failed_early = integrate_prefixes(
            integrator, np.stack([starts[i] for i in members]), grid, lengths,
            largest_step(grid)
        )
        for row, i in enumerate(members):
            predictions[i] = Y[row, : lengths[row]]
        failed[np.asarray(members)[failed_early]] = True
    for members in own:
        lengths = [rel_times[i].shape[0] for i in members]
        # Shorter members wait at their last time (intervals of zero).
        grids = np.stack([np.pad(rel_times[i], (0, max(lengths) - n), mode="edge")
                          for i, n in zip(members, lengths)])
        Y, failed_early = integrate_own_grids(
            integrator, np.stack([starts[i] for i in members]), grids,
            np.array([largest_step(rel_times[i]) for i in members])
        )
        for row, (i, n) in enumerate(zip(members, lengths)):
            predictions[i] = Y[row, :n]
        failed[np.asarray(members)[failed_early]] = True
    return predictions, failed


def _own_grids(batches, rel_times):
    """The batches of :func:`shared_grids`, those on irregular stamps merged into one.

    Records time-stamped by a lab clock rarely share their stamps: alone,
    each is integrated by itself, and the steps' overhead, not the
    arithmetic, sets the time (the search on 200 jittered records of the
    pendulum: 51 CPU seconds, 7 merged).
    Merged, each member steps over its own intervals side by side with the
    others (:func:`integrate_own_grids`). Returns the batches left as they
    are and the merged ones (none, or one of at least two members).
    """
    kept, irregular = [], []
    for members in batches:
        (kept if _uniform(rel_times[members[0]]) else irregular).append(members)
    if len(irregular) == 1:
        return kept + irregular, []
    return kept, [[i for members in irregular for i in members]] if irregular else []


def integrate_own_grids(integrator, y0, grids, max_steps):
    """Integrate a batch side by side, each initial state over time stamps of its own.

    Each member takes the steps :func:`~._integrate.integrate` takes for it
    alone: each of its intervals cut into the fewest equal steps no longer
    than its own ``max_steps``, and none over an interval of zero (a member
    that ended waits at its last time). The members that need a step at once
    take it together. A member whose state becomes non-finite is frozen at
    its last finite state from there on, as :func:`~._integrate.integrate`
    does.

    Parameters
    ----------
    integrator : FixedStepIntegrator
        A method whose step takes one step size per member (RK4, AVF).
    y0 : ndarray of shape (n_members, n_states)
        Initial states, at each member's first time stamp.
    grids : ndarray of shape (n_members, n_times)
        Each member's increasing time stamps (strictly, until it repeats its
        last one).
    max_steps : ndarray of shape (n_members,)
        Each member's largest step.

    Returns
    -------
    Y : ndarray of shape (n_members, n_times, n_states)
        Each member's solution at its time stamps.
    failed : ndarray of shape (n_members,) of bool
        Whether a member became non-finite before its last time.
    """
    wrap = integrator.dynamics.wrap or (lambda y: y)
    y = wrap(np.array(y0, dtype=float))
    n_members, n_times = grids.shape
    Y = np.empty((n_members, n_times, y.shape[1]))
    Y[:, 0] = y
    failed = np.zeros(n_members, dtype=bool)
    active = np.arange(n_members)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for k in range(n_times - 1):
            if active.size:
                interval = grids[active, k + 1] - grids[active, k]
                n_sub = np.where(interval > 0, np.maximum(
                    1, np.ceil(interval / max_steps[active] - 1e-9)), 0).astype(int)
                h = (interval / n_sub)[:, None]
                y_active = y[active]
                for j in range(int(n_sub.max())):
                    going = n_sub > j
                    y_active[going] = integrator.step(y_active[going], h[going])
                finite = np.isfinite(y_active).all(axis=1)
                failed[active[~finite]] = True
                active, y_active = active[finite], y_active[finite]
                y[active] = wrap(y_active)
            Y[:, k + 1] = y
    return Y, failed


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
        if _uniform(rel):
            key = ("uniform", float(np.round(np.log(rel[-1] / (rel.shape[0] - 1)), 9)))
        else:
            shape = np.round(rel / rel[-1], 9).tobytes()
            key = (rel.shape[0], shape, float(np.round(np.log(rel[-1]), 9)))
        batches.setdefault(key, []).append(i)
    return list(batches.values())


def _uniform(rel):
    """Whether relative time stamps (two or more) step uniformly, to :data:`GRID_TOLERANCE`."""
    return np.ptp(np.diff(rel)) <= GRID_TOLERANCE * rel[-1]


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


def shooting_errors(model, Xt, *, fit_intervals=None, substeps=None, return_first=False):
    """Errors of rollouts from least-squares initial states (shooting).

    Each held-out trajectory's initial state is fitted under the model to its
    first ``fit_intervals + 1`` observations (all of them by default) by one
    Gauss-Newton step from its first observation, with a forward-difference
    Jacobian; the rollout from the fitted state is then compared with all the
    observations. The step is kept only if it lowers the misfit over the
    fitted observations, so the fitted start is never worse than the first
    observation. The rollouts from the first observation and the perturbed
    ones share one batch, so the whole costs about two rollouts.

    Parameters
    ----------
    model : fitted HamiltonianRegressor or VectorFieldRegressor
        The model to integrate (with its own method, as the default score).
    Xt : derivative layout
        Held-out trajectories; only their times and raw observations are used.
    fit_intervals : int or None, default=None
        Sampling intervals the initial state is fitted to; None fits it to the
        whole trajectory.
    substeps : int or None, default=None
        Integration steps per sampling interval; None: the model's default
        step, at least one per interval (see :func:`predict_segments`).
    return_first : bool, default=False
        Also return the rollouts from the first observations (for studies).

    Returns
    -------
    errors : ndarray of shape (n_trajectories,)
        Root-mean-square of ``(X_hat - X) / state_scale_`` over each whole
        trajectory from its fitted initial state, ``inf`` where the rollout
        from the first observation failed.
    first : list of ndarray, and ndarray of bool
        The rollouts from the first observations and whether they failed;
        only with ``return_first=True``.
    """
    data = unpack_derivatives(Xt)
    times, observed = list(data.times), list(data.observed)
    n_traj, n_states = len(observed), observed[0].shape[1]
    rel_times = [t - t[0] for t in times]
    window = [
        t.shape[0] if fit_intervals is None else min(fit_intervals + 1, t.shape[0])
        for t in rel_times
    ]
    steps = SHOOTING_STEP * model.state_scale_
    # One batch: each trajectory from its first observation over its whole
    # length, then perturbed along every state variable over its window.
    starts = [O[0].astype(float) for O in observed]
    segment_times = list(rel_times)
    for k in range(n_traj):
        for i in range(n_states):
            starts.append(starts[k] + np.eye(n_states)[i] * steps[i])
            segment_times.append(rel_times[k][: window[k]])
    rolled, failed_rollout = predict_segments(model, starts, segment_times, substeps)
    base, failed = rolled[:n_traj], failed_rollout[:n_traj]
    first = list(base)
    trial, trying = [], []
    for k in range(n_traj):
        w = window[k]
        rows = n_traj + k * n_states + np.arange(n_states)
        if failed[k] or w < 2 or failed_rollout[rows].any():
            continue
        Y0 = base[k][:w]
        jac = np.stack(
            [scaled_difference(model, rolled[j], Y0).ravel() / steps[i]
             for i, j in enumerate(rows)],
            axis=1,
        )
        residual = scaled_difference(model, Y0, observed[k][:w]).ravel()
        delta = np.linalg.lstsq(jac, -residual, rcond=None)[0]
        trial.append(starts[k] + delta)
        trying.append(k)
    if trying:
        moved, moved_failed = predict_segments(
            model, trial, [rel_times[k] for k in trying], substeps
        )
        for Y, bad, k in zip(moved, moved_failed, trying):
            if not bad and _misfit(model, Y, observed[k], window[k]) < _misfit(
                model, base[k], observed[k], window[k]
            ):
                base[k] = Y
    errors = np.zeros(n_traj)
    for k in range(n_traj):
        if failed[k]:
            errors[k] = np.inf
        elif base[k] is not None:
            errors[k] = np.sqrt(np.mean(scaled_difference(model, base[k], observed[k]) ** 2))
    if return_first:
        return errors, (first, failed)
    return errors


def _misfit(model, Y, O, w):
    if Y is None:
        return 0.0
    return float(np.sum(scaled_difference(model, Y[:w], O[:w]) ** 2))


# Largest polynomial degree in time of the noise-floor fits; each
# trajectory's degree is chosen up to it by the Bayesian information criterion.
FLOOR_MAX_DEGREE = 12


def noise_floor(model, Xt):
    """What a perfect model's shooting error would be, per held-out trajectory.

    Each trajectory's scaled observations (periodic variables unwrapped) are
    fitted by polynomials in time, of the degree (up to 12, and below half
    the samples) that minimizes the Bayesian information criterion. The
    residual variance, corrected for the fitted coefficients, estimates the
    observation noise ``s**2``; an exact model fitting the ``n_states``
    initial values would leave ``s**2 (N - n_states) / N`` over the
    trajectory's ``N`` values. The estimate depends on the raw observations,
    their times and ``state_scale_`` only, never on the candidate's dynamics.
    (The criterion was chosen in ``benchmarks/cv_scoring_study.py``: it kept
    the fold scores' spread smallest among the adaptive choices tried.)

    Parameters
    ----------
    model : fitted regressor
        For ``state_scale_`` and the periodic variables only.
    Xt : derivative layout
        Held-out trajectories.

    Returns
    -------
    floor : ndarray of shape (n_trajectories,)
        Root-mean-square noise floor of each trajectory, in the units of
        :func:`shooting_errors` (0 where a trajectory is too short to tell).
    """
    data = unpack_derivatives(Xt)
    floor = np.zeros(len(data.observed))
    bases = {}
    for k, (t, O) in enumerate(zip(data.times, data.observed)):
        n_times, n_states = O.shape
        top = min(FLOOR_MAX_DEGREE, n_times // 2 - 1)
        if top < 1:
            continue
        s = 2.0 * (t - t[0]) / (t[-1] - t[0]) - 1.0
        key = (n_times, np.round(s, 9).tobytes())
        if key not in bases:
            # Nested orthonormal bases: the first d + 1 columns of Q span the
            # polynomials of degree d.
            bases[key] = np.linalg.qr(np.polynomial.legendre.legvander(s, top))[0]
        Q = bases[key][:, : top + 1]
        steps = model._space.wrap_difference(np.diff(O, axis=0)) / model.state_scale_
        Z = np.concatenate([np.zeros((1, n_states)), np.cumsum(steps, axis=0)])
        explained = np.cumsum(np.sum((Q.T @ Z) ** 2, axis=1))
        rss = np.maximum(np.sum(Z**2) - explained, 0.0)
        n_values, n_coef = Z.size, n_states * np.arange(1, top + 2)
        if not rss[-1] > 0:  # noise-free to round-off
            continue
        with np.errstate(divide="ignore"):
            bic = n_values * np.log(rss / n_values) + n_coef * np.log(n_values)
        d = int(np.argmin(bic))
        floor[k] = np.sqrt(rss[d] / (n_values - n_coef[d]) * (n_values - n_states) / n_values)
    return floor


def rollout_score(model, Xt, sample_weight=None):
    """The regressors' default score on the derivative layout.

    ``1 - mean_k (min(1, e_k) - f_k)``: ``e_k`` the error of trajectory ``k``
    from its least-squares initial state (:func:`shooting_errors`), ``f_k``
    its noise floor (:func:`noise_floor`), the mean weighted by
    ``sample_weight``. The floor does not depend on the candidate's dynamics,
    so it moves every candidate's score on a fold alike: it leaves the
    ranking of candidates as it is and takes out of the fold-to-fold spread
    what comes from the noise of the held-out trajectories. (Root-mean-square
    forms over the trajectories chose better on the noisy Morse scenes of
    ``benchmarks/cv_scoring_study.py`` but not on its other scenes, and on
    the paper's noisy pendulum they put the 2-term sparse model above the
    dense one by more than a standard error of the fold scores on at most 6
    of 10 data seeds, this mean on 9: see the cross-validation page of the
    documentation.)
    """
    errors = shooting_errors(model, Xt)
    floor = noise_floor(model, Xt)
    return float(1.0 - np.average(np.minimum(errors, 1.0) - floor, weights=sample_weight))
