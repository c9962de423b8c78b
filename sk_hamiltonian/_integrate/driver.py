"""Running an integrator: the registry of methods, and the driver of a whole run.

:func:`integrate` is where a simulation chooses its path: the steps of the
integrator in numpy, or the whole run as one compiled loop
(:mod:`.compiled`) where the configuration allows numba
(:func:`~sk_hamiltonian._config.use_numba`) and the model offers it.
"""

import math

import numpy as np

from .._config import use_numba
from ..exceptions import SimulationError
from .avf import AveragedVectorField
from .compiled import integrate_compiled
from .rk4 import RK4
from .symplectic import Leapfrog, Yoshida4

METHODS = {cls.name: cls for cls in (RK4, AveragedVectorField, Leapfrog, Yoshida4)}


def make_integrator(method, dynamics):
    """The integrator named ``method`` for a model, or a ValueError naming the choices."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {sorted(METHODS)}; got {method!r}.")
    return METHODS[method](dynamics)


def integrate(integrator, y0, t, max_step=None):
    """Integrate a batch of initial states and sample the solutions at ``t``.

    Each interval ``[t[k], t[k + 1]]`` is split into the fewest equal steps no
    longer than ``max_step``. A trajectory whose state becomes non-finite is
    frozen at its last finite state and reported in ``failed_at``; the others
    go on. Periodic variables are wrapped at every output time if the model
    says how (``Dynamics.wrap``).

    Parameters
    ----------
    integrator : FixedStepIntegrator
        The stepping method.
    y0 : ndarray of shape (n_states, n_features)
        Initial states, taken at time ``t[0]``.
    t : ndarray of shape (n_times,)
        Strictly increasing output times.
    max_step : float or None
        Largest step; None (or infinity) steps from one output time to the next.

    Returns
    -------
    y : ndarray of shape (n_times, n_states, n_features)
        Solutions at ``t``; for a failed trajectory, the values from its
        failure on repeat its last finite state.
    failed_at : ndarray of shape (n_states,)
        For each trajectory, the index into ``t`` of the first output time it
        could not reach, or ``n_times`` if it reached them all.
    """
    if getattr(integrator.dynamics, "compiled", None) is not None and use_numba():
        result = integrate_compiled(integrator, y0, t, max_step)
        if result is not None:
            return result
    wrap = integrator.dynamics.wrap or (lambda y: y)
    y = wrap(np.array(y0, dtype=float))
    n_times = t.shape[0]
    out = np.empty((n_times,) + y.shape)
    out[0] = y
    failed_at = np.full(y.shape[0], n_times, dtype=np.intp)
    active = np.arange(y.shape[0])
    substeps = max_step is not None and math.isfinite(max_step)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for k in range(n_times - 1):
            interval = t[k + 1] - t[k]
            n_sub = max(1, math.ceil(interval / max_step - 1e-9)) if substeps else 1
            h = interval / n_sub
            y_active = y[active]
            for _ in range(n_sub):
                y_active = integrator.step(y_active, h)
            finite = np.isfinite(y_active).all(axis=1)
            if not finite.all():
                failed_at[active[~finite]] = k + 1
                active, y_active = active[finite], y_active[finite]
            y[active] = wrap(y_active)
            out[k + 1] = y
            if active.size == 0:
                out[k + 2 :] = y
                break
    return out, failed_at


LEARNED_MODEL_HINT = (
    "The trajectory probably left the domain where the model is valid; use a "
    "shorter horizon, a smaller step (max_step), or initial states inside the "
    "training domain."
)


def raise_on_failure(failed_at, t, what="the learned system", hint=LEARNED_MODEL_HINT):
    """Raise :class:`SimulationError` if any trajectory of :func:`integrate` failed.

    Parameters
    ----------
    failed_at : ndarray of shape (n_states,)
        As returned by :func:`integrate`.
    t : ndarray of shape (n_times,)
        The output times given to :func:`integrate`.
    what : str
        What was simulated, for the message.
    hint : str
        How to avoid the failure, for the message.
    """
    n_failed = int(np.sum(failed_at < t.shape[0]))
    if n_failed:
        first = int(failed_at.min())
        raise SimulationError(
            f"Simulating {what} failed for {n_failed} of {failed_at.shape[0]} initial "
            f"state(s): the state became non-finite, or an implicit step did not "
            f"converge, between t={t[first - 1]:.6g} and t={t[first]:.6g}. {hint}",
            t_reached=float(t[first - 1]),
            t_failed=float(t[first]),
            failed_at=failed_at.copy(),
        )
