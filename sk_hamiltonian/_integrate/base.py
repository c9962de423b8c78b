"""Base class and driver shared by the fixed-step integrators."""

import math

import numpy as np

from ..exceptions import SimulationError


class FixedStepIntegrator:
    """Base class of the fixed-step integrators of ``dy/dt = f(y)``.

    Integrators work on a batch of states of shape ``(n_states, n_features)``
    at once. Subclasses implement :meth:`_step_impl`; callers use :meth:`step`.

    Parameters
    ----------
    fun : callable
        Right-hand side ``f``, mapping an array of shape ``(n, n_features)`` to an
        array of the same shape.
    """

    #: Whether the method conserves a first integral exactly (set by subclasses).
    conserves_energy = False

    def __init__(self, fun):
        self.fun = fun

    def step(self, y, h):
        """Advance a batch of states by one step.

        Parameters
        ----------
        y : ndarray of shape (n_states, n_features)
            Current states.
        h : float
            Step size.

        Returns
        -------
        y_new : ndarray of shape (n_states, n_features)
            States after one step. Rows that could not be advanced (an implicit
            solve that did not converge) are NaN, which :func:`integrate`
            reports as a failure of that trajectory.
        """
        return self._step_impl(np.asarray(y, dtype=float), float(h))

    def _step_impl(self, y, h):
        raise NotImplementedError


def integrate(integrator, y0, t, max_step=None):
    """Integrate a batch of initial states and sample the solutions at ``t``.

    Each interval ``[t[k], t[k + 1]]`` is split into the fewest equal steps no
    longer than ``max_step``. A trajectory whose state becomes non-finite is
    frozen at its last finite state and reported in ``failed_at``; the others go on.

    Parameters
    ----------
    integrator : FixedStepIntegrator
        The stepping method.
    y0 : ndarray of shape (n_states, n_features)
        Initial states, taken at time ``t[0]``.
    t : ndarray of shape (n_times,)
        Strictly increasing output times.
    max_step : float or None
        Largest step; None steps from one output time to the next.

    Returns
    -------
    y : ndarray of shape (n_times, n_states, n_features)
        Solutions at ``t``; for a failed trajectory, the values from its
        failure on repeat its last finite state.
    failed_at : ndarray of shape (n_states,)
        For each trajectory, the index into ``t`` of the first output time it
        could not reach, or ``n_times`` if it reached them all.
    """
    y = np.array(y0, dtype=float)
    n_times = t.shape[0]
    out = np.empty((n_times,) + y.shape)
    out[0] = y
    failed_at = np.full(y.shape[0], n_times, dtype=np.intp)
    active = np.arange(y.shape[0])
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for k in range(n_times - 1):
            interval = t[k + 1] - t[k]
            n_sub = 1 if max_step is None else max(1, math.ceil(interval / max_step - 1e-9))
            h = interval / n_sub
            y_active = y[active]
            for _ in range(n_sub):
                y_active = integrator.step(y_active, h)
            finite = np.isfinite(y_active).all(axis=1)
            if not finite.all():
                failed_at[active[~finite]] = k + 1
                active, y_active = active[finite], y_active[finite]
            y[active] = y_active
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
