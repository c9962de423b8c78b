"""Base class and model interface shared by the fixed-step integrators."""

import numpy as np


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
        compiled loops (:mod:`.compiled`); None: the
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
        h : float or ndarray of shape (n_states, 1)
            Step size, or one per state (RK4 and the averaged vector field).

        Returns
        -------
        y_new : ndarray of shape (n_states, n_features)
            States after one step. Rows that could not be advanced (an implicit
            solve that did not converge) are NaN, which :func:`integrate`
            reports as a failure of that trajectory.
        """
        h = np.asarray(h, dtype=float) if np.ndim(h) else float(h)
        return self._step_impl(np.asarray(y, dtype=float), h)

    def _step_impl(self, y, h):
        raise NotImplementedError
