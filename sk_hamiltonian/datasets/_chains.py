"""Scenes beyond the paper: chains of unit masses with nearest-neighbour bonds (FPUT, Toda).

A chain of ``N`` particles has ``N`` momenta and ``N`` positions; its bonds
join neighbours, with fixed ends (``q_0 = q_{N+1} = 0``) or on a ring.
"""

import math
import numbers

import numpy as np

from ._system import HamiltonianSystem, _split


_BOUNDARIES = ("fixed", "periodic")


def _check_chain(n_particles, boundary):
    if (
        isinstance(n_particles, bool)
        or not isinstance(n_particles, numbers.Integral)
        or n_particles < 2
    ):
        raise ValueError(f"n_particles must be an integer >= 2, got {n_particles!r}.")
    if not isinstance(boundary, str) or boundary not in _BOUNDARIES:
        raise ValueError(
            "boundary must be 'fixed' (q_0 = q_{N+1} = 0) or 'periodic' "
            f"(q_{{N+1}} = q_1), got {boundary!r}."
        )
    return int(n_particles)


def _bond_stretches(q, boundary):
    """``r_i = q_{i+1} - q_i``: N + 1 bonds with fixed ends, N on a ring."""
    # Filled in place: padding q or np.roll would add a temporary the size of
    # the batch, which costs about as much as the arithmetic, on every
    # right-hand-side evaluation of the reference solver.
    n = q.shape[-1]
    if boundary == "fixed":
        r = np.empty(q.shape[:-1] + (n + 1,))
        np.subtract(q[..., 1:], q[..., :-1], out=r[..., 1:n])
        r[..., 0] = q[..., 0]
        r[..., n] = -q[..., -1]
    else:
        r = np.empty(q.shape)
        np.subtract(q[..., 1:], q[..., :-1], out=r[..., :-1])
        r[..., -1] = q[..., 0] - q[..., -1]
    return r


def _bond_gradient(force, boundary, out):
    """``dH/dq_i = V'(r_{i-1}) - V'(r_i)``: particle i ends one bond, starts the next."""
    if boundary == "fixed":
        np.subtract(force[..., :-1], force[..., 1:], out=out)
    else:
        np.subtract(force[..., :-1], force[..., 1:], out=out[..., 1:])
        out[..., 0] = force[..., -1] - force[..., 0]
    return out


# Amplitude of the chains' u0*, the longest standing wave at rest. Its
# trajectory then stays inside the [-1, 1] box (checked for 2 to 8, 32 and 64
# particles); at 0.5 the momenta of a ring of two particles exceed 1.
_CHAIN_AMPLITUDE = 0.4


def _chain(name, potential, force, params):
    """A chain of unit masses with nearest-neighbour bond potential ``V``."""
    n_particles, boundary = params["n_particles"], params["boundary"]

    def hamiltonian(X):
        p, q = _split(X)
        bonds = potential(_bond_stretches(q, boundary))
        return 0.5 * np.sum(p**2, axis=-1) + np.sum(bonds, axis=-1)

    def gradient(X):
        p, q = _split(X)
        grad = np.empty(X.shape)
        grad[..., :n_particles] = p
        _bond_gradient(force(_bond_stretches(q, boundary)), boundary, grad[..., n_particles:])
        return grad

    i = np.arange(1, n_particles + 1)
    if boundary == "fixed":
        q0 = _CHAIN_AMPLITUDE * np.sin(np.pi * i / (n_particles + 1))
    else:
        # cos rather than sin: sin(2 pi i / 2) vanishes, leaving a ring of two at rest.
        q0 = _CHAIN_AMPLITUDE * np.cos(2 * np.pi * i / n_particles)
    return HamiltonianSystem(
        name, hamiltonian, gradient,
        domain=[[-1.0, 1.0]] * (2 * n_particles),
        initial_state=np.concatenate([np.zeros(n_particles), q0]),
        params=params,
    )


def fput_chain(n_particles=8, *, alpha=0.0, beta=1.0, boundary="fixed"):
    """Fermi-Pasta-Ulam-Tsingou chain of unit masses.

    ``H = sum_i p_i**2 / 2 + sum_bonds V(r)`` over the bond stretches
    ``r = q_{i+1} - q_i``, with ``V(r) = r**2 / 2 + alpha r**3 / 3 + beta r**4 / 4``.
    This system is not in the paper.

    Parameters
    ----------
    n_particles : int, default=8
        Number ``N`` of moving particles, at least 2; ``n_dof = N``.
    alpha : float, default=0.0
        Coefficient of the cubic term (the alpha-FPUT chain).
    beta : float, default=1.0
        Coefficient of the quartic term (the beta-FPUT chain), at least 0.
    boundary : {"fixed", "periodic"}, default="fixed"
        ``"fixed"``: walls at both ends, ``q_0 = q_{N+1} = 0``, so ``N + 1``
        bonds. ``"periodic"``: a ring, ``q_{N+1} = q_1``, so ``N`` bonds.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``[-1, 1]**(2N)``; ``u0*`` at rest in the longest standing
        wave of amplitude 0.4, ``q_i = 0.4 sin(pi i / (N + 1))`` with fixed
        ends and ``q_i = 0.4 cos(2 pi i / N)`` on a ring. No
        ``paper_settings``.

    Notes
    -----
    The domain: with displacements and momenta of order one, uniformly drawn
    states have bond stretches up to 2, where for ``beta = 1`` the quartic
    term outweighs the quadratic one, so even short trajectories show the
    nonlinearity; the fastest oscillations have periods of order one (``pi``
    for the linear chain, shorter where the quartic term stiffens the bonds).
    Drawn states are rough (neighbouring displacements are independent),
    unlike the smooth ``u0*``, whose trajectory stays inside the box. Its
    bond stretches are at most about ``2.5 / N``, so for long chains it probes
    the nearly linear regime.

    On a ring ``H`` is unchanged by shifting every ``q_i`` by one constant,
    and the total momentum is conserved: a drawn state with nonzero total
    momentum drifts and, over long times, leaves the box.

    With ``beta = 0`` and ``alpha != 0`` the potential is unbounded below: a
    bond stretched past ``r = -1 / alpha`` runs away and the solution blows
    up in finite time (:meth:`HamiltonianSystem.solve` raises
    ``SimulationError``). With ``beta > 0`` every solution is bounded.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import fput_chain
    >>> system = fput_chain(4)
    >>> system.n_dof, system.params["boundary"]
    (4, 'fixed')
    >>> float(system.hamiltonian([0, 0, 0, 0, 1, 0, 0, 0]))  # V(1) + V(-1)
    1.5
    """
    n_particles = _check_chain(n_particles, boundary)
    for name, value in dict(alpha=alpha, beta=beta).items():
        if not (isinstance(value, numbers.Real) and math.isfinite(value)):
            raise ValueError(f"{name} must be a finite number, got {value!r}.")
    if beta < 0:
        raise ValueError(
            f"beta must be >= 0, got {beta!r}; with beta < 0 the potential is "
            "unbounded below and every large enough stretch blows up."
        )

    def potential(r):
        r2 = r * r
        return r2 * (0.5 + r * (alpha / 3) + r2 * (beta / 4))

    def force(r):
        # In place: r is a scratch array, and each temporary of a large batch
        # costs about as much as the arithmetic.
        f = np.multiply(r, beta)
        f += alpha
        f *= r
        f *= r
        f += r
        return f

    return _chain(
        "fput_chain", potential, force,
        dict(n_particles=n_particles, alpha=alpha, beta=beta, boundary=boundary),
    )


def toda_lattice(n_particles=8, *, boundary="fixed"):
    """Toda lattice of unit masses.

    ``H = sum_i p_i**2 / 2 + sum_bonds V(r)`` over the bond stretches
    ``r = q_{i+1} - q_i``, with ``V(r) = exp(-r) + r - 1``: minimal at
    ``r = 0``, ``r**2 / 2 - r**3 / 6 + ...`` near it, exponentially stiff in
    compression and linear in extension. This system is not in the paper.

    Parameters
    ----------
    n_particles : int, default=8
        Number ``N`` of moving particles, at least 2; ``n_dof = N``.
    boundary : {"fixed", "periodic"}, default="fixed"
        ``"fixed"``: walls at both ends, ``q_0 = q_{N+1} = 0``, so ``N + 1``
        bonds. ``"periodic"``: a ring, ``q_{N+1} = q_1``, so ``N`` bonds.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``[-1, 1]**(2N)`` (compressions up to ``r = -2`` cost
        ``V = e**2 - 3``, about 4.4); ``u0*`` at rest in the longest standing
        wave of amplitude 0.4, as for :func:`fput_chain`. No
        ``paper_settings``.

    Notes
    -----
    The stretches add up to zero with either boundary (they telescope to
    ``q_{N+1} - q_0``), so the linear part of ``V`` only shifts ``H`` by a
    constant and the motion is that of the classical Toda lattice with
    ``V(r) = exp(-r)``. It is integrable: the ring is Toda's periodic
    lattice, and a chain with fixed ends is the odd solution
    ``q_{-i} = -q_i`` of a ring of ``2N + 2`` particles. On a ring, as for
    :func:`fput_chain`, a state with nonzero total momentum drifts.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import toda_lattice
    >>> system = toda_lattice(3, boundary="periodic")
    >>> system.initial_state
    array([ 0. ,  0. ,  0. , -0.2, -0.2,  0.4])
    >>> float(system.hamiltonian([0, 0, 0, 1, 1, 1]))  # a rigid shift
    0.0
    """
    n_particles = _check_chain(n_particles, boundary)

    def potential(r):
        return np.expm1(-r) + r

    def force(r):
        f = np.negative(r)
        np.expm1(f, out=f)
        return np.negative(f, out=f)

    return _chain(
        "toda_lattice", potential, force, dict(n_particles=n_particles, boundary=boundary)
    )
