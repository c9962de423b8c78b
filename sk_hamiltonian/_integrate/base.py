"""Base class, model interface and driver shared by the fixed-step integrators."""

import math

import numpy as np

from .._config import use_numba
from ..exceptions import SimulationError


def apply_inverse_symplectic(g):
    """Return ``J^{-1} g`` for ``J = [[0, I], [-I, 0]]``, row by row.

    ``J^{-1} = [[0, -I], [I, 0]]``, so ``(p, q)``-gradients map to
    ``(-dH/dq, dH/dp)``: Hamilton's equations.
    """
    d = g.shape[-1] // 2
    # Two ufunc calls into one buffer: a simulation calls this at every stage,
    # where ``np.concatenate`` of a list costs more than the arithmetic.
    out = np.empty_like(g)
    np.negative(g[..., d:], out=out[..., :d])
    out[..., d:] = g[..., :d]
    return out


class Dynamics:
    """What an integrator may ask of a model of ``dy/dt = f(y)``.

    Every model gives its vector field, and its Jacobian for the implicit
    averaged-vector-field method. A Hamiltonian model may also give a linear
    damping ``gamma`` (``dp/dt = -dH/dq - gamma * dH/dp``) and, when ``H =
    T(p) + V(q)``, the two partial gradients that explicit symplectic methods
    step with.

    Parameters
    ----------
    field : callable
        ``f``, mapping ``(n, n_features)`` to ``(n, n_features)``.
    jacobian : callable, default=None
        ``Df``, mapping ``(n, n_features)`` to ``(n, n_features, n_features)``.
    damping : ndarray of shape (n_features // 2,), default=None
        Linear damping coefficients; None (or all zero) for a conservative model.
    kinetic_gradient, potential_gradient : callable, default=None
        ``dT/dp`` and ``dV/dq`` of a separable ``H``, mapping ``(n, d)`` to
        ``(n, d)``; None for a model that is not separable.
    n_nodes : int, default=1
        Gauss-Legendre nodes that make the average of ``f`` over a segment
        exact (or accurate to round-off), for the AVF method.
    phase_rates : ndarray of shape (n_features,), default=None
        For a model with trigonometric factors: per variable, the radians
        per unit its fastest factor turns (see ``ModelSpace.phase_rates``).
        ``n_nodes`` then holds for short segments, and the AVF method adds
        nodes to a step whose segment turns its factors further. None: the
        field is a polynomial.
    wrap : callable, default=None
        Maps states to their canonical representatives (periodic variables
        into their period); applied between output times.
    compiled : KernelModel, default=None
        The model's space and coefficients, for whole integrations as
        compiled loops (:mod:`sk_hamiltonian._kernels.simulate`); None: the
        steps above only.
    """

    def __init__(
        self, field, *, jacobian=None, damping=None, kinetic_gradient=None,
        potential_gradient=None, n_nodes=1, phase_rates=None, wrap=None, compiled=None,
    ):
        self.field = field
        self.jacobian = jacobian
        self.damping = None if damping is None or not np.any(damping) else np.asarray(damping)
        self.kinetic_gradient = kinetic_gradient
        self.potential_gradient = potential_gradient
        self.n_nodes = n_nodes
        self.phase_rates = None if phase_rates is None else np.asarray(phase_rates, dtype=float)
        self.wrap = wrap
        self.compiled = compiled


class FixedStepIntegrator:
    """Base class of the fixed-step integrators.

    Integrators work on a batch of states of shape ``(n_states, n_features)``
    at once. Subclasses implement :meth:`_step_impl` and check in
    :meth:`_check` that the model gives what they need; callers use
    :meth:`step`.

    Parameters
    ----------
    dynamics : Dynamics or callable
        The model; a callable is taken as the vector field alone.
    """

    #: Whether the method conserves (or dissipates exactly as the model does)
    #: the model's energy (set by subclasses).
    conserves_energy = False
    #: Name of the method in :data:`METHODS` (set by subclasses).
    name = None

    def __init__(self, dynamics):
        if not isinstance(dynamics, Dynamics):
            dynamics = Dynamics(dynamics)
        self.dynamics = dynamics
        self.fun = dynamics.field
        self._check(dynamics)

    def _check(self, dynamics):
        """Raise ValueError if the model lacks what the method needs."""

    def step(self, y, h):
        """Advance a batch of states by one step.

        Parameters
        ----------
        y : ndarray of shape (n_states, n_features)
            Current states.
        h : float
            Step size.

        Returns
        -------
        y_new : ndarray of shape (n_states, n_features)
            States after one step. Rows that could not be advanced (an implicit
            solve that did not converge) are NaN, which :func:`integrate`
            reports as a failure of that trajectory.
        """
        return self._step_impl(np.asarray(y, dtype=float), float(h))

    def _step_impl(self, y, h):
        raise NotImplementedError


def integrate(integrator, y0, t, max_step=None):
    """Integrate a batch of initial states and sample the solutions at ``t``.

    Each interval ``[t[k], t[k + 1]]`` is split into the fewest equal steps no
    longer than ``max_step``. A trajectory whose state becomes non-finite is
    frozen at its last finite state and reported in ``failed_at``; the others
    go on. Periodic variables are wrapped at every output time if the model
    says how (``Dynamics.wrap``).

    Parameters
    ----------
    integrator : FixedStepIntegrator
        The stepping method.
    y0 : ndarray of shape (n_states, n_features)
        Initial states, taken at time ``t[0]``.
    t : ndarray of shape (n_times,)
        Strictly increasing output times.
    max_step : float or None
        Largest step; None (or infinity) steps from one output time to the next.

    Returns
    -------
    y : ndarray of shape (n_times, n_states, n_features)
        Solutions at ``t``; for a failed trajectory, the values from its
        failure on repeat its last finite state.
    failed_at : ndarray of shape (n_states,)
        For each trajectory, the index into ``t`` of the first output time it
        could not reach, or ``n_times`` if it reached them all.
    """
    if getattr(integrator.dynamics, "compiled", None) is not None and use_numba():
        from .._kernels.simulate import integrate_compiled

        result = integrate_compiled(integrator, y0, t, max_step)
        if result is not None:
            return result
    wrap = integrator.dynamics.wrap or (lambda y: y)
    y = wrap(np.array(y0, dtype=float))
    n_times = t.shape[0]
    out = np.empty((n_times,) + y.shape)
    out[0] = y
    failed_at = np.full(y.shape[0], n_times, dtype=np.intp)
    active = np.arange(y.shape[0])
    substeps = max_step is not None and math.isfinite(max_step)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for k in range(n_times - 1):
            interval = t[k + 1] - t[k]
            n_sub = max(1, math.ceil(interval / max_step - 1e-9)) if substeps else 1
            h = interval / n_sub
            y_active = y[active]
            for _ in range(n_sub):
                y_active = integrator.step(y_active, h)
            finite = np.isfinite(y_active).all(axis=1)
            if not finite.all():
                failed_at[active[~finite]] = k + 1
                active, y_active = active[finite], y_active[finite]
            y[active] = wrap(y_active)
            out[k + 1] = y
            if active.size == 0:
                out[k + 2 :] = y
                break
    return out, failed_at


LEARNED_MODEL_HINT = (
    "The trajectory probably left the domain where the model is valid; use a "
    "shorter horizon, a smaller step (max_step), or initial states inside the "
    "training domain."
)


def raise_on_failure(failed_at, t, what="the learned system", hint=LEARNED_MODEL_HINT):
    """Raise :class:`SimulationError` if any trajectory of :func:`integrate` failed.

    Parameters
    ----------
    failed_at : ndarray of shape (n_states,)
        As returned by :func:`integrate`.
    t : ndarray of shape (n_times,)
        The output times given to :func:`integrate`.
    what : str
        What was simulated, for the message.
    hint : str
        How to avoid the failure, for the message.
    """
    n_failed = int(np.sum(failed_at < t.shape[0]))
    if n_failed:
        first = int(failed_at.min())
        raise SimulationError(
            f"Simulating {what} failed for {n_failed} of {failed_at.shape[0]} initial "
            f"state(s): the state became non-finite, or an implicit step did not "
            f"converge, between t={t[first - 1]:.6g} and t={t[first]:.6g}. {hint}",
            t_reached=float(t[first - 1]),
            t_failed=float(t[first]),
            failed_at=failed_at.copy(),
        )
