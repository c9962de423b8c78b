"""The known systems by name: the paper's five (:data:`SYSTEMS`) and the scenes beyond it (:data:`SCENES`).

The systems themselves live in :mod:`._paper` (the paper's examples),
:mod:`._pendula` and :mod:`._oscillators` (scenes beyond them) and
:mod:`._chains` (lattices);
:mod:`._system` defines what a system is.
"""

import functools

from ._chains import fput_chain, toda_lattice
from ._oscillators import anharmonic_spring, double_well
from ._paper import cherry, double_pendulum, exponential, henon_heiles, single_pendulum
from ._pendula import coupled_pendula, damped_pendulum, torsion_pendulum


#: The paper's five systems by name; values are the factories.
SYSTEMS = {
    "single_pendulum": single_pendulum,
    "exponential": exponential,
    "henon_heiles": henon_heiles,
    "cherry": cherry,
    "double_pendulum": double_pendulum,
}


#: Systems beyond the paper's, by name; values are the factories. Each builds
#: a system of that name.
SCENES = {
    "anharmonic_spring": anharmonic_spring,
    "coupled_pendula": coupled_pendula,
    "damped_pendulum": damped_pendulum,
    "double_well": double_well,
    "double_pendulum_full_circle": functools.partial(double_pendulum, full_circle=True),
    "fput_chain": fput_chain,
    "toda_lattice": toda_lattice,
    "torsion_pendulum": torsion_pendulum,
}


def load_system(name, **params):
    """Build a system by name.

    Parameters
    ----------
    name : str
        A key of :data:`SYSTEMS`, the paper's systems: ``"single_pendulum"``,
        ``"exponential"``, ``"henon_heiles"``, ``"cherry"`` or
        ``"double_pendulum"``; or of :data:`SCENES`, systems beyond the paper:
        ``"anharmonic_spring"``, ``"coupled_pendula"``, ``"damped_pendulum"``,
        ``"double_pendulum_full_circle"``, ``"double_well"``, ``"fput_chain"``, ``"toda_lattice"``
        or ``"torsion_pendulum"``.
    **params
        Parameters passed to the factory, e.g. ``length`` for the single
        pendulum or ``n_particles`` for the chains.

    Returns
    -------
    system : HamiltonianSystem
        The system.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import load_system
    >>> load_system("single_pendulum", length=2.0)
    HamiltonianSystem(name='single_pendulum', n_dof=1, length=2.0, g=9.8)
    >>> load_system("toda_lattice", n_particles=16).n_dof
    16
    """
    factories = {**SYSTEMS, **SCENES}
    if not isinstance(name, str) or name not in factories:
        raise ValueError(
            f"Unknown system {name!r}; valid names are {sorted(SYSTEMS)} (the "
            f"paper's) and {sorted(SCENES)}."
        )
    return factories[name](**params)
