"""Explicit symplectic methods for separable Hamiltonians ``H = T(p) + V(q)``."""

import numpy as np

from .base import FixedStepIntegrator


class Leapfrog(FixedStepIntegrator):
    """Stormer-Verlet (leapfrog), the explicit symplectic method of order 2.

    One step is a half kick, a drift and a half kick::

        p <- p - h/2 dV/dq(q);  q <- q + h dT/dp(p);  p <- p - h/2 dV/dq(q)

    It needs ``H = T(p) + V(q)`` and costs two gradient halves per step.
    Being symplectic, it keeps the energy error bounded (it oscillates, with
    no drift) over exponentially long times, and is time-reversible.

    Parameters
    ----------
    dynamics : Dynamics
        A conservative separable model (with ``kinetic_gradient`` and
        ``potential_gradient``).
    """

    name = "leapfrog"
    #: Composition weights of the substeps (one leapfrog step here).
    weights = (1.0,)

    def _check(self, dynamics):
        if dynamics.kinetic_gradient is None or dynamics.potential_gradient is None:
            raise ValueError(
                f"method={self.name!r} is an explicit symplectic method for separable "
                f"Hamiltonians H = T(p) + V(q); this model is not separable (a kept "
                f"term holds both momenta and positions: fit HamiltonianRegressor with "
                f"separable=True), so use method='avf' (energy-conserving) or "
                f"method='rk4'."
            )
        if dynamics.damping is not None:
            raise ValueError(
                f"method={self.name!r} integrates conservative systems; this model has "
                f"damping, so use method='avf' (its dissipation is exact) or method='rk4'."
            )

    def _step_impl(self, y, h):
        d = y.shape[1] // 2
        p, q = y[:, :d].copy(), y[:, d:].copy()
        kick, drift = self.dynamics.potential_gradient, self.dynamics.kinetic_gradient
        for w in self.weights:
            p -= (0.5 * w * h) * kick(q)
            q += (w * h) * drift(p)
            p -= (0.5 * w * h) * kick(q)
        return np.concatenate([p, q], axis=1)


class Yoshida4(Leapfrog):
    """Yoshida's fourth-order composition of three leapfrog steps.

    Weights ``w1 = 1 / (2 - 2**(1/3))`` and ``w0 = -2**(1/3) w1``, steps
    ``w1 h, w0 h, w1 h``: symmetric, symplectic and of order 4, at three
    leapfrog steps' cost. Same requirements as :class:`Leapfrog`.

    Parameters
    ----------
    dynamics : Dynamics
        A conservative separable model.
    """

    name = "yoshida4"
    _w1 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
    weights = (_w1, -(2.0 ** (1.0 / 3.0)) * _w1, _w1)
