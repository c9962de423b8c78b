"""Coefficients of a Hamiltonian fitted to whole observed trajectories (output error).

The least-squares fits of the package match ``J dx/dt`` to ``grad H`` at
states and derivatives estimated from the data, so noise in the states biases
them, and the derivatives' errors reach the coefficients unweighted. Once the
terms are known, their coefficients ``theta`` can be fitted instead to what
was observed: each trajectory is simulated from an initial state ``x0_k`` of
its own, and

    sum_k sum_j || W_kj * (y_kj - x(t_kj; x0_k, theta)) ||^2

is minimised over ``theta`` and every ``x0_k`` (the *output-error* or
trajectory-matching estimate; with the right weights ``W``, the maximum
likelihood estimate of the coefficients for independent noise).

The flow is integrated by the classical Runge-Kutta method together with its
forward sensitivities (``d x / d x0`` and ``d x / d theta``), and the problem
is solved by Levenberg-Marquardt. Its normal matrix is block arrowhead (one
small block per trajectory's initial state, coupled only through ``theta``),
so the initial states are eliminated by their Schur complement and each
iteration solves one system of the size of ``theta``.

The weights come from the residuals: each variable's noise variance is
modelled as ``a_i + b_i x_i^2`` (additive noise, relative noise, or both),
fitted to the squared residuals of the unweighted fit, and the fit is
repeated with ``W = 1 / sqrt(a_i + b_i x_i^2)`` (feasible generalised least
squares, :data:`N_REWEIGHTS` times).
"""

import numpy as np

from ._structure import apply_structure

# Levenberg-Marquardt: iterations per (re)weighted fit, the relative decrease
# of the cost below which it stops, and Marquardt's lambda beyond which no step
# downhill is left to find.
MAX_ITER = 20
RTOL = 1e-9
MAX_LAMBDA = 1e8
# Fits with weights from the previous fit's residuals, after the unweighted one.
N_REWEIGHTS = 2
# A variance model never gives a sample more weight than this many times the
# average sample's (a variable near zero under relative noise would otherwise
# weigh without bound, and with it the model's own error at that sample).
MAX_RELATIVE_WEIGHT = 10.0


class TrajectoryFitError(RuntimeError):
    """The model's simulation of the training trajectories failed (non-finite states)."""


class FlowModel:
    """``x' = (J^{-1} - Gamma) G(x) theta``: a Hamiltonian linear in its coefficients.

    The parameters are ``theta``, followed by the friction ``gamma`` of each
    momentum (``Gamma`` subtracts ``gamma_i dH/dp_i`` from ``dp_i/dt``) when
    ``n_damped`` is the number of momenta.

    Parameters
    ----------
    gradients : callable
        ``gradients(X)``: the gradients of the terms at the rows of ``X``,
        ndarray of shape (n_samples, n_states, n_terms).
    hessian : callable
        ``hessian(X, theta)``: the Hessian of ``H`` with coefficients
        ``theta``, ndarray of shape (n_samples, n_states, n_states).
    wrap_difference : callable
        Differences of states, periodic components wrapped into their period.
    n_damped : int, default=0
        Number of friction parameters at the end of the parameters: 0 (no
        friction) or the number of momenta.
    """

    def __init__(self, gradients, hessian, wrap_difference, n_damped=0):
        self.gradients = gradients
        self.hessian = hessian
        self.wrap_difference = wrap_difference
        self.n_damped = n_damped

    def split(self, params):
        """``(theta, gamma)``; ``gamma`` None without friction."""
        if not self.n_damped:
            return params, None
        return params[: -self.n_damped], params[-self.n_damped :]

    def project(self, params):
        """The nearest admissible parameters: friction is never negative."""
        if not self.n_damped:
            return params
        params = params.copy()
        params[-self.n_damped :] = np.maximum(params[-self.n_damped :], 0.0)
        return params

    def rates(self, x, params, Sx=None, Sp=None):
        """The field at ``x``, and the sensitivities' rates when ``Sx`` and ``Sp`` are given."""
        theta, gamma = self.split(params)
        G = self.gradients(x)
        g = G @ theta
        field = apply_structure(g, gamma)
        if Sx is None:
            return field, None, None
        jacobian = _columns(self.hessian(x, theta), gamma)
        forcing = _columns(G, gamma)
        if gamma is not None:
            # d (dp_i/dt) / d gamma_i = -dH/dp_i.
            n, d = len(x), x.shape[1] // 2
            friction = np.zeros((n, 2 * d, d))
            friction[:, np.arange(d), np.arange(d)] = -g[:, :d]
            forcing = np.concatenate([forcing, friction], axis=2)
        return field, jacobian @ Sx, jacobian @ Sp + forcing


def _columns(M, gamma):
    """``(J^{-1} - Gamma) M`` for matrices ``M`` of shape (n, n_states, k), column by column."""
    return apply_structure(M.swapaxes(1, 2), gamma).swapaxes(1, 2)


def flow(model, theta, x0, steps, sensitivities=True):
    """States at the sample times from ``x0``, and their sensitivities, by RK4.

    Parameters
    ----------
    model : FlowModel
    theta : ndarray of shape (n_params,)
        The model's parameters (coefficients, then any friction: :class:`FlowModel`).
    x0 : ndarray of shape (n_trajectories, n_states)
        States at the first sample time.
    steps : list of ndarray
        ``steps[j]``: the RK4 steps from sample ``j`` to sample ``j + 1``,
        of shape (n_substeps,) (shared by all trajectories) or (n_substeps,
        n_trajectories) (one column per trajectory, for trajectories sampled
        at times of their own).
    sensitivities : bool, default=True
        Also integrate ``d x / d x0`` and ``d x / d theta``.

    Returns
    -------
    X : ndarray of shape (n_trajectories, n_times, n_states)
    SX : ndarray of shape (n_trajectories, n_times, n_states, n_states) or None
    ST : ndarray of shape (n_trajectories, n_times, n_states, n_params) or None
    """
    n, d = x0.shape
    k = len(theta)
    n_times = len(steps) + 1
    X = np.empty((n, n_times, d))
    X[:, 0] = x0
    state = [x0.copy(), None, None]
    SX = ST = None
    if sensitivities:
        SX, ST = np.empty((n, n_times, d, d)), np.empty((n, n_times, d, k))
        state[1] = np.broadcast_to(np.eye(d), (n, d, d)).copy()
        state[2] = np.zeros((n, d, k))
        SX[:, 0], ST[:, 0] = state[1], state[2]
    for j, interval in enumerate(steps):
        for h in interval:
            state = _rk4_step(model, theta, state, h)
        X[:, j + 1] = state[0]
        if sensitivities:
            SX[:, j + 1], ST[:, j + 1] = state[1], state[2]
    return X, SX, ST


def _rk4_step(model, theta, state, h):
    def scaled(c, r):  # a step per trajectory scales the rows of r
        return c * r if np.ndim(c) == 0 else c.reshape((-1,) + (1,) * (r.ndim - 1)) * r

    def rates(shift, c):
        x, Sx, St = (None if s is None else s + scaled(c, r) for s, r in zip(state, shift))
        return model.rates(x, theta, Sx, St)

    k1 = model.rates(state[0], theta, state[1], state[2])
    k2 = rates(k1, h / 2)
    k3 = rates(k2, h / 2)
    k4 = rates(k3, h)
    return [None if s is None else s + scaled(h / 6, a + 2 * b + 2 * c + e)
            for s, a, b, c, e in zip(state, k1, k2, k3, k4)]


class _Group:
    """Trajectories sharing their sample times: observations, steps, weights."""

    def __init__(self, Y, steps):
        self.Y = Y
        self.steps = steps
        self.W = np.ones_like(Y)

    def residuals(self, model, X):
        return model.wrap_difference(self.Y - X) * self.W


def fit_trajectories(model, theta, groups, *, max_iter=MAX_ITER, n_reweights=N_REWEIGHTS):
    """Output-error coefficients of ``model`` on observed trajectories.

    Parameters
    ----------
    model : FlowModel
    theta : ndarray of shape (n_params,)
        Starting parameters (the least-squares fit's coefficients, then any
        friction: :class:`FlowModel`).
    groups : list of (ndarray, list of ndarray)
        ``(Y, steps)``: trajectories ``Y`` of shape (n_trajectories, n_times,
        n_states) observed at common times, and the RK4 steps between them
        (as for :func:`flow`).
    max_iter : int, default=MAX_ITER
        Levenberg-Marquardt iterations per fit.
    n_reweights : int, default=N_REWEIGHTS
        Fits with weights from the noise model after the unweighted one.

    Returns
    -------
    result : dict
        ``theta``; ``x0``, the fitted initial states, one array per group;
        ``n_iter``, the Levenberg-Marquardt iterations in all; ``noise``, the
        variance model ``(a_i, b_i)`` of each variable, ndarray of shape
        (n_states, 2) (None without reweighting); ``rms``, the unweighted
        root-mean-square residual of each variable at the end.

    Raises
    ------
    TrajectoryFitError
        If the starting model's simulation of the trajectories is not finite.
    """
    groups = [_Group(np.asarray(Y, dtype=float), steps) for Y, steps in groups]
    x0s = [g.Y[:, 0].copy() for g in groups]
    theta = np.asarray(theta, dtype=float)
    runs = _simulate(model, theta, x0s, groups)
    if runs is None:
        raise TrajectoryFitError(
            "the model's simulation of the training trajectories is not finite")
    n_iter, noise = 0, None
    for round_ in range(n_reweights + 1):
        if round_:
            # The states do not depend on the weights: the last fit's serve.
            noise = _reweight(model, groups, [run[0] for run in runs])
        theta, x0s, runs, used = _levenberg_marquardt(model, theta, x0s, runs, groups, max_iter)
        n_iter += used
    residuals = [model.wrap_difference(g.Y - run[0]) for g, run in zip(groups, runs)]
    d = groups[0].Y.shape[-1]
    rms = np.sqrt(np.mean(np.concatenate([r.reshape(-1, d) for r in residuals]) ** 2, axis=0))
    return dict(theta=theta, x0=x0s, n_iter=n_iter, noise=noise, rms=rms)


def _simulate(model, theta, x0s, groups):
    """Every group's states and sensitivities; None if any state is not finite."""
    runs = []
    for g, x0 in zip(groups, x0s):
        with np.errstate(all="ignore"):
            run = flow(model, theta, x0, g.steps)
        if not all(np.all(np.isfinite(a)) for a in run):
            return None
        runs.append(run)
    return runs


def _cost(model, groups, runs):
    return sum(float(np.sum(g.residuals(model, run[0]) ** 2)) for g, run in zip(groups, runs))


def _levenberg_marquardt(model, theta, x0s, runs, groups, max_iter):
    """Minimise the weighted cost over ``theta`` and the initial states.

    ``runs`` are the simulations (:func:`_simulate`) of the starting point.
    Stops after ``max_iter`` iterations, when an accepted step lowers the cost
    by less than :data:`RTOL` of it, or when Marquardt's lambda exceeds
    :data:`MAX_LAMBDA` (no step downhill left). Returns ``(theta, x0s, runs,
    n_iter)``.
    """
    cost = _cost(model, groups, runs)
    lam = 1e-6
    for n_iter in range(1, max_iter + 1):
        step_theta, steps_x0 = _gauss_newton_step(model, groups, runs, lam)
        new_theta = model.project(theta + step_theta)
        new_x0s = [x0 + dx for x0, dx in zip(x0s, steps_x0)]
        new_runs = _simulate(model, new_theta, new_x0s, groups)
        new_cost = np.inf if new_runs is None else _cost(model, groups, new_runs)
        if new_cost < cost:
            done = cost - new_cost < RTOL * cost
            theta, x0s, runs, cost = new_theta, new_x0s, new_runs, new_cost
            lam = max(lam / 10, 1e-12)
            if done:
                break
        else:
            lam *= 100
            if lam > MAX_LAMBDA:
                break
    return theta, x0s, runs, n_iter


def _gauss_newton_step(model, groups, runs, lam):
    """The damped Gauss-Newton step, initial states eliminated by their Schur complement.

    The normal matrix is ``[[diag(A_k^T A_k), A_k^T B_k], [B_k^T A_k, sum_k
    B_k^T B_k]]`` with ``A_k = d r_k / d x0_k`` and ``B_k = d r_k / d theta``;
    its diagonal is scaled by ``1 + lam`` (Marquardt).
    """
    k = runs[0][2].shape[-1]
    S, rhs, parts = np.zeros((k, k)), np.zeros(k), []
    for g, (X, SX, ST) in zip(groups, runs):
        n, n_times, d = g.Y.shape
        r = g.residuals(model, X).reshape(n, n_times * d)
        A = (SX * g.W[..., None]).reshape(n, n_times * d, d)
        B = (ST * g.W[..., None]).reshape(n, n_times * d, k)
        AA = np.einsum("nri,nrj->nij", A, A)
        AA += lam * AA * np.eye(d)
        AB = np.einsum("nri,nrj->nij", A, B)
        Ar = np.einsum("nri,nr->ni", A, r)
        AA_inv = np.linalg.inv(AA)
        AA_inv_AB = AA_inv @ AB
        S += np.einsum("nri,nrj->ij", B, B) - np.einsum("nji,njk->ik", AB, AA_inv_AB)
        rhs += np.einsum("nri,nr->i", B, r) - np.einsum("nji,nj->i", AA_inv_AB, Ar)
        parts.append((AA_inv, AA_inv_AB, Ar))
    S[np.diag_indices(k)] *= 1 + lam
    step_theta = np.linalg.lstsq(S, rhs, rcond=None)[0]
    steps_x0 = [np.einsum("nij,nj->ni", AA_inv, Ar) - AA_inv_AB @ step_theta
                for AA_inv, AA_inv_AB, Ar in parts]
    return step_theta, steps_x0


def _reweight(model, groups, states):
    """Weights from each variable's noise model ``a_i + b_i x_i^2``; returns the model.

    ``states`` are the fitted model's simulations of each group. The
    variances are fitted to the squared unweighted residuals by least
    squares (negative parts set to zero) and floored at the average
    variance over :data:`MAX_RELATIVE_WEIGHT` squared.
    """
    d = groups[0].Y.shape[-1]
    x = np.concatenate([X.reshape(-1, d) for X in states])
    r = np.concatenate([model.wrap_difference(g.Y - X).reshape(-1, d)
                        for g, X in zip(groups, states)])
    noise = np.empty((d, 2))
    for i in range(d):
        design = np.column_stack([np.ones(len(x)), x[:, i] ** 2])
        noise[i] = np.maximum(np.linalg.lstsq(design, r[:, i] ** 2, rcond=None)[0], 0.0)
    a, b = noise[:, 0], noise[:, 1]
    floor = (a + b * np.mean(x ** 2, axis=0)) / MAX_RELATIVE_WEIGHT ** 2
    if not np.all(floor > 0):
        return noise  # residuals all zero: exact data, nothing to weigh
    for g, X in zip(groups, states):
        g.W = 1.0 / np.sqrt(np.maximum(a + b * X ** 2, floor))
    return noise
