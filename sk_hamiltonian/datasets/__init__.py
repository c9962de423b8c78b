"""Known Hamiltonian systems and trajectory data from the paper's numerical examples."""

from ._systems import (
    PAPER_DT,
    SYSTEMS,
    HamiltonianSystem,
    cherry,
    double_pendulum,
    exponential,
    henon_heiles,
    load_system,
    single_pendulum,
)
from ._trajectories import make_trajectories

__all__ = [
    "PAPER_DT",
    "SYSTEMS",
    "HamiltonianSystem",
    "cherry",
    "double_pendulum",
    "exponential",
    "henon_heiles",
    "load_system",
    "make_trajectories",
    "single_pendulum",
]
