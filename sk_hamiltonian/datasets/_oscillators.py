"""Oscillators beyond the paper's: a particle in a double well, a hardening spring."""

import numbers

import numpy as np

from ._system import HamiltonianSystem, _split


def double_well(stiffness=1.0, quartic=1.0):
    """A particle in a double-well potential (an undamped Duffing oscillator), a scene beyond the paper.

    ``H(p, q) = p**2 / 2 - a q**2 / 2 + b q**4 / 4``: three monomials, with
    wells at ``q = +-sqrt(a / b)`` and the separatrix at ``H = 0``.

    Parameters
    ----------
    stiffness : float, default=1.0
        ``a > 0``, the (negative) stiffness at the top of the barrier.
    quartic : float, default=1.0
        ``b > 0``, the quartic stiffening.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``(-1.5, 1.5) x (-2, 2)``, ``u0* = (0.3, 1.2)``, no
        ``paper_settings``.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import double_well
    >>> float(double_well().hamiltonian([0.0, 1.0]))  # the bottom of a well
    -0.25
    """
    return _quartic_oscillator("double_well", -1, stiffness, quartic, [[-1.5, 1.5], [-2.0, 2.0]])


def anharmonic_spring(stiffness=1.0, quartic=1.0):
    """A hardening spring (an undamped Duffing oscillator with one well), a scene beyond the paper.

    ``H(p, q) = p**2 / 2 + k q**2 / 2 + b q**4 / 4``: three monomials, one
    well at ``q = 0``, and a period that shortens as the energy grows. Its
    laws tie closely with periodic series in ``q`` on noisy derivatives,
    which makes it a test of a search's parsimony.

    Parameters
    ----------
    stiffness : float, default=1.0
        ``k > 0``, the linear stiffness.
    quartic : float, default=1.0
        ``b > 0``, the quartic stiffening.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``(-1.5, 1.5) x (-1.5, 1.5)``, ``u0* = (0.3, 1.2)``, no
        ``paper_settings``.

    See Also
    --------
    double_well : The same monomials with a negative stiffness.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import anharmonic_spring
    >>> float(anharmonic_spring().hamiltonian([0.0, 1.0]))
    0.75
    """
    return _quartic_oscillator("anharmonic_spring", 1, stiffness, quartic,
                               [[-1.5, 1.5], [-1.5, 1.5]])


def _quartic_oscillator(name, sign, stiffness, quartic, domain):
    """``H = p**2 / 2 + sign * a q**2 / 2 + b q**4 / 4``, its parameters checked."""
    for label, value in (("stiffness", stiffness), ("quartic", quartic)):
        if not (isinstance(value, numbers.Real) and 0 < value < np.inf):
            raise ValueError(f"{label} must be a positive finite number, got {value!r}.")
    linear = sign * stiffness

    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        p, q = X[..., 0], X[..., 1]
        return p**2 / 2 + linear * q**2 / 2 + quartic * q**4 / 4

    def gradient(X):
        p, q = _split(X)
        return np.concatenate([p, linear * q + quartic * q**3], axis=-1)

    return HamiltonianSystem(
        name, hamiltonian, gradient, domain=domain, initial_state=[0.3, 1.2],
        params=dict(stiffness=stiffness, quartic=quartic),
    )
