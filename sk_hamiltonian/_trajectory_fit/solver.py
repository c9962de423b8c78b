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
squares, :data:`N_REWEIGHTS` times). A noise model from a fit that did not
converge, or whose residuals are far above the noise the data show by
themselves (:mod:`.noise`), never weighs the next fit.

Long records are cut into segments before they reach the solver
(:mod:`.segments`): over many periods, a small error of frequency becomes a
large error of phase, and the cost of the whole record has many minima.
"""

import numpy as np

from .._structure import apply_structure
from .covariance import information, unit_diagonal_scale
from .noise import mean_variance, noise_weights, residual_noise_model
from .outliers import isolated_outliers

# Levenberg-Marquardt: iterations per (re)weighted fit, the relative decrease
# of the cost below which it stops, and Marquardt's lambda beyond which no step
# downhill is left to find.
MAX_ITER = 30
RTOL = 1e-9
MAX_LAMBDA = 1e8
# The initial states of held-out trajectories under fixed coefficients: a
# misfit to compare (to half a percent), not an estimate, needs fewer digits.
HELD_OUT_RTOL = 1e-4
HELD_OUT_MAX_ITER = 10
# Fits with weights from the previous fit's residuals, after the first one.
N_REWEIGHTS = 2
# Fits after the last that left out outliers, at most (each leaves out the next worst).
MAX_OUTLIER_FITS = 2
# A noise model fitted to the residuals is used only where its variance stays
# below this many times the variance the data themselves show (the noise
# model ``bound`` of :func:`fit_trajectories`, estimated without any model):
# residuals far above it are the model's error, not noise, and weights made
# from them would hide that error where it is largest.
MAX_VARIANCE_RATIO = 4.0


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
    gradients_and_hessian : callable, default=None
        ``gradients_and_hessian(X, theta)``: both at once, where that is
        cheaper than apart (the sensitivities need both at every stage).
    """

    def __init__(self, gradients, hessian, wrap_difference, n_damped=0,
                 gradients_and_hessian=None):
        self.gradients = gradients
        self.hessian = hessian
        self.wrap_difference = wrap_difference
        self.n_damped = n_damped
        self.gradients_and_hessian = gradients_and_hessian

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
        if Sx is not None and self.gradients_and_hessian is not None:
            G, hessian = self.gradients_and_hessian(x, theta)
        else:
            G = self.gradients(x)
            hessian = None if Sx is None else self.hessian(x, theta)
        g = G @ theta
        field = apply_structure(g, gamma)
        if Sx is None:
            return field, None, None
        jacobian = _columns(hessian, gamma)
        if Sp is None:
            return field, jacobian @ Sx, None
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
    sensitivities : {True, False, "x0"}, default=True
        Also integrate ``d x / d x0`` and ``d x / d theta`` (True), or ``d x
        / d x0`` alone (``"x0"``).

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
        SX = np.empty((n, n_times, d, d))
        state[1] = np.broadcast_to(np.eye(d), (n, d, d)).copy()
        SX[:, 0] = state[1]
    if sensitivities is True:
        ST = np.empty((n, n_times, d, k))
        state[2] = np.zeros((n, d, k))
        ST[:, 0] = state[2]
    for j, interval in enumerate(steps):
        for h in interval:
            state = _rk4_step(model, theta, state, h)
        X[:, j + 1] = state[0]
        if SX is not None:
            SX[:, j + 1] = state[1]
        if ST is not None:
            ST[:, j + 1] = state[2]
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
    """Trajectories integrated side by side: observations, steps, which samples count, weights."""

    def __init__(self, Y, steps, mask=None):
        self.Y = Y
        self.steps = steps
        self.mask = np.ones(Y.shape[:2], dtype=bool) if mask is None else np.asarray(mask, bool)
        self.W = np.repeat(self.mask[..., None].astype(float), Y.shape[2], axis=2)

    def weigh(self, weights):
        """Set the weights of the samples that count (the others stay at zero)."""
        self.W = weights * self.mask[..., None]

    def leave_out(self, samples):
        """Let ``samples`` (boolean, shaped as the mask) count no more."""
        self.mask = self.mask & ~samples
        self.W = self.W * self.mask[..., None]

    def valid(self, A):
        """The rows of ``A`` (shaped as ``Y``) at the samples that count, (n_samples, n_states)."""
        return A[self.mask]

    def residuals(self, model, X, rows=slice(None)):
        """Weighted residuals of simulated ``X`` (of the trajectories ``rows``)."""
        return model.wrap_difference(self.Y[rows] - X) * self.W[rows]

    def misfit(self, model, X, rows=slice(None)):
        """Each trajectory's weighted sum of squared residuals (of the trajectories ``rows``)."""
        return np.sum(self.residuals(model, X, rows) ** 2, axis=(1, 2))


def _groups(groups):
    """:class:`_Group` of each ``(Y, steps)`` or ``(Y, steps, mask)``."""
    return [_Group(np.asarray(group[0], dtype=float), *group[1:]) for group in groups]


def _observed_scale(groups):
    return np.sqrt(np.mean(np.concatenate([g.valid(g.Y) for g in groups]) ** 2, axis=0))


def fit_trajectories(model, theta, groups, *, bound=None, max_iter=MAX_ITER,
                     n_reweights=N_REWEIGHTS, first_noise=None, weight_states=None,
                     leave_out_outliers=False):
    """Output-error coefficients of ``model`` on observed trajectories.

    The first fit is weighted by ``first_noise`` (unweighted without it);
    each of the ``n_reweights`` fits after it is weighted by a noise model
    fitted to the residuals of the one before
    (:func:`~.noise.residual_noise_model`). That noise model is trusted only
    when the fit it comes from converged and, given ``bound``, its variance
    stays within :data:`MAX_VARIANCE_RATIO` times ``bound``'s in every
    variable; otherwise ``bound`` weighs the next fit (a fit that does not
    explain the data would otherwise weigh its own misfit away).

    Parameters
    ----------
    model : FlowModel
    theta : ndarray of shape (n_params,)
        Starting parameters (the least-squares fit's coefficients, then any
        friction: :class:`FlowModel`).
    groups : list of tuple
        ``(Y, steps)`` or ``(Y, steps, mask)``: trajectories ``Y`` of shape
        (n_trajectories, n_times, n_states) integrated side by side, the RK4
        steps between their samples (as for :func:`flow`; a trajectory that
        ended has steps of zero), and which samples count, of shape
        (n_trajectories, n_times) (all when omitted).
    bound : ndarray of shape (n_states, 2), default=None
        A noise model estimated without the model
        (:func:`~.noise.difference_noise_model`), the check of the fitted
        one; None: the fitted one is always used.
    max_iter : int, default=MAX_ITER
        Levenberg-Marquardt iterations per fit.
    n_reweights : int, default=N_REWEIGHTS
        Fits with weights from a noise model after the unweighted one.
    first_noise : ndarray of shape (n_states, 2), default=None
        A noise model to weigh the first fit, at the states simulated from
        the start; None: unweighted.
    weight_states : list of ndarray, default=None
        Where ``first_noise`` is taken instead, one array per group of the
        shape of its ``Y`` (say, another fit's ``states``): fits of several
        models weighed at the same states minimise the same cost, and their
        misfits can be compared. None: at the states simulated from the start.
    leave_out_outliers : bool, default=False
        After each fit, leave out the samples that stand alone far above its
        residuals (:func:`~.outliers.isolated_outliers`) and, where the last
        fit left some out, fit once more (at most :data:`MAX_OUTLIER_FITS`
        more), reweighted when ``n_reweights`` is positive.

    Returns
    -------
    result : dict
        ``theta``; ``x0``, the fitted initial states, one array per group;
        ``n_iter``, the Levenberg-Marquardt iterations in all;
        ``converged``, whether the last fit stopped on its own rules rather
        than at ``max_iter``; ``noise``, the variance model ``(a_i, b_i)`` of
        each variable that weighs the last fit, ndarray of shape (n_states,
        2) (None without reweighting); ``noise_source``, ``"residuals"`` or
        ``"data"`` (``bound``), or None; ``rms``, the unweighted
        root-mean-square residual of each variable at the end; ``misfit``,
        each trajectory's weighted sum of squared residuals under ``noise``
        (one array per group; with an honest noise model, about the number
        of its observations); ``states``, the fitted trajectories (one array
        per group); ``outliers``, the samples left out (one boolean array
        per group of the shape of its mask; none without
        ``leave_out_outliers``).

    Raises
    ------
    TrajectoryFitError
        If the starting model's simulation of the trajectories is not finite.
    """
    groups = _groups(groups)
    x0s = [g.Y[:, 0].copy() for g in groups]
    theta = np.asarray(theta, dtype=float)
    runs = _simulate(model, theta, x0s, groups)
    if runs is None:
        raise TrajectoryFitError(
            "the model's simulation of the training trajectories is not finite")
    scale = _observed_scale(groups)
    n_iter, noise, source, converged = 0, None, None, True
    if first_noise is not None:
        # Weights at the simulated states, not at the observations: weights
        # from noisy observations favour the samples whose noise shrank them.
        noise, source = first_noise, "data"
        _weigh(groups, [run[0] for run in runs] if weight_states is None else weight_states,
               noise, scale)
    outliers = [np.zeros_like(g.mask) for g in groups]
    n_fits, round_, most = n_reweights + 1, 0, n_reweights + 1 + MAX_OUTLIER_FITS
    while round_ < n_fits:
        if round_ and n_reweights:
            # The states do not depend on the weights: the last fit's serve.
            states = [run[0] for run in runs]
            noise, source = _noise_model(model, groups, states, converged, bound)
            _weigh(groups, states, noise, scale)
        theta, x0s, runs, used, converged = _levenberg_marquardt(
            model, theta, x0s, runs, groups, max_iter)
        n_iter += used
        round_ += 1
        # Samples are left out only where a fit without them follows.
        if leave_out_outliers and round_ < most and _leave_out(model, groups, runs, outliers,
                                                                scale):
            n_fits = max(n_fits, round_ + 1)
    residuals = [g.valid(model.wrap_difference(g.Y - run[0])) for g, run in zip(groups, runs)]
    rms = np.sqrt(np.mean(np.concatenate(residuals) ** 2, axis=0))
    matrix, scores = information(model, groups, runs)
    return dict(theta=theta, x0=x0s, n_iter=n_iter, converged=converged, noise=noise,
                noise_source=source, rms=rms,
                misfit=[g.misfit(model, run[0]) for g, run in zip(groups, runs)],
                states=[run[0] for run in runs], information=matrix, scores=scores,
                outliers=outliers)


def _leave_out(model, groups, runs, outliers, scale):
    """Leave out the isolated outliers of the last fit (:mod:`.outliers`); whether any."""
    raw = [model.wrap_difference(g.Y - run[0]) for g, run in zip(groups, runs)]
    found = isolated_outliers(raw, [r * g.W for r, g in zip(raw, groups)],
                              [g.mask for g in groups], scale)
    for g, far, left in zip(groups, found, outliers):
        g.leave_out(far)
        left |= far
    return any(far.any() for far in found)


def fit_initial_states(model, thetas, groups, noise, *, max_iter=HELD_OUT_MAX_ITER):
    """Each trajectory's misfit under each of several fixed parameters, its initial state fitted.

    The held-out check of a fit: with the parameters fixed, every
    trajectory's initial state is fitted to its observations by
    Levenberg-Marquardt iterations of its own (the trajectories are
    independent: each has its own damping, stops on its own, and only those
    still moving are simulated). The weights come from ``noise`` at the
    states simulated under the first parameters, and weigh every later
    parameter vector's residuals alike, so that the misfits compare; each
    later fit starts from the initial states fitted under the one before
    (parameters under comparison are close).

    Parameters
    ----------
    model : FlowModel
    thetas : array-like of shape (n_thetas, n_params)
        The parameter vectors to compare.
    groups : list of tuple
        As for :func:`fit_trajectories`.
    noise : ndarray of shape (n_states, 2)
        The variance model of the weights.
    max_iter : int, default=HELD_OUT_MAX_ITER

    Returns
    -------
    misfits : list of list of ndarray
        For each parameter vector, each trajectory's weighted sum of squared
        residuals, one array per group; ``inf`` for a trajectory whose
        simulation is not finite.
    """
    groups = _groups(groups)
    scale = _observed_scale(groups)
    misfits, starts = [], [None] * len(groups)
    for k, theta in enumerate(np.atleast_2d(np.asarray(thetas, dtype=float))):
        fitted = [_fit_rows(model, theta, g, noise if k == 0 else None, scale, max_iter, x0)
                  for g, x0 in zip(groups, starts)]
        misfits.append([cost for cost, _ in fitted])
        starts = [x0 for _, x0 in fitted]
    return misfits


def _fit_rows(model, theta, g, noise, scale, max_iter, x0=None):
    """Levenberg-Marquardt over each row's initial state on its own; the rows' misfits and states.

    ``noise`` None keeps the weights ``g`` already has.
    """
    n, _, d = g.Y.shape

    def run(rows, starts, sensitivities="x0"):
        steps = [h if np.ndim(h) == 1 else h[:, rows] for h in g.steps]
        with np.errstate(all="ignore"):
            X, SX, _ = flow(model, theta, starts, steps, sensitivities=sensitivities)
        if SX is None:
            return X, None, None
        cost = g.misfit(model, X, rows)
        cost[~np.isfinite(cost) | ~np.isfinite(SX).all(axis=(1, 2, 3))] = np.inf
        return X, SX, cost

    everyone = np.arange(n)
    warm = x0 is not None
    x0 = g.Y[:, 0].copy() if x0 is None else np.array(x0, dtype=float)
    if noise is not None:
        start, _, _ = run(everyone, x0, sensitivities=False)
        # Weights at the simulated states (as in fit_trajectories), the
        # observations where a simulation fails.
        g.weigh(noise_weights(noise, np.where(np.isfinite(start), start, g.Y), scale, g.mask))
    X, SX, cost = run(everyone, x0)
    lost = np.flatnonzero(~np.isfinite(cost))
    if warm and lost.size:
        # A state fitted under other parameters may not simulate under these.
        x0[lost] = g.Y[lost, 0]
        X[lost], SX[lost], cost[lost] = run(lost, x0[lost])
    lam = np.full(n, 1e-6)
    active = np.isfinite(cost)
    for _ in range(max_iter):
        rows = np.flatnonzero(active)
        if not rows.size:
            break
        r = g.residuals(model, X[rows], rows).reshape(rows.size, -1)
        A = (SX[rows] * g.W[rows][..., None]).reshape(rows.size, -1, d)
        AA = np.einsum("nri,nrj->nij", A, A)
        AA += lam[rows, None, None] * AA * np.eye(d)
        step = np.linalg.solve(AA, np.einsum("nri,nr->ni", A, r)[..., None])[..., 0]
        new_X, new_SX, new_cost = run(rows, x0[rows] + step)
        better = new_cost < cost[rows]
        done = better & (cost[rows] - new_cost < HELD_OUT_RTOL * cost[rows])
        moved = rows[better]
        x0[moved] += step[better]
        X[moved], SX[moved], cost[moved] = new_X[better], new_SX[better], new_cost[better]
        lam[rows] = np.where(better, np.maximum(lam[rows] / 10, 1e-12), lam[rows] * 100)
        active[rows[done]] = False
        active &= lam <= MAX_LAMBDA
    return cost, x0


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


def _levenberg_marquardt(model, theta, x0s, runs, groups, max_iter, fixed=False, rtol=RTOL):
    """Minimise the weighted cost over ``theta`` and the initial states.

    ``runs`` are the simulations (:func:`_simulate`) of the starting point;
    ``fixed`` keeps ``theta`` and fits the initial states only. Stops after
    ``max_iter`` iterations (not converged), when an accepted step lowers
    the cost by less than ``rtol`` of it, or when Marquardt's lambda
    exceeds :data:`MAX_LAMBDA` (no step downhill left: a minimum, to the
    precision the simulations allow). Returns ``(theta, x0s, runs, n_iter,
    converged)``.
    """
    cost = _cost(model, groups, runs)
    lam = 1e-6
    converged = False
    for n_iter in range(1, max_iter + 1):
        step_theta, steps_x0 = _gauss_newton_step(model, groups, runs, lam, fixed)
        new_theta = model.project(theta + step_theta)
        new_x0s = [x0 + dx for x0, dx in zip(x0s, steps_x0)]
        new_runs = _simulate(model, new_theta, new_x0s, groups)
        new_cost = np.inf if new_runs is None else _cost(model, groups, new_runs)
        if new_cost < cost:
            done = cost - new_cost < rtol * cost
            theta, x0s, runs, cost = new_theta, new_x0s, new_runs, new_cost
            lam = max(lam / 10, 1e-12)
            if done:
                converged = True
                break
        else:
            lam *= 100
            if lam > MAX_LAMBDA:
                converged = True
                break
    return theta, x0s, runs, n_iter, converged


def _gauss_newton_step(model, groups, runs, lam, fixed=False):
    """The damped Gauss-Newton step, initial states eliminated by their Schur complement.

    The normal matrix is ``[[diag(A_k^T A_k), A_k^T B_k], [B_k^T A_k, sum_k
    B_k^T B_k]]`` with ``A_k = d r_k / d x0_k`` and ``B_k = d r_k / d theta``;
    its diagonal is scaled by ``1 + lam`` (Marquardt). With ``fixed``, the
    step of ``theta`` is zero and each initial state's is its own block's.
    """
    k = runs[0][2].shape[-1]
    S, rhs, parts = np.zeros((k, k)), np.zeros(k), []
    for g, (X, SX, ST) in zip(groups, runs):
        n, n_times, d = g.Y.shape
        r = g.residuals(model, X).reshape(n, n_times * d)
        A = (SX * g.W[..., None]).reshape(n, n_times * d, d)
        AA = np.einsum("nri,nrj->nij", A, A)
        AA += lam * AA * np.eye(d)
        Ar = np.einsum("nri,nr->ni", A, r)
        AA_inv = np.linalg.inv(AA)
        if fixed:
            parts.append((AA_inv, None, Ar))
            continue
        B = (ST * g.W[..., None]).reshape(n, n_times * d, k)
        AB = np.einsum("nri,nrj->nij", A, B)
        AA_inv_AB = AA_inv @ AB
        S += np.einsum("nri,nrj->ij", B, B) - np.einsum("nji,njk->ik", AB, AA_inv_AB)
        rhs += np.einsum("nri,nr->i", B, r) - np.einsum("nji,nj->i", AA_inv_AB, Ar)
        parts.append((AA_inv, AA_inv_AB, Ar))
    if fixed:
        return np.zeros(k), [np.einsum("nij,nj->ni", AA_inv, Ar) for AA_inv, _, Ar in parts]
    S[np.diag_indices(k)] *= 1 + lam
    # Solved scaled to a unit diagonal: coefficients in the user's units can
    # differ by twenty orders of magnitude (the stiff spring's p^2 0.002 with
    # momenta in thousandths, beside its q^4 1835), and unscaled, the
    # least-squares solve cut the small directions off as round-off.
    scale = unit_diagonal_scale(S)
    step_theta = scale * np.linalg.lstsq(S * np.outer(scale, scale), scale * rhs, rcond=None)[0]
    steps_x0 = [np.einsum("nij,nj->ni", AA_inv, Ar) - AA_inv_AB @ step_theta
                for AA_inv, AA_inv_AB, Ar in parts]
    return step_theta, steps_x0


def _noise_model(model, groups, states, converged, bound):
    """The noise model that weighs the next fit, and where it comes from.

    The residuals' own model (``"residuals"``) when the fit converged and,
    given ``bound``, stays within :data:`MAX_VARIANCE_RATIO` of it in every
    variable; else ``bound`` (``"data"``).
    """
    x = np.concatenate([g.valid(X) for g, X in zip(groups, states)])
    r = np.concatenate([g.valid(model.wrap_difference(g.Y - X)) for g, X in zip(groups, states)])
    fitted = residual_noise_model(x, r)
    if bound is None:
        return fitted, "residuals"
    limit = MAX_VARIANCE_RATIO * mean_variance(bound, x)
    if converged and np.all(mean_variance(fitted, x) <= limit):
        return fitted, "residuals"
    return bound, "data"


def _weigh(groups, states, noise, scale):
    """Weights ``1 / sigma`` at the fitted states (:func:`~.noise.noise_weights`)."""
    for g, X in zip(groups, states):
        g.weigh(noise_weights(noise, X, scale, g.mask))
