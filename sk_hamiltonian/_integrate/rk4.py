"""The classical fourth-order explicit Runge-Kutta method."""

from .base import FixedStepIntegrator


class RK4(FixedStepIntegrator):
    """Classical fourth-order Runge-Kutta method, the paper's solver.

    It works for every model. It does not conserve the Hamiltonian exactly:
    the deviation of a conserved quantity decreases like ``h**4``.

    Parameters
    ----------
    dynamics : Dynamics or callable
        The model, or its vector field.
    """

    name = "rk4"

    def _step_impl(self, y, h):
        f = self.fun
        k1 = f(y)
        k2 = f(y + (0.5 * h) * k1)
        k3 = f(y + (0.5 * h) * k2)
        k4 = f(y + h * k3)
        return y + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
