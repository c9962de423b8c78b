"""The five Hamiltonian systems of the paper's numerical examples, and more.

Every system is a :class:`HamiltonianSystem`: the true Hamiltonian ``H``, its
closed-form gradient, the domain ``D`` the paper samples training states from,
the paper's test initial state ``u0*``, and the paper's learning settings.
Systems beyond the paper (:data:`SCENES`) have the same parts except the
settings.
States are ordered ``u = (p_1, ..., p_d, q_1, ..., q_d)`` and evolve by
``du/dt = J^{-1} grad H(u)`` with ``J = [[0, I], [-I, 0]]``.
"""

import functools
import math
import numbers

import numpy as np

from .._integrate import RK4, integrate, raise_on_failure
from .._structure import apply_structure

#: Sampling step of the trajectory data in the examples reproducing the paper.
#: The paper does not state it; with 0.01 the O(dt**2) error of second-order
#: finite differences (about 1e-4 relative) is negligible next to the model
#: errors. All five examples use this one value.
PAPER_DT = 0.01


def _read_only(values):
    array = np.array(values, dtype=float)
    array.setflags(write=False)
    return array


def _check_periodic(periodic, domain):
    n_features = domain.shape[0]
    if periodic is None:
        periodic = np.zeros(n_features, dtype=bool)
    periodic = np.array(periodic)
    if periodic.dtype != bool or periodic.shape != (n_features,):
        raise ValueError(
            f"periodic must be a boolean array of shape ({n_features},), one flag per "
            f"state component (p before q), got dtype {periodic.dtype} and shape "
            f"{periodic.shape}."
        )
    rows = domain[periodic]
    if not np.all(np.isfinite(rows)) or np.any(rows[:, 1] <= rows[:, 0]):
        raise ValueError(
            "The domain row (low, high) of a periodic component is one full period "
            "high - low, so it must be finite with low < high; got rows "
            f"{rows.tolist()} for components {np.flatnonzero(periodic).tolist()}."
        )
    periodic.setflags(write=False)
    return periodic


class HamiltonianSystem:
    """A known Hamiltonian system ``du/dt = J^{-1} grad H(u)``, optionally damped.

    With ``damping`` ``gamma``, the momenta feel linear friction:
    ``dp/dt = -dH/dq - gamma * dH/dp`` (``dH/dp = dq/dt``), and the energy
    decreases at the rate ``sum_i gamma_i (dq_i/dt)**2``.

    Parameters
    ----------
    name : str
        Short name of the system.
    hamiltonian : callable
        ``H``, mapping an array of shape ``(..., 2 * n_dof)`` to ``(...,)``.
    gradient : callable
        ``grad H``, mapping ``(..., 2 * n_dof)`` to ``(..., 2 * n_dof)``.
    domain : array-like of shape (2 * n_dof, 2)
        One ``(low, high)`` row per state component, ``p`` before ``q``.
    initial_state : array-like of shape (2 * n_dof,)
        The test initial state ``u0*``.
    paper_settings : dict, default=None
        The paper's learning settings for this system.
    params : dict, default=None
        Physical parameters, shown in the representation.
    periodic : array-like of bool of shape (2 * n_dof,), default=None
        Which state components are angles whose ``domain`` row ``[low, high)``
        is exactly one full period ``high - low``. None marks none.
    damping : array-like of shape (n_dof,), default=None
        Friction coefficients ``gamma >= 0``, one per degree of freedom; None
        (or zeros) for a conservative system.

    Attributes
    ----------
    n_dof : int
        Number of degrees of freedom ``d``; states have ``2 * d`` components.
    domain : ndarray of shape (2 * n_dof, 2)
        Read-only copy of ``domain``.
    initial_state : ndarray of shape (2 * n_dof,)
        Read-only copy of ``initial_state``.
    paper_settings : dict
        Keys ``degree`` (``n``), ``n_trajectories`` (``M``), ``n_intervals``
        (``J``) and ``noise``, plus ``t_final`` where the paper gives one;
        empty for systems that are not in the paper.
    params : dict
        Physical parameters.
    periodic : ndarray of bool of shape (2 * n_dof,)
        Read-only; True for the angles. ``H`` is periodic in such a component
        with period ``high - low`` of its ``domain`` row, and states that
        differ by whole periods there are the same physical state. Trajectories
        from :meth:`solve` and :func:`make_trajectories` are continuous: their
        angles are not wrapped into ``[low, high)`` and may leave the domain.
    damping : ndarray of shape (n_dof,)
        Read-only friction coefficients (zeros for a conservative system).

    Examples
    --------
    >>> from sk_hamiltonian.datasets import load_system
    >>> system = load_system("henon_heiles")
    >>> system.n_dof
    2
    >>> system.vector_field([0.0, 0.0, 1.0, 0.0])
    array([-1., -1.,  0.,  0.])
    """

    def __init__(
        self, name, hamiltonian, gradient, domain, initial_state, paper_settings=None,
        params=None, *, periodic=None, damping=None,
    ):
        domain = _read_only(domain)
        if domain.ndim != 2 or domain.shape[1] != 2 or domain.shape[0] % 2:
            raise ValueError(
                f"domain must have shape (2 * n_dof, 2), got {domain.shape}."
            )
        initial_state = _read_only(initial_state)
        if initial_state.shape != (domain.shape[0],):
            raise ValueError(
                f"initial_state must have shape ({domain.shape[0]},) to match the "
                f"domain, got {initial_state.shape}."
            )
        periodic = _check_periodic(periodic, domain)
        n_dof = domain.shape[0] // 2
        damping = _read_only(np.zeros(n_dof) if damping is None else damping)
        if damping.shape != (n_dof,) or not np.all(np.isfinite(damping)) or np.any(damping < 0):
            raise ValueError(
                f"damping must hold {n_dof} finite friction coefficients >= 0, one per "
                f"degree of freedom; got {np.asarray(damping).tolist()}."
            )
        self.damping = damping
        self.name = name
        self.n_dof = domain.shape[0] // 2
        self.domain = domain
        self.initial_state = initial_state
        self.paper_settings = dict(paper_settings or {})
        self.params = dict(params or {})
        self.periodic = periodic
        self._hamiltonian = hamiltonian
        self._gradient = gradient

    def __repr__(self):
        fields = [f"name={self.name!r}", f"n_dof={self.n_dof}"]
        fields += [f"{key}={value!r}" for key, value in self.params.items()]
        return f"HamiltonianSystem({', '.join(fields)})"

    def _check_states(self, X, name="X"):
        X = np.asarray(X, dtype=float)
        if X.ndim == 0 or X.shape[-1] != 2 * self.n_dof:
            raise ValueError(
                f"{name} must have shape (..., {2 * self.n_dof}) for the {self.name} "
                f"system (p_1..p_d, q_1..q_d), got {X.shape}."
            )
        return X

    def hamiltonian(self, X):
        """Evaluate the true Hamiltonian.

        Parameters
        ----------
        X : array-like of shape (..., 2 * n_dof)
            States ``(p, q)``.

        Returns
        -------
        H : ndarray of shape (...,)
            ``H(X)``.
        """
        return self._hamiltonian(self._check_states(X))

    def gradient(self, X):
        """Evaluate the closed-form gradient of the Hamiltonian.

        Parameters
        ----------
        X : array-like of shape (..., 2 * n_dof)
            States ``(p, q)``.

        Returns
        -------
        grad : ndarray of shape (..., 2 * n_dof)
            ``(dH/dp, dH/dq)`` at ``X``.
        """
        return self._gradient(self._check_states(X))

    def vector_field(self, X):
        """Evaluate Hamilton's equations ``J^{-1} grad H`` (with the damping).

        Parameters
        ----------
        X : array-like of shape (..., 2 * n_dof)
            States ``(p, q)``.

        Returns
        -------
        dXdt : ndarray of shape (..., 2 * n_dof)
            ``(dp/dt, dq/dt) = (-dH/dq - gamma * dH/dp, dH/dp)`` at ``X``.
        """
        return self._field(self._check_states(X))

    def _field(self, X):
        return apply_structure(self._gradient(X), self.damping if self.damping.any() else None)

    def solve(self, x0, t, max_step=None, *, on_failure="raise"):
        """Reference solution by the classical Runge-Kutta method (RK4).

        Parameters
        ----------
        x0 : array-like of shape (2 * n_dof,) or (n_states, 2 * n_dof)
            Initial state(s), taken at time ``t[0]``.
        t : array-like of shape (n_times,)
            Strictly increasing output times.
        max_step : float, default=None
            Largest RK4 step. None uses a hundredth of the smallest interval
            of ``t``, fine enough that the reference error is far below any
            learning error (the paper used a ten-thousandth).
        on_failure : {"raise", "nan"}, default="raise"
            When a solution becomes non-finite (it blows up in finite time):
            raise, or fill it with NaN from the first output time it did not
            reach (the other solutions go on).

        Returns
        -------
        X : ndarray of shape (n_times, 2 * n_dof) or (n_states, n_times, 2 * n_dof)
            The solution at ``t``, with one leading axis per initial state if
            ``x0`` is 2-D. It is continuous in time: angles (see ``periodic``)
            are not wrapped into the domain.

        Raises
        ------
        SimulationError
            If a solution becomes non-finite, with ``on_failure="raise"``.

        Examples
        --------
        >>> import numpy as np
        >>> from sk_hamiltonian.datasets import load_system
        >>> system = load_system("single_pendulum")
        >>> system.solve(system.initial_state, np.linspace(0, 1, 11)).shape
        (11, 2)
        """
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.shape[0] < 1 or not np.all(np.isfinite(t)):
            raise ValueError(
                f"t must be a non-empty 1-D array of finite times, got shape {t.shape}."
            )
        if np.any(np.diff(t) <= 0):
            raise ValueError("t must be strictly increasing; sort it and drop repeats.")
        x0 = np.asarray(x0, dtype=float)
        if x0.ndim not in (1, 2) or x0.shape[-1] != 2 * self.n_dof:
            raise ValueError(
                f"x0 must have shape ({2 * self.n_dof},) or (n_states, {2 * self.n_dof}) "
                f"for the {self.name} system, got {x0.shape}."
            )
        if not np.all(np.isfinite(x0)):
            raise ValueError("x0 must be finite; it contains NaN or infinity.")
        if max_step is None:
            max_step = np.diff(t).min() / 100.0 if t.shape[0] > 1 else None
        elif not (isinstance(max_step, numbers.Real) and 0 < max_step < math.inf):
            raise ValueError(f"max_step must be a positive finite number, got {max_step!r}.")
        if on_failure not in ("raise", "nan"):
            raise ValueError(f"on_failure must be 'raise' or 'nan'; got {on_failure!r}.")
        y, failed_at = integrate(RK4(self._field), np.atleast_2d(x0), t, max_step=max_step)
        if on_failure == "raise":
            raise_on_failure(
                failed_at,
                t,
                what=f"the true {self.name} system",
                hint="Its exact solution blows up there: stop the horizon before that time.",
            )
        y = np.swapaxes(y, 0, 1)
        y[np.arange(t.shape[0])[None, :] >= failed_at[:, None]] = np.nan
        return y[0] if x0.ndim == 1 else y


def _split(X):
    d = X.shape[-1] // 2
    return X[..., :d], X[..., d:]


def _check_positive(**values):
    for name, value in values.items():
        if not (isinstance(value, numbers.Real) and 0 < value < math.inf):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}.")


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
    "double_pendulum_full_circle": functools.partial(double_pendulum, full_circle=True),
    "fput_chain": fput_chain,
    "toda_lattice": toda_lattice,
}


def load_system(name, **params):
    """Build a system by name.

    Parameters
    ----------
    name : str
        A key of :data:`SYSTEMS`, the paper's systems: ``"single_pendulum"``,
        ``"exponential"``, ``"henon_heiles"``, ``"cherry"`` or
        ``"double_pendulum"``; or of :data:`SCENES`, systems beyond the paper:
        ``"double_pendulum_full_circle"``, ``"fput_chain"`` or
        ``"toda_lattice"``.
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
