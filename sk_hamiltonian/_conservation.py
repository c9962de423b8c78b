"""Does the learned energy stay constant along the training trajectories?

A conservative model can only be as good as the data are conservative. After
a fit, ``H~`` is evaluated along every training trajectory and a common linear
trend in time is estimated (one intercept per trajectory, one slope for all):
its size relative to the spread of ``H~`` over the data, and its z-score. Only
the states enter, never the estimated derivatives, so a bias of the
derivative estimate cannot fake or hide a trend.
"""

import numpy as np


def energy_trend(energies):
    """Common trend of ``H~`` in time along several trajectories.

    Parameters
    ----------
    energies : list of (ndarray, ndarray)
        ``(times, H~ along the trajectory)`` per trajectory.

    Returns
    -------
    rate : float
        Slope of ``H~`` in time divided by the standard deviation of ``H~``
        over all the states: the fraction of the energy's spread gained per
        unit time (negative: lost). NaN when no trajectory has two samples.
    z : float
        The slope over its standard error; NaN as ``rate``.
    """
    tt, th, hh = 0.0, 0.0, []
    centred = []
    for t, H in energies:
        if t.shape[0] < 2:
            continue
        tc, hc = t - t.mean(), H - H.mean()
        tt += tc @ tc
        th += tc @ hc
        centred.append((tc, hc))
        hh.append(H)
    spread = np.std(np.concatenate(hh)) if hh else 0.0
    if not centred or tt == 0 or spread == 0:
        return float("nan"), float("nan")
    slope = th / tt
    residual = sum(float(np.sum((hc - slope * tc) ** 2)) for tc, hc in centred)
    dof = sum(tc.shape[0] for tc, _ in centred) - len(centred) - 1
    if dof < 1:
        return float(slope / spread), float("nan")
    stderr = np.sqrt(residual / dof / tt)
    z = slope / stderr if stderr > 0 else np.copysign(np.inf, slope) if slope else 0.0
    return float(slope / spread), float(z)
