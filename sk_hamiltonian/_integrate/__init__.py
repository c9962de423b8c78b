"""Fixed-step time integrators behind ``simulate``.

One module per method family, a base class whose public ``step`` calls the
private ``_step_impl``, a :class:`Dynamics` object through which an integrator
asks the model for what it needs (its vector field; ``grad H`` and its Hessian
for the energy-conserving method; the separable split for the explicit
symplectic ones), and :data:`METHODS`, which maps the names accepted by the
``method=`` arguments to the classes.
"""

from .avf import AveragedVectorField, apply_structure
from .base import (
    Dynamics,
    FixedStepIntegrator,
    SimulationError,
    apply_inverse_symplectic,
    integrate,
    raise_on_failure,
)
from .rk4 import RK4
from .symplectic import Leapfrog, Yoshida4

METHODS = {cls.name: cls for cls in (RK4, AveragedVectorField, Leapfrog, Yoshida4)}


def make_integrator(method, dynamics):
    """The integrator named ``method`` for a model, or a ValueError naming the choices."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {sorted(METHODS)}; got {method!r}.")
    return METHODS[method](dynamics)


__all__ = [
    "METHODS",
    "RK4",
    "AveragedVectorField",
    "Dynamics",
    "FixedStepIntegrator",
    "Leapfrog",
    "SimulationError",
    "Yoshida4",
    "apply_inverse_symplectic",
    "apply_structure",
    "integrate",
    "make_integrator",
    "raise_on_failure",
]
