"""Structure-preserving learning of unknown Hamiltonian systems from trajectories.

The estimators follow Wu, Qin & Xiu, "Structure-preserving method for
reconstructing unknown Hamiltonian systems from trajectory data".
"""

from ._config import config_context, get_config, set_config
from ._derivatives import DerivativeTransformer
from ._hamiltonian import HamiltonianRegressor
from ._trajectories import unpack_derivatives
from ._vector_field import VectorFieldRegressor
from .io import ModelFileError, load, save
from .exceptions import (
    ConservationWarning,
    DomainWarning,
    IllConditionedWarning,
    OutlierWarning,
    SimulationError,
    SmoothingWarning,
    StateOrderWarning,
)

__version__ = "0.1.0"

__all__ = [
    "ConservationWarning",
    "DerivativeTransformer",
    "DomainWarning",
    "HamiltonianRegressor",
    "IllConditionedWarning",
    "ModelFileError",
    "OutlierWarning",
    "SimulationError",
    "SmoothingWarning",
    "StateOrderWarning",
    "VectorFieldRegressor",
    "config_context",
    "get_config",
    "load",
    "save",
    "set_config",
    "unpack_derivatives",
]
