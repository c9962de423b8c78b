"""Fixed-step time integrators behind ``simulate``.

One module per method family, a base class whose public ``step`` calls the
private ``_step_impl``, a :class:`Dynamics` object through which an integrator
asks the model for what it needs (its vector field; ``grad H`` and its Hessian
for the energy-conserving method; the separable split for the explicit
symplectic ones), and :data:`METHODS`, which maps the names accepted by the
``method=`` arguments to the classes. :mod:`.driver` runs a whole
integration, by the steps here or as one compiled loop (:mod:`.compiled`);
:mod:`.simulation` is what a fitted model's ``simulate`` delegates to.
"""

from ..exceptions import SimulationError
from .avf import AveragedVectorField
from .base import Dynamics, FixedStepIntegrator
from .driver import METHODS, integrate, make_integrator, raise_on_failure
from .rk4 import RK4
from .symplectic import Leapfrog, Yoshida4

__all__ = [
    "METHODS",
    "RK4",
    "AveragedVectorField",
    "Dynamics",
    "FixedStepIntegrator",
    "Leapfrog",
    "SimulationError",
    "Yoshida4",
    "integrate",
    "make_integrator",
    "raise_on_failure",
]
