"""Fixed-step time integrators behind ``simulate``.

One module per method, a base class whose public ``step`` calls the private
``_step_impl``, and :data:`METHODS`, which maps the names accepted by the
``method=`` arguments to the classes.
"""

from .avf import AveragedVectorField, apply_inverse_symplectic
from .base import FixedStepIntegrator, SimulationError, integrate, raise_on_failure
from .rk4 import RK4

METHODS = {"rk4": RK4, "avf": AveragedVectorField}

__all__ = [
    "METHODS",
    "RK4",
    "AveragedVectorField",
    "FixedStepIntegrator",
    "SimulationError",
    "apply_inverse_symplectic",
    "integrate",
    "raise_on_failure",
]
