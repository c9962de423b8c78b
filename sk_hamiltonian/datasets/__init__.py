"""Known Hamiltonian systems (the paper's examples and beyond) and trajectory data."""

from ._systems import (
    PAPER_DT,
    SCENES,
    SYSTEMS,
    HamiltonianSystem,
    cherry,
    damped_pendulum,
    double_pendulum,
    exponential,
    fput_chain,
    henon_heiles,
    load_system,
    single_pendulum,
    toda_lattice,
)
from ._trajectories import make_trajectories

__all__ = [
    "PAPER_DT",
    "SCENES",
    "SYSTEMS",
    "HamiltonianSystem",
    "cherry",
    "damped_pendulum",
    "double_pendulum",
    "exponential",
    "fput_chain",
    "henon_heiles",
    "load_system",
    "make_trajectories",
    "single_pendulum",
    "toda_lattice",
]
