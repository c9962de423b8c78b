"""Pendula beyond the paper's: with friction."""

import math
import numbers

from ._paper import single_pendulum


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
