"""Known Hamiltonian systems (the paper's examples and beyond) and trajectory data."""

from ._chains import fput_chain, toda_lattice
from ._paper import PAPER_DT, cherry, double_pendulum, exponential, henon_heiles, single_pendulum
from ._oscillators import anharmonic_spring, double_well
from ._pendula import coupled_pendula, damped_pendulum, torsion_pendulum
from ._system import HamiltonianSystem
from ._systems import SCENES, SYSTEMS, load_system
from ._trajectories import make_trajectories

__all__ = [
    "PAPER_DT",
    "SCENES",
    "SYSTEMS",
    "HamiltonianSystem",
    "anharmonic_spring",
    "cherry",
    "coupled_pendula",
    "damped_pendulum",
    "double_pendulum",
    "double_well",
    "exponential",
    "fput_chain",
    "henon_heiles",
    "load_system",
    "make_trajectories",
    "single_pendulum",
    "toda_lattice",
    "torsion_pendulum",
]
