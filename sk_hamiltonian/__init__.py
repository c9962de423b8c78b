"""Structure-preserving learning of unknown Hamiltonian systems from trajectories."""

__version__ = "0.1.0"
