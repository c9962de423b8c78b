"""What a fitted model's ``simulate`` delegates: its checks, its defaults and the run.

The regressors' ``simulate`` validates its arguments with the checks here,
asks for the integrator and step a fit implies (:func:`default_method`,
:func:`default_step`, from the learned system's time scale
:func:`time_scale`), and hands the run to :func:`run`.
"""

import math
from numbers import Real

import numpy as np

from .._memory import SizeLimitError, bytes_text, describe_limit, memory_limit
from .._numba import numba_available
from .._threads import limit_blas
from .._warnings import warn
from .driver import integrate, raise_on_failure

# Default integration step as a fraction of the learned system's time scale
# 1 / rho (rho: spectral radius of its Jacobian over the training states):
# the global error of RK4 then stays near (0.1)**4 / 120 per unit of rho * t,
# that of the second-order methods near (0.02)**2 / 12.
STEP_FRACTION = {"rk4": 0.1, "yoshida4": 0.1, "avf": 0.02, "leapfrog": 0.02}
# Training states at which the Jacobian is evaluated for the time scale.
TIME_SCALE_SAMPLES = 256
# Most integration steps one simulate call takes per initial state: a few
# seconds with the compiled kernels on a small model, up to about twenty
# minutes with numpy (measured: 136 us an RK4 step of the pendulum's
# degree-6 model, one initial state, on a busy shared machine).
# Far beyond the horizons the models are trusted for, it refuses accidents
# such as t = [0, 1e12] or max_step=1e-12, which would run for days.
MAX_STEPS = 10**7
# Most AVF steps per initial state a simulate call takes without numba before
# it warns. Without the compiled loop each AVF step solves its implicit
# equation in numpy: 3-10 ms a step on models of two or three terms
# (measured on a busy shared machine), 3-12 times an RK4 step (docs/scaling.rst
# records 2.4-5.9 on the pendulum's degree-6 model). Below ten thousand steps
# the run ends within seconds to half a minute (the README's first example
# takes 4 000, and must run clean under -W error); beyond, it takes minutes,
# and the remedy (the ``fast`` extra) is worth a word.
SLOW_AVF_STEPS = 10_000
#: The remedy the warning names (the command-line tool looks for it too).
FAST_EXTRA = 'pip install "sk_hamiltonian[fast]"'
# Copies of the output a simulation holds at its peak (the integrator's
# array, the finished trajectories, the states checked against the domain).
OUTPUT_COPIES = 3


def as_numbers(value, name, expected):
    """``value`` as a float array, or a ValueError naming ``name`` and what it should be.

    NumPy's own errors ("could not convert string to float: 'a'", "setting
    an array element with a sequence") name neither the argument nor the
    shape it needs.
    """
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        shown = repr(value)
        shown = shown if len(shown) <= 60 else shown[:57] + "..."
        raise ValueError(f"{name} must be {expected}; got {shown}.") from None


def check_time(t):
    """Validate output times: 1-D, finite, strictly increasing."""
    t = as_numbers(t, "t", "a 1-D array of numbers, the output times")
    if t.ndim != 1 or t.size < 1:
        raise ValueError(f"t must be a non-empty 1-D array of times; got shape {t.shape}.")
    if not np.isfinite(t).all():
        raise ValueError("t contains NaN or infinity.")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing.")
    return t


def check_initial_states(x0, n_features):
    """``x0`` as a 2-D float array of finite initial states, and whether it was one state."""
    x0 = as_numbers(
        x0, "x0", f"numbers: one initial state of {n_features} values (p_1..p_d, q_1..q_d), "
        f"or several as the rows of an array of shape (n_initial, {n_features})")
    single = x0.ndim == 1
    x0 = np.atleast_2d(x0)
    if x0.ndim != 2 or x0.shape[1] != n_features:
        raise ValueError(
            f"x0 must have shape ({n_features},) or (n_initial, "
            f"{n_features}); got {np.shape(x0)}."
        )
    if not np.isfinite(x0).all():
        raise ValueError("x0 contains NaN or infinity.")
    return x0, single


def check_max_step(max_step):
    """Raise unless ``max_step`` is None, positive, or ``numpy.inf``."""
    if max_step is not None and not (
        isinstance(max_step, Real) and not isinstance(max_step, bool) and max_step > 0
    ):
        raise ValueError(
            f"max_step must be a positive number, numpy.inf, or None; got {max_step!r}."
        )


def check_outputs(n_times, n_initial, n_states, what="t"):
    """Refuse a simulation whose output would exceed the memory limit (before it is allocated).

    Parameters
    ----------
    n_times, n_initial, n_states : int or float
        Output times (a float, possibly infinite, before they are built),
        initial states and state variables.
    what : str, default="t"
        What sets the output times, for the message.

    Raises
    ------
    ValueError
        (:class:`~sk_hamiltonian._memory.SizeLimitError`) naming the sizes.
    """
    need = OUTPUT_COPIES * 8.0 * n_times * n_initial * n_states
    if need > memory_limit():
        raise SizeLimitError(
            f"{what} asks for {n_times:,.0f} output times of {n_states} variables from "
            f"{n_initial:,} initial state(s): about {bytes_text(need)}, beyond "
            f"{describe_limit()}. Ask "
            f"for fewer output times (a coarser or shorter t), or simulate in pieces."
        )


def count_steps(t, max_step):
    """Integration steps per initial state over ``t`` with ``max_step`` (as :func:`integrate` splits them)."""
    if max_step is None or not math.isfinite(max_step):
        return float(t.shape[0] - 1)
    with np.errstate(over="ignore"):
        return float(np.sum(np.maximum(1.0, np.ceil(np.diff(t) / max_step - 1e-9))))


def check_steps(t, max_step, default=None):
    """Refuse more than :data:`MAX_STEPS` integration steps per initial state.

    Parameters
    ----------
    t : ndarray of shape (n_times,)
        Output times (checked).
    max_step : float
        The step taken.
    default : str, default=None
        How ``max_step`` was chosen when the caller did not give it, for
        the message.

    Raises
    ------
    ValueError
        (:class:`~sk_hamiltonian._memory.SizeLimitError`) naming ``t``,
        ``max_step`` and the count.
    """
    n_steps = count_steps(t, max_step)
    if n_steps <= MAX_STEPS:
        return
    given = f"max_step={max_step:.3g}" + (f" ({default})" if default else "")
    raise SizeLimitError(
        f"t runs from {t[0]:.6g} to {t[-1]:.6g} ({t.shape[0]:,} output times); with "
        f"{given} that is {n_steps:.3g} integration steps per initial state, beyond the limit "
        f"of {MAX_STEPS:.0e}. Shorten t, pass a larger max_step (numpy.inf steps from one "
        f"output time to the next), or simulate in pieces (each from the last state of the "
        f"one before)."
    )


def warn_slow_avf(method, t, max_step):
    """Warn once when an AVF run of more than :data:`SLOW_AVF_STEPS` steps runs without numba.

    The warning names the user's line (the package's ``_warnings.warn``),
    whichever public ``simulate`` (the regressor's, a search's) was called.

    Parameters
    ----------
    method : str
        The integrator's name; only ``"avf"`` can warn.
    t : ndarray of shape (n_times,)
        Output times (checked).
    max_step : float
        The step taken.
    """
    if method != "avf" or numba_available():
        return
    n_steps = count_steps(t, max_step)
    if n_steps <= SLOW_AVF_STEPS:
        return
    warn(
        f"method='avf' takes {n_steps:,.0f} integration steps per initial state here, and "
        f"numba is not installed: without it each AVF step solves its implicit equation in "
        f"numpy, several times (3-12x measured) the cost of an RK4 step, about 3-10 ms a step "
        f"even for a model of a few terms. Installing the fast extra, {FAST_EXTRA}, runs the "
        f"whole simulation compiled and removes that cost; or pass a larger max_step, or "
        f"method='rk4' where exact conservation of the learned energy is not needed.",
        UserWarning,
    )


def check_on_failure(on_failure):
    """Raise unless ``on_failure`` is ``"raise"`` or ``"nan"``."""
    if on_failure not in ("raise", "nan"):
        raise ValueError(f"on_failure must be 'raise' or 'nan'; got {on_failure!r}.")


def default_method(fit_on):
    """The integrator a model fitted on ``fit_on`` is simulated with by default."""
    # A fit on steps learns the averaged-vector-field map at the data step.
    return "avf" if fit_on == "steps" else "rk4"


def default_step(method, *, describes_flow, dt, time_scale):
    """The step ``simulate`` takes when ``max_step`` is None.

    The training step ``dt`` for the AVF method of a model whose coefficients
    describe the AVF map at that step (``describes_flow=False``: fitted on
    steps, and not refined on the trajectories since), else
    :data:`STEP_FRACTION` of the learned system's ``time_scale``
    (``describes_flow=True``: they describe the flow).
    """
    if not describes_flow and method == "avf" and np.isfinite(dt):
        return dt
    return STEP_FRACTION[method] * time_scale


def time_scale(jacobian, states):
    """``1 / rho``, rho the 90th percentile of the Jacobian's spectral radius over ``states``.

    Parameters
    ----------
    jacobian : callable
        ``jacobian(X)``: the learned field's Jacobians at the rows of ``X``,
        or None where the model has none.
    states : ndarray of shape (n_samples, n_states)
        Training states; at most about :data:`TIME_SCALE_SAMPLES` of them,
        evenly strided, are used.

    Returns
    -------
    time_scale : float
        NaN without a Jacobian, infinity for a system that does not move.
    """
    J = jacobian(states[:: max(1, states.shape[0] // TIME_SCALE_SAMPLES)])
    if J is None:
        return float("nan")
    J = J[np.isfinite(J).all(axis=(1, 2))]
    with np.errstate(all="ignore"):
        radius = np.abs(np.linalg.eigvals(J)).max(axis=1)
    radius = radius[np.isfinite(radius)]
    rho = float(np.percentile(radius, 90)) if radius.size else 0.0
    return 1.0 / rho if rho > 0 else float("inf")


def run(integrator, x0, t, max_step, on_failure, what):
    """Integrate ``x0`` over ``t``: the trajectories, NaN from where each failed.

    Parameters
    ----------
    integrator : FixedStepIntegrator
        The method, bound to the model.
    x0 : ndarray of shape (n_initial, n_states)
        Initial states (checked).
    t : ndarray of shape (n_times,)
        Output times (checked).
    max_step : float
        Largest step.
    on_failure : {"raise", "nan"}
        ``"raise"`` a :class:`~sk_hamiltonian.SimulationError` naming
        ``what`` if a trajectory fails.
    what : str
        What is simulated, for the error message.

    Returns
    -------
    Y : ndarray of shape (n_initial, n_times, n_states)
    reached : ndarray of shape (n_initial, n_times) of bool
        The output times each trajectory reached (False where ``Y`` is NaN).
    """
    # Many small products: one BLAS thread.
    with limit_blas(0):
        Y, failed_at = integrate(integrator, x0, t, max_step)
    if on_failure == "raise":
        raise_on_failure(failed_at, t, what=what)
    Y = np.swapaxes(Y, 0, 1)
    reached = np.arange(t.shape[0])[None, :] < failed_at[:, None]
    Y[~reached] = np.nan
    return Y, reached
