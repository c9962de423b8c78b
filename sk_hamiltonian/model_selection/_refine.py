"""The chosen model's coefficients refitted to the raw trajectories (``refine="trajectories"``)."""

import math

import numpy as np

from .._space.space import ModelSpace
from .._trajectory_fit import FlowModel, TrajectoryFitError, fit_trajectories

# Kept terms beyond which the refinement is skipped: its sensitivities cost
# (n_samples x n_states x n_terms) per step, and a model of that many terms is
# not the sparse law the refinement is for.
MAX_REFINED_TERMS = 40
# Relative size below which a readable coefficient is round-off of a zero.
ROUND_OFF = 1e-10


def refine_on_trajectories(regressor, trajectories, dt):
    """Refit the kept terms of a fitted ``HamiltonianRegressor`` to raw trajectories.

    The kept terms are those of the readable form (monomials, ``cos``,
    ``sin``), the constant aside; their coefficients, the friction of a model
    fitted with ``damping=True`` (kept non-negative) and every trajectory's
    initial state are fitted by :func:`~sk_hamiltonian._trajectory_fit.fit_trajectories`,
    starting from the regressor's, and ``coef_``, ``support_`` and
    ``damping_`` are updated in place.

    Parameters
    ----------
    regressor : HamiltonianRegressor
        Fitted.
    trajectories : list of ndarray of shape (n_times_k, n_columns)
        Raw trajectories, with their time stamps in the first column when
        ``dt`` is None.
    dt : float or None
        Sampling step.

    Returns
    -------
    info : dict
        ``status`` (``"refined"``, or why the coefficients were kept as
        fitted), and when refined: ``n_terms``, ``n_iter``, ``noise`` (the
        noise variance model ``(a_i, b_i)``, ``a_i + b_i x_i^2``, per
        variable), ``rms`` (the root-mean-square residual per variable) and
        ``change`` (the largest relative change of a readable coefficient).
    """
    space = regressor._space
    readable = space.readable_basis()
    values = readable.from_fitting @ regressor.coef_
    nonconstant = np.any(space.powers != 0, axis=1)
    # The fit keeps terms in the readable basis; mapped back from the fitting
    # basis, the others come out at round-off, not at zero.
    kept = np.abs(values) > ROUND_OFF * np.max(np.abs(values), initial=0.0)
    terms = np.flatnonzero(kept & nonconstant)
    if len(terms) == 0:
        return dict(status="kept: no term to refine")
    if len(terms) > MAX_REFINED_TERMS:
        return dict(status=f"kept: {len(terms)} terms, more than {MAX_REFINED_TERMS}")
    to_fitting = readable.to_fitting[:, terms].toarray()
    rows = np.any(to_fitting != 0, axis=1)
    sub = ModelSpace(space.domain, space.powers[rows], space.periodic, space.mixed)
    columns = to_fitting[rows]
    damped = bool(regressor.damping)
    model = FlowModel(
        gradients=lambda X: sub.gradients(X) @ columns,
        hessian=lambda X, theta: sub.hessian_dot(X, columns @ theta),
        wrap_difference=sub.wrap_difference,
        n_damped=len(regressor.damping_) if damped else 0,
    )
    groups = _groups(trajectories, dt, regressor._default_step("rk4"))
    theta0 = values[terms]
    start = np.concatenate([theta0, regressor.damping_]) if damped else theta0
    try:
        with np.errstate(all="ignore"):
            result = fit_trajectories(model, start, groups)
    except TrajectoryFitError as error:
        return dict(status=f"kept: {error}")
    if not np.all(np.isfinite(result["theta"])):
        return dict(status="kept: the refined coefficients are not finite")
    theta, friction = model.split(result["theta"])
    regressor.coef_ = regressor.coef_ + to_fitting @ (theta - theta0)
    if damped:
        regressor.damping_ = friction
    regressor.support_ = regressor.support_ | rows
    regressor._rebuild_fitted()
    change = float(np.max(np.abs(theta - theta0) / np.abs(theta0)))
    return dict(status="refined", n_terms=len(terms), n_iter=result["n_iter"],
                noise=result["noise"], rms=result["rms"], change=change)


def _groups(trajectories, dt, max_step):
    """Trajectories grouped by length, with the RK4 steps between their samples.

    Each interval between samples is cut into equal steps of at most
    ``max_step``; trajectories of one length integrate side by side, each
    with steps of its own when their sample times differ.
    """
    by_length = {}
    for T in trajectories:
        by_length.setdefault(len(T), []).append(T)
    groups = []
    for members in by_length.values():
        if dt is None:
            times = np.stack([T[:, 0] for T in members])
            states = np.stack([T[:, 1:] for T in members])
        else:
            times = dt * np.arange(len(members[0]))[np.newaxis]
            states = np.stack(members)
        intervals = np.diff(times, axis=1)  # (n_trajectories or 1, n_times - 1)
        steps = []
        for h in intervals.T:
            n = max(1, math.ceil(np.max(h) / max_step - 1e-9))
            steps.append(np.repeat((h / n)[np.newaxis], n, axis=0) if len(h) > 1
                         else np.full(n, h[0] / n))
        groups.append((states, steps))
    return groups
