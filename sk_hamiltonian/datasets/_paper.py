"""The five Hamiltonian systems of the paper's numerical examples.

Each factory returns a :class:`~._system.HamiltonianSystem` with the paper's
domain, test initial state ``u0*`` and learning settings
(``paper_settings``). :func:`double_pendulum` also builds the full-circle
variant beyond the paper.
"""

import math
import numbers

import numpy as np

from ._system import HamiltonianSystem, _check_positive, _split

#: Sampling step of the trajectory data in the examples reproducing the paper.
#: The paper does not state it; with 0.01 the O(dt**2) error of second-order
#: finite differences (about 1e-4 relative) is negligible next to the model
#: errors. All five examples use this one value.
PAPER_DT = 0.01


def single_pendulum(length=1.0, g=9.8, *, damping=0.0):
    """Example 1: ideal single pendulum with unit mass, optionally with friction.

    ``H(p, q) = p**2 / (2 l**2) + g l (1 - cos q)``; with ``damping``
    ``gamma``, ``dp/dt = -dH/dq - gamma dq/dt``.

    Parameters
    ----------
    length : float, default=1.0
        Length ``l`` of the pendulum.
    g : float, default=9.8
        Gravitational constant.
    damping : float, default=0.0
        Linear friction coefficient ``gamma >= 0``. Non-zero values make a
        damped pendulum (not one of the paper's examples: no paper settings).

    Returns
    -------
    system : HamiltonianSystem
        Domain ``(-2 pi, 2 pi) x (-pi, pi)``, ``u0* = (-3.876, -1.193)``.
    """
    _check_positive(length=length, g=g)
    if not (isinstance(damping, numbers.Real) and 0 <= damping < math.inf):
        raise ValueError(f"damping must be a finite number >= 0, got {damping!r}.")

    def hamiltonian(X):
        p, q = X[..., 0], X[..., 1]
        return p**2 / (2 * length**2) + g * length * (1 - np.cos(q))

    def gradient(X):
        p, q = _split(X)
        return np.concatenate([p / length**2, g * length * np.sin(q)], axis=-1)

    damped = damping > 0
    return HamiltonianSystem(
        "damped_pendulum" if damped else "single_pendulum", hamiltonian, gradient,
        domain=[[-2 * np.pi, 2 * np.pi], [-np.pi, np.pi]],
        initial_state=[-3.876, -1.193],
        paper_settings=(
            None if damped else dict(degree=6, n_trajectories=500, n_intervals=40, noise=0.08)
        ),
        params=dict(length=length, g=g, **(dict(damping=damping) if damped else {})),
        damping=[damping],
    )


def exponential(alpha1=1.0, alpha2=1.1):
    """Example 2: ``H(p, q) = exp(-alpha1 p**2 - alpha2 q**4)``.

    Parameters
    ----------
    alpha1 : float, default=1.0
        Coefficient of ``p**2``.
    alpha2 : float, default=1.1
        Coefficient of ``q**4``.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``[-1, 1]**2``, ``u0* = (0.6, 0.6)``.
    """
    _check_positive(alpha1=alpha1, alpha2=alpha2)

    def hamiltonian(X):
        p, q = X[..., 0], X[..., 1]
        return np.exp(-alpha1 * p**2 - alpha2 * q**4)

    def gradient(X):
        p, q = _split(X)
        h = np.exp(-alpha1 * p**2 - alpha2 * q**4)
        return np.concatenate([-2 * alpha1 * p * h, -4 * alpha2 * q**3 * h], axis=-1)

    return HamiltonianSystem(
        "exponential", hamiltonian, gradient,
        domain=[[-1.0, 1.0]] * 2,
        initial_state=[0.6, 0.6],
        paper_settings=dict(degree=6, n_trajectories=300, n_intervals=2, noise=0.0),
        params=dict(alpha1=alpha1, alpha2=alpha2),
    )


def henon_heiles():
    """Example 3: the Henon-Heiles system.

    ``H = (p1**2 + p2**2) / 2 + (q1**2 + q2**2) / 2 + q1**2 q2 - q2**3 / 3``.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``[-1, 1]**4``, ``u0* = (0.3, -0.25, 0.2, -0.25)``.
    """

    def hamiltonian(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        return 0.5 * (p1**2 + p2**2 + q1**2 + q2**2) + q1**2 * q2 - q2**3 / 3

    def gradient(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        return np.stack([p1, p2, q1 + 2 * q1 * q2, q2 + q1**2 - q2**2], axis=-1)

    return HamiltonianSystem(
        "henon_heiles", hamiltonian, gradient,
        domain=[[-1.0, 1.0]] * 4,
        initial_state=[0.3, -0.25, 0.2, -0.25],
        paper_settings=dict(degree=3, n_trajectories=500, n_intervals=2, noise=0.0),
    )


def cherry():
    """Example 4: Cherry's system, whose solutions can blow up in finite time.

    ``H = (q1**2 + p1**2) / 2 - (q2**2 + p2**2) + p2 (p1**2 - q1**2) / 2 - q1 q2 p1``.

    Returns
    -------
    system : HamiltonianSystem
        Domain ``(-2, 2) x (-1, 2) x (-2, 1) x (-1, 1)``,
        ``u0* = (-0.05, 0.1, 0.15, 0.1)``. The true solution from ``u0*``
        blows up near ``t = 27.9``.
    """

    def hamiltonian(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        return (
            0.5 * (q1**2 + p1**2) - (q2**2 + p2**2) + 0.5 * p2 * (p1**2 - q1**2)
            - q1 * q2 * p1
        )

    def gradient(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        return np.stack(
            [
                p1 + p2 * p1 - q1 * q2,
                -2 * p2 + 0.5 * (p1**2 - q1**2),
                q1 - p2 * q1 - q2 * p1,
                -2 * q2 - q1 * p1,
            ],
            axis=-1,
        )

    return HamiltonianSystem(
        "cherry", hamiltonian, gradient,
        domain=[[-2.0, 2.0], [-1.0, 2.0], [-2.0, 1.0], [-1.0, 1.0]],
        initial_state=[-0.05, 0.1, 0.15, 0.1],
        paper_settings=dict(degree=3, n_trajectories=500, n_intervals=2, noise=0.0),
    )


def double_pendulum(
    m1=1.0, m2=1.0, l1=1.0, l2=1.0, g=9.8, *, full_circle=False, momentum_bound=1.0
):
    """Example 5: double pendulum in angles and canonical momenta.

    With ``s = q1 - q2`` and ``D(s) = m1 + m2 sin(s)**2``::

        H = N / (2 m2 l1**2 l2**2 D) - (m1 + m2) g l1 cos q1 - m2 g l2 cos q2,
        N = m2 l2**2 p1**2 + (m1 + m2) l1**2 p2**2 - 2 m2 l1 l2 p1 p2 cos s.

    Parameters
    ----------
    m1, m2 : float, default=1.0
        Masses of the inner and outer bob.
    l1, l2 : float, default=1.0
        Lengths of the inner and outer rod.
    g : float, default=9.8
        Gravitational constant.
    full_circle : bool, default=False
        Whether the angles range over full circles: the same ``H``, but angle
        domains ``[-pi, pi)`` marked ``periodic`` and a large-swing ``u0*``.
        This variant is not in the paper.
    momentum_bound : float, default=1.0
        Half-width of the momentum domain when ``full_circle=True``; ignored
        otherwise.

    Returns
    -------
    system : HamiltonianSystem
        With ``full_circle=False``, the paper's system: domain
        ``(-5, 5) x (-4, 4) x (-1, 1) x (-1, 1)``, ``u0* = (0, 0, pi/6, pi/4)``,
        simulated up to ``t = 20`` in the paper. With ``full_circle=True``,
        ``"double_pendulum_full_circle"``: domain ``[-b, b]**2 x [-pi, pi)**2``
        with ``b = momentum_bound``, ``periodic = (False, False, True, True)``,
        ``u0* = (0, 0, 0, 2)`` and no ``paper_settings``.

    Notes
    -----
    The full-circle ``u0*`` starts the outer rod at rest at 2 rad (115
    degrees); with the default parameters the inner rod then swings to about
    +-1.15 rad. Its motion is regular, not chaotic: from it, and from the
    3 x 3 grid of starts at rest within 0.1 rad of it, a perturbation of
    size ``1e-8`` grows to at most about ``1e-5`` by ``t = 200``, whereas
    from ``(0, 0, 2, -1)`` it reaches order one by ``t = 20``. Along it the
    momenta reach about ``|p1| = 6.7`` and ``|p2| = 4.5``, far outside the
    default momentum domain; ``H`` is quadratic in ``p``, so a model that is
    quadratic in ``p`` too can extrapolate there.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import double_pendulum
    >>> system = double_pendulum(full_circle=True)
    >>> system.name
    'double_pendulum_full_circle'
    >>> system.periodic
    array([False, False,  True,  True])
    """
    _check_positive(m1=m1, m2=m2, l1=l1, l2=l2, g=g, momentum_bound=momentum_bound)
    if not isinstance(full_circle, (bool, np.bool_)):
        raise ValueError(f"full_circle must be True or False, got {full_circle!r}.")
    M = m1 + m2

    def kinetic_parts(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        s = q1 - q2
        cos_s, sin_s = np.cos(s), np.sin(s)
        D = m1 + m2 * sin_s**2
        N = m2 * l2**2 * p1**2 + M * l1**2 * p2**2 - 2 * m2 * l1 * l2 * p1 * p2 * cos_s
        return p1, p2, q1, q2, cos_s, sin_s, D, N

    def hamiltonian(X):
        p1, p2, q1, q2, _, _, D, N = kinetic_parts(X)
        kinetic = N / (2 * m2 * l1**2 * l2**2 * D)
        return kinetic - M * g * l1 * np.cos(q1) - m2 * g * l2 * np.cos(q2)

    def gradient(X):
        p1, p2, q1, q2, cos_s, sin_s, D, N = kinetic_parts(X)
        # The kinetic energy depends on q only through s, so its q1- and
        # q2-derivatives are +dT/ds and -dT/ds; dD/ds = m2 sin(2s).
        dT_ds = p1 * p2 * sin_s / (l1 * l2 * D) - N * 2 * sin_s * cos_s / (
            2 * l1**2 * l2**2 * D**2
        )
        dH_dp1 = (l2 * p1 - l1 * p2 * cos_s) / (l1**2 * l2 * D)
        dH_dp2 = (M * l1 * p2 - m2 * l2 * p1 * cos_s) / (m2 * l1 * l2**2 * D)
        dH_dq1 = M * g * l1 * np.sin(q1) + dT_ds
        dH_dq2 = m2 * g * l2 * np.sin(q2) - dT_ds
        return np.stack([dH_dp1, dH_dp2, dH_dq1, dH_dq2], axis=-1)

    params = dict(m1=m1, m2=m2, l1=l1, l2=l2, g=g)
    if full_circle:
        return HamiltonianSystem(
            "double_pendulum_full_circle", hamiltonian, gradient,
            domain=[[-momentum_bound, momentum_bound]] * 2 + [[-np.pi, np.pi]] * 2,
            initial_state=[0.0, 0.0, 0.0, 2.0],
            params=dict(params, momentum_bound=momentum_bound),
            periodic=[False, False, True, True],
        )
    return HamiltonianSystem(
        "double_pendulum", hamiltonian, gradient,
        domain=[[-5.0, 5.0], [-4.0, 4.0], [-1.0, 1.0], [-1.0, 1.0]],
        initial_state=[0.0, 0.0, np.pi / 6, np.pi / 4],
        paper_settings=dict(
            degree=15, n_trajectories=20000, n_intervals=2, noise=0.0, t_final=20.0
        ),
        params=params,
    )
