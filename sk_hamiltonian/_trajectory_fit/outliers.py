"""Samples the trajectory fit leaves out: isolated and far beyond the spread of its residuals.

The search's preparation cuts records at spikes, samples far from the cubic
through their neighbours (:mod:`sk_hamiltonian._spikes`). At the first and
last samples of a record that cubic extrapolates from one side, with weights
that multiply the noise about eightfold, so a reading moved by tens of noise
levels there passes for noise. The fitted trajectories pass close to its
neighbours whichever side they are on: against them such a sample stands
out, and a few of them (squared, each weighs as hundreds of good samples)
pull the coefficients and inflate the noise model that weighs the next fit.

:func:`isolated_outliers` marks a sample when, in some variable, its
weighted residual exceeds :data:`OUTLIER_SDS` times that variable's spread
(the scaled median absolute residual over all the samples, which a few
outliers do not move) and :data:`ISOLATION` times each neighbour's, and its
residual itself exceeds :data:`OUTLIER_SDS` times the spread of the
residuals themselves and a :data:`FLOOR` fraction of the variable's scale
(round-off of exact data). The weights alone would not do: under relative
noise a state near zero has a weight near its reciprocal, and there the
fit's own small error stands tens of spreads out (by the weights alone, at
eight spreads, 12 samples of the pendulum at 20 % relative noise, seed 0 of
the robustness study's data). A
model that is wrong somewhere is wrong smoothly along a trajectory, its
neighbours' residuals as large: isolation keeps its misfit in the fit. At
most :data:`MAX_FRACTION` of a trajectory's samples that count are left out
at once.

Measured on the robustness study's pendulum at 2 % noise (500 x 41, ``dt = 0.01``,
``benchmarks/moved_readings.py``): see ``docs/robustness.rst``.
"""

import numpy as np

from .._outliers import MAD_TO_STD, listed
from .._warnings import warn
from ..exceptions import OutlierWarning

# A sample is left out beyond this many spreads of the residuals ...
OUTLIER_SDS = 10.0
# ... standing this many times above each neighbour's residual ...
ISOLATION = 3.0
# ... and above this fraction of the variable's scale.
FLOOR = 1e-6
# Never more than this fraction of a trajectory's samples.
MAX_FRACTION = 0.2


def isolated_outliers(residuals, weighted, masks, scale):
    """Samples whose residual stands alone far above the rest.

    Parameters
    ----------
    residuals : list of ndarray of shape (n_k, n_times_k, n_states)
        Observations less the fitted trajectories, one array per group.
    weighted : list of ndarray
        The same in units of the fit's weights.
    masks : list of ndarray of bool of shape (n_k, n_times_k)
        The samples that count now.
    scale : ndarray of shape (n_states,)
        Each variable's scale (root mean square of the observations).

    Returns
    -------
    outliers : list of ndarray of bool of shape (n_k, n_times_k)
        The samples to leave out, among those that count.
    """
    size = [np.abs(z) for z in weighted]
    spread = MAD_TO_STD * np.median(np.concatenate([s[m] for s, m in zip(size, masks)]), axis=0)
    raw = MAD_TO_STD * np.median(np.concatenate([np.abs(r[m]) for r, m in zip(residuals, masks)]),
                                 axis=0)
    floor = np.maximum(OUTLIER_SDS * raw, FLOOR * scale)
    out = []
    for r, s, mask in zip(residuals, size, masks):
        s = np.where(mask[..., None], s, 0.0)
        neighbours = np.zeros_like(s)
        neighbours[:, 1:] = s[:, :-1]
        neighbours[:, :-1] = np.maximum(neighbours[:, :-1], s[:, 1:])
        far = ((s > OUTLIER_SDS * spread) & (s > ISOLATION * neighbours)
               & (np.abs(r) > floor)).any(axis=2) & mask
        # A trajectory where many samples stand out is one the model misses.
        far[far.sum(axis=1) > MAX_FRACTION * mask.sum(axis=1)] = False
        out.append(far)
    return out


def warn_left_out(who, left_out, where=None):
    """An :class:`~sk_hamiltonian.OutlierWarning` naming the samples the fit left out.

    Parameters
    ----------
    who : str
        The estimator's name, first in the message.
    left_out : dict
        Trajectory (numbered as in the user's ``X``) to sample indices.
    where : str, default=None
        The attribute that lists them; None: the message lists them (the
        first ten trajectories).
    """
    n = sum(len(v) for v in left_out.values())
    shown = dict(list(left_out.items())[:10])
    listing = (f"{where} lists them" if where is not None else
               f"By trajectory: {shown}" + (" and more" if len(shown) < len(left_out) else ""))
    warn(
        OutlierWarning(
            f"{who}: the trajectory fit left out {n} sample{'' if n == 1 else 's'} of "
            f"trajectories {listed(left_out)} (numbered as in X), each alone beyond "
            f"{OUTLIER_SDS:g} times the spread of its residuals: readings moved far off, most "
            f"often at a record's first or last samples, where a spike screen cannot tell them "
            f"from noise. {listing}.",
            trajectories=list(left_out),
        ),
        OutlierWarning,
    )
