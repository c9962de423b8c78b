"""Many models of one space from one initial state each, by RK4 in one batched loop.

The refits of a resampled model (:func:`sk_hamiltonian.inspection.prediction_band`)
share a model space and differ in their coefficients: row ``r`` of the batch
is the state of model ``r``, and one evaluation of the basis at every row
serves all of them, as one simulation of many initial states serves one
model. A trajectory that becomes non-finite stops there, the others go on.
"""

import math

import numpy as np

from .._threads import limit_blas


def simulate_ensemble(field, x0, t, max_step, wrap=None):
    """RK4 trajectories of ``n_models`` models.

    Parameters
    ----------
    field : callable
        ``field(Y, models)``: the time derivatives of the states ``Y`` (one
        row per entry of ``models``) under the models ``models``.
    x0 : ndarray of shape (n_models, n_states)
        Each model's initial state, at ``t[0]``.
    t : ndarray of shape (n_times,)
        Strictly increasing output times.
    max_step : float
        Largest step; each interval of ``t`` is split into the fewest equal
        steps no longer than this.
    wrap : callable, default=None
        Wraps periodic variables into their period at each output time.

    Returns
    -------
    Y : ndarray of shape (n_models, n_times, n_states)
        NaN from the first output time a model's trajectory could not reach.
    """
    wrap = wrap or (lambda y: y)
    y = wrap(np.array(x0, dtype=float))
    out = np.full((y.shape[0], t.shape[0], y.shape[1]), np.nan)
    out[:, 0] = y
    active = np.arange(y.shape[0])
    with limit_blas(0), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for k in range(t.shape[0] - 1):
            interval = t[k + 1] - t[k]
            n_sub = max(1, math.ceil(interval / max_step - 1e-9))
            h = interval / n_sub
            y_active = y[active]

            def f(Y):
                return field(Y, active)

            for _ in range(n_sub):
                k1 = f(y_active)
                k2 = f(y_active + (0.5 * h) * k1)
                k3 = f(y_active + (0.5 * h) * k2)
                k4 = f(y_active + h * k3)
                y_active = y_active + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
            finite = np.isfinite(y_active).all(axis=1)
            active, y_active = active[finite], y_active[finite]
            if active.size == 0:
                break
            y[active] = wrap(y_active)
            out[active, k + 1] = y[active]
    return out
