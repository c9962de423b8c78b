"""A known Hamiltonian system: its ``H``, closed-form gradient, domain and reference solver.

Every system of :mod:`sk_hamiltonian.datasets` is a :class:`HamiltonianSystem`:
the true Hamiltonian ``H``, its closed-form gradient, the domain ``D`` the
training states are sampled from, a test initial state ``u0*`` and, for the
paper's systems, the paper's learning settings. States are ordered ``u =
(p_1, ..., p_d, q_1, ..., q_d)`` and evolve by ``du/dt = J^{-1} grad H(u)``
with ``J = [[0, I], [-I, 0]]``.
"""

import math
import numbers

import numpy as np

from .._integrate import RK4, integrate, raise_on_failure
from .._integrate.simulation import as_numbers
from .._structure import apply_structure


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
        t = as_numbers(t, "t", "a 1-D array of numbers, the output times")
        if t.ndim != 1 or t.shape[0] < 1 or not np.all(np.isfinite(t)):
            raise ValueError(
                f"t must be a non-empty 1-D array of finite times, got shape {t.shape}."
            )
        if np.any(np.diff(t) <= 0):
            raise ValueError("t must be strictly increasing; sort it and drop repeats.")
        x0 = as_numbers(
            x0, "x0", f"numbers: one initial state of {2 * self.n_dof} values (p_1..p_d, "
            f"q_1..q_d), or several as the rows of an array of shape (n_states, {2 * self.n_dof})")
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
