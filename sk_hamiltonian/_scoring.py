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


def multistep_errors(model, Xt, n_steps=None, *, stride=1, substeps=ROLLOUT_SUBSTEPS):
    """Relative errors of ``n_steps``-ahead predictions from observed states.

    From every ``stride``-th observation of each held-out trajectory (that has
    ``n_steps`` observations after it), the model is integrated ``n_steps``
    sampling intervals ahead and compared with the observations it passes.
    Each prediction is compared over its whole segment, its starting
    observation included (where it is exact), as the default score compares
    its single rollout: with ``n_steps`` at least the number of intervals, the
    two coincide.

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
        Integration steps per sampling interval.

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
    # Segments whose relative time stamps agree (to round-off) share one batch.
    groups = {}
    for i, rel in enumerate(rel_times):
        scale = max(rel[-1], np.finfo(float).tiny)
        groups.setdefault((rel.shape[0], np.round(rel / scale, 9).tobytes()), []).append(i)
    squared_error = np.zeros(len(observed))
    count = np.zeros(len(observed))
    failed = np.zeros(len(observed), dtype=bool)
    for members in groups.values():
        rel = rel_times[members[0]]
        if rel.shape[0] < 2:
            continue
        max_step = (
            np.min(np.diff(rel)) / substeps
            if integrator.name == "rk4"
            else model._default_step(integrator.name)
        )
        Y, failed_at = integrate(integrator, np.stack([starts[i] for i in members]), rel, max_step)
        Y = np.swapaxes(Y, 0, 1)
        T = np.stack([targets[i] for i in members])
        who = owner[members]
        # A failed prediction holds its last finite, possibly huge, state; its
        # error is set to inf below, so an overflow here changes nothing.
        with np.errstate(over="ignore", invalid="ignore"):
            scaled = model._space.wrap_difference(Y - T) / model.state_scale_
            np.add.at(squared_error, who, np.sum(scaled**2, axis=(1, 2)))
        np.add.at(count, who, T.shape[1] * T.shape[2])
        failed[who[failed_at < rel.shape[0]]] = True
    with np.errstate(invalid="ignore", divide="ignore"):
        errors = np.sqrt(squared_error / np.maximum(count, 1))
    errors[failed] = np.inf
    return errors
