"""Pendula beyond the paper's: with friction, on a torsion spring, coupled by a spring.

The last two are neither polynomial nor periodic in their angles, so the
laws are sparse only in a mixed model space
(``HamiltonianRegressor(mixed=...)``, polynomials and Fourier terms of the
same coordinate).
"""

import math
import numbers

import numpy as np

from ._paper import single_pendulum
from ._system import HamiltonianSystem, _check_positive, _split


def damped_pendulum(damping=0.1, *, length=1.0, g=9.8):
    """The single pendulum with linear friction: a scene beyond the paper.

    ``H(p, q) = p**2 / (2 l**2) + g l (1 - cos q)`` and
    ``dp/dt = -dH/dq - gamma dq/dt``, so ``H`` falls along every trajectory
    that moves. The same system as ``single_pendulum(length, g,
    damping=damping)``, under the name that system carries.

    Parameters
    ----------
    damping : float, default=0.1
        Linear friction coefficient ``gamma > 0`` (for ``gamma = 0``, the
        conservative pendulum, use :func:`single_pendulum`).
    length : float, default=1.0
        Length ``l`` of the pendulum.
    g : float, default=9.8
        Gravitational constant.

    Returns
    -------
    system : HamiltonianSystem
        Named ``"damped_pendulum"``; domain ``(-2 pi, 2 pi) x (-pi, pi)``,
        ``u0* = (-3.876, -1.193)``, no ``paper_settings``.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import damped_pendulum
    >>> damped_pendulum(0.2)
    HamiltonianSystem(name='damped_pendulum', n_dof=1, length=1.0, g=9.8, damping=0.2)
    """
    if not (isinstance(damping, numbers.Real) and 0 < damping < math.inf):
        raise ValueError(
            f"damping must be a positive finite number, got {damping!r}; for the "
            f"conservative pendulum use single_pendulum()."
        )
    return single_pendulum(length, g, damping=damping)


def torsion_pendulum(stiffness=1.0, g=4.0):
    """A pendulum on a torsion spring: gravity and a restoring torque, a scene beyond the paper.

    ``H(p, q) = p**2 / 2 + k q**2 / 2 + g (1 - cos q)``: three terms in a
    space that holds both the polynomials and the Fourier terms of ``q``.
    With ``k > 0`` every motion is bounded, and the angle ranges over
    several radians, where ``q**2`` and ``cos q`` are far from each other.

    Parameters
    ----------
    stiffness : float, default=1.0
        Torsion stiffness ``k > 0``.
    g : float, default=4.0
        Gravitational constant times length (``g l``, unit mass and length).

    Returns
    -------
    system : HamiltonianSystem
        Domain ``(-4, 4) x (-4, 4)``, ``u0* = (1, 2)``, no ``paper_settings``.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import torsion_pendulum
    >>> system = torsion_pendulum()
    >>> float(system.hamiltonian([0.0, 2.0]))  # k q**2 / 2 + g (1 - cos q)
    7.664587...
    """
    _check_positive(stiffness=stiffness, g=g)

    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        p, q = X[..., 0], X[..., 1]
        return p**2 / 2 + stiffness * q**2 / 2 + g * (1 - np.cos(q))

    def gradient(X):
        p, q = _split(X)
        return np.concatenate([p, stiffness * q + g * np.sin(q)], axis=-1)

    return HamiltonianSystem(
        "torsion_pendulum", hamiltonian, gradient, domain=[[-4.0, 4.0], [-4.0, 4.0]],
        initial_state=[1.0, 2.0], params=dict(stiffness=stiffness, g=g),
    )


def coupled_pendula(coupling=1.0, g=9.8):
    """Two pendula whose angles are coupled by a spring, a scene beyond the paper.

    ``H = (p1**2 + p2**2) / 2 + g (2 - cos q1 - cos q2) + c (q1 - q2)**2 / 2``:
    seven terms in a space with the polynomials and the Fourier terms of
    both angles (``q1**2``, ``q1 q2`` and ``q2**2`` from the spring).

    Parameters
    ----------
    coupling : float, default=1.0
        Spring constant ``c > 0`` between the angles.
    g : float, default=9.8
        Gravitational constant (unit masses and lengths).

    Returns
    -------
    system : HamiltonianSystem
        Domain ``(-3, 3)**2 x (-1.5, 1.5)**2`` (momenta first),
        ``u0* = (0, 0, 1, -0.5)``, no ``paper_settings``.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import coupled_pendula
    >>> import numpy as np
    >>> np.round(coupled_pendula().vector_field([0.0, 0.0, 0.5, 0.0]), 4)  # q1 displaced
    array([-5.1984,  0.5   ,  0.    ,  0.    ])
    """
    _check_positive(coupling=coupling, g=g)

    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        p1, p2, q1, q2 = X[..., 0], X[..., 1], X[..., 2], X[..., 3]
        return ((p1**2 + p2**2) / 2 + g * (2 - np.cos(q1) - np.cos(q2))
                + coupling * (q1 - q2) ** 2 / 2)

    def gradient(X):
        p, q = _split(X)
        stretch = coupling * (q[..., :1] - q[..., 1:])
        dq = g * np.sin(q) + np.concatenate([stretch, -stretch], axis=-1)
        return np.concatenate([p, dq], axis=-1)

    return HamiltonianSystem(
        "coupled_pendula", hamiltonian, gradient,
        domain=[[-3.0, 3.0], [-3.0, 3.0], [-1.5, 1.5], [-1.5, 1.5]],
        initial_state=[0.0, 0.0, 1.0, -0.5], params=dict(coupling=coupling, g=g),
    )
