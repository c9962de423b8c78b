"""Generate the paper's training data: many short, optionally noisy trajectories."""

import math
import numbers

import numpy as np
from sklearn.utils import check_random_state

from ._system import HamiltonianSystem
from ._systems import load_system


def _check_int(value, name, minimum):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}.")
    return int(value)


def _check_domain(domain, n_features):
    domain = np.asarray(domain, dtype=float)
    if domain.shape != (n_features, 2):
        raise ValueError(
            f"domain must have shape ({n_features}, 2), one (low, high) row per "
            f"state component, got {domain.shape}."
        )
    if not np.all(np.isfinite(domain)) or np.any(domain[:, 0] >= domain[:, 1]):
        raise ValueError(
            "domain rows must be finite (low, high) pairs with low < high; swap or "
            f"widen the offending rows, got {domain.tolist()}."
        )
    return domain


def make_trajectories(
    system,
    n_trajectories,
    n_intervals,
    dt,
    noise=0.0,
    domain=None,
    random_state=None,
    return_clean=False,
):
    """Sample short trajectories of a Hamiltonian system, as in the paper.

    Initial states are drawn i.i.d. uniformly in ``domain``, each is advanced
    ``n_intervals`` steps of length ``dt`` by the reference solver
    (:meth:`HamiltonianSystem.solve`, RK4 with steps of at most ``dt / 100``,
    all trajectories at once), and every entry is then multiplied by
    ``1 + eta`` with ``eta`` i.i.d. uniform in ``[-noise, noise]``.

    Parameters
    ----------
    system : HamiltonianSystem or str
        The system, or a name accepted by :func:`load_system`.
    n_trajectories : int
        Number of trajectories ``M``, at least 1.
    n_intervals : int
        Number of time intervals ``J`` per trajectory, at least 1; each
        trajectory has ``n_intervals + 1`` states.
    dt : float
        Time between consecutive states, positive.
    noise : float, default=0.0
        Relative noise level, in ``[0, 1)``; 0 gives exact data.
    domain : array-like of shape (2 * n_dof, 2), default=None
        ``(low, high)`` bounds of the initial states, ``p`` before ``q``.
        None uses ``system.domain``.
    random_state : int, RandomState instance or None, default=None
        Seeds the initial states and the noise. Pass an int for reproducible
        output.
    return_clean : bool, default=False
        Whether to also return the noise-free trajectories.

    Returns
    -------
    X : ndarray of shape (n_trajectories, n_intervals + 1, 2 * n_dof)
        The (noisy) trajectories; ``X[i, k]`` is the state of trajectory ``i``
        at time ``k * dt``. Angles (``system.periodic``) are not wrapped: each
        trajectory is continuous and may leave ``domain``.
    X_clean : ndarray of shape (n_trajectories, n_intervals + 1, 2 * n_dof)
        The noise-free trajectories. Only returned if ``return_clean=True``.

    Raises
    ------
    SimulationError
        If the true solution from some initial state blows up within
        ``n_intervals * dt`` (possible for Cherry's system); shrink ``dt``,
        ``n_intervals`` or ``domain``.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import make_trajectories
    >>> X = make_trajectories("single_pendulum", 500, 40, dt=0.1, noise=0.08,
    ...                       random_state=0)
    >>> X.shape
    (500, 41, 2)
    """
    if isinstance(system, str):
        system = load_system(system)
    elif not isinstance(system, HamiltonianSystem):
        raise ValueError(
            "system must be a HamiltonianSystem or one of the names accepted by "
            f"load_system, got {type(system).__name__}."
        )
    n_trajectories = _check_int(n_trajectories, "n_trajectories", 1)
    n_intervals = _check_int(n_intervals, "n_intervals", 1)
    if not (isinstance(dt, numbers.Real) and 0 < dt < math.inf):
        raise ValueError(f"dt must be a positive finite number, got {dt!r}.")
    if not (isinstance(noise, numbers.Real) and 0 <= noise < 1):
        raise ValueError(
            f"noise must be a relative level in [0, 1) (e.g. 0.08 for 8%), got {noise!r}."
        )
    n_features = 2 * system.n_dof
    domain = _check_domain(system.domain if domain is None else domain, n_features)
    rng = check_random_state(random_state)

    x0 = rng.uniform(domain[:, 0], domain[:, 1], size=(n_trajectories, n_features))
    t = dt * np.arange(n_intervals + 1)
    X_clean = system.solve(x0, t)
    if noise == 0:
        X = X_clean.copy()
    else:
        X = X_clean * (1.0 + rng.uniform(-noise, noise, size=X_clean.shape))
    return (X, X_clean) if return_clean else X
