"""Does the learned energy stay constant along the training trajectories?

A conservative model can only be as good as the data are conservative. After
a fit, ``H~`` is evaluated along every training trajectory and a common linear
trend in time is estimated (one intercept per trajectory, one slope for all):
its size relative to the spread of ``H~`` over the data, and its z-score. Only
the states enter, never the estimated derivatives, so a bias of the
derivative estimate cannot fake or hide a trend.

The spread is taken over the states and over the same states with their
variables decorrelated (:func:`decorrelated`): along one long trajectory of
a conservative system ``H~`` barely varies, and a round-off trend would
otherwise count as a large fraction of a round-off spread.
"""

import numpy as np


def decorrelated(states):
    """The states with each variable's column rotated by a different offset.

    Keeps every variable's values (the data's box) but breaks the relations
    between them that a conserved energy imposes, deterministically.
    """
    n, m = states.shape
    return np.column_stack([np.roll(states[:, i], (i * n) // m) for i in range(m)])


def energy_trend(energies, spread=None):
    """Common trend of ``H~`` in time along several trajectories.

    Parameters
    ----------
    energies : list of (ndarray, ndarray)
        ``(times, H~ along the trajectory)`` per trajectory.
    spread : float, default=None
        The energy scale of the data the slope is divided by; None: the
        standard deviation of ``H~`` over all the states.

    Returns
    -------
    rate : float
        Slope of ``H~`` in time divided by ``spread``: the fraction of the
        energy's spread gained per unit time (negative: lost). NaN when no
        trajectory has two samples.
    z : float
        The slope over its standard error; NaN as ``rate``.
    """
    pairs = [(t, H) for t, H in energies if t.shape[0] >= 2]
    if not pairs:
        return float("nan"), float("nan")
    # All trajectories at once (thousands of short ones are common): centre
    # each on its own means through group sums.
    lengths = np.array([t.shape[0] for t, _ in pairs])
    group = np.repeat(np.arange(lengths.size), lengths)
    times = np.concatenate([t for t, _ in pairs])
    values = np.concatenate([H for _, H in pairs])
    tc = times - (np.bincount(group, times) / lengths)[group]
    hc = values - (np.bincount(group, values) / lengths)[group]
    # Sums, not BLAS dot products: a multi-threaded ddot of this size waits
    # for a second core on a busy machine (measured: 0.5 s against 0.04 s over
    # the default sk-hamiltonian run beside a CPU-bound process).
    tt, th = float(np.sum(tc * tc)), float(np.sum(tc * hc))
    spread = np.std(values) if spread is None else spread
    if tt == 0 or spread == 0:
        return float("nan"), float("nan")
    slope = th / tt
    residual = float(np.sum((hc - slope * tc) ** 2))
    dof = values.size - lengths.size - 1
    if dof < 1:
        return float(slope / spread), float("nan")
    stderr = np.sqrt(residual / dof / tt)
    z = slope / stderr if stderr > 0 else np.copysign(np.inf, slope) if slope else 0.0
    return float(slope / spread), float(z)
