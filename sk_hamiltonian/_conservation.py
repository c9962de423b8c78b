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

The z-score's standard error is cluster-robust: the deviations of ``H~``
from the trend along one trajectory are correlated (its error is a smooth
function of the state, and de-noised states are smooth in time), so the
samples of a trajectory are not independent, but different trajectories
are. The standard error treats each trajectory as one unit; with fewer than
:data:`MIN_CLUSTERS` trajectories, contiguous stretches of them, each with
its own mean, so that there are about that many units. The t statistic
with ``units - 1`` degrees of freedom is reported as the normal z-score of
the same tail probability. The naive standard error, which counts every
sample as independent, was 4 to 5 times smaller on the noisy pendulum (100
trajectories of 41 samples) and made a trend "significant" in 5 of 20
conservative data sets. On simulated conservative energies with AR(1)
noise along each trajectory (correlation 0.9 to 0.99 between samples), the
z-score has a standard deviation of 0.6 to 1.0 (below 1 where the
correlation outlasts a stretch), where the naive one spread five times
wider.

A trend *counts* (:func:`trend_verdict`) only when it is both significant,
``|z| >`` :data:`TREND_Z`, and large, more than :data:`TREND_SIZE` of the
spread of ``H~`` per period of the learned system (``2 pi time_scale_``):
on noise-free data the model's own small error gives trends that are
significant but far too small to matter.
"""

import numpy as np
from scipy import stats

# A trend counts when its cluster-robust z-score exceeds this in size ...
TREND_Z = 4.0
# ... and H~ changes by more than this fraction of its spread per period of
# the learned system (2 pi time_scale_). Measured on the pendulum
# (DerivativeTransformer(dt=0.01, degree=3), HamiltonianRegressor(degree=8),
# 100 trajectories of 40 steps of 0.01, seeds 0-19; docs/measurements.rst):
# relative noise 0.08, |z| <= 2.6 (over seeds 0-59 too) with changes up to
# 0.074 per period; noise-free, z from -3.5 to -0.8 (the de-noising's own
# bias); damped_pendulum(0.1) with noise 0.08, z from -6.2 to -2.3, 17 of
# 20 beyond -4, with changes of 0.06 to 0.24 per period.
TREND_SIZE = 0.02
# Fewer trajectories than this are cut into contiguous stretches for the
# standard error, so that it rests on about this many units.
MIN_CLUSTERS = 20


def decorrelated(states):
    """The states with each variable's column rotated by a different offset.

    Keeps every variable's values (the data's box) but breaks the relations
    between them that a conserved energy imposes, deterministically.
    """
    n, m = states.shape
    return np.column_stack([np.roll(states[:, i], (i * n) // m) for i in range(m)])


def _clusters(lengths):
    """Unit of every sample: its trajectory, or (with few trajectories) a stretch of it."""
    if lengths.size >= MIN_CLUSTERS:
        return np.repeat(np.arange(lengths.size), lengths)
    total = lengths.sum()
    units, first = [], 0
    for n in lengths:
        # Stretches in proportion to the trajectory's share of the samples,
        # at least two samples each.
        k = int(max(1, min(n // 2, round(MIN_CLUSTERS * n / total))))
        units.append(first + (np.arange(n) * k) // n)
        first += k
    return np.concatenate(units)


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
        The slope over its cluster-robust standard error (see the module
        docstring); NaN as ``rate``, or when the data make a single unit.
    """
    pairs = [(t, H) for t, H in energies if t.shape[0] >= 2]
    if not pairs:
        return float("nan"), float("nan")
    # All trajectories at once (thousands of short ones are common): centre
    # each unit (a trajectory, or a stretch of one) on its own means through
    # group sums.
    lengths = np.array([t.shape[0] for t, _ in pairs])
    unit = _clusters(lengths)
    sizes = np.bincount(unit)
    times = np.concatenate([t for t, _ in pairs])
    values = np.concatenate([H for _, H in pairs])
    tc = times - (np.bincount(unit, times) / sizes)[unit]
    hc = values - (np.bincount(unit, values) / sizes)[unit]
    # Sums, not BLAS dot products: a multi-threaded ddot of this size waits
    # for a second core on a busy machine (measured: 0.5 s against 0.04 s over
    # the default sk-hamiltonian run beside a CPU-bound process).
    tt, th = float(np.sum(tc * tc)), float(np.sum(tc * hc))
    spread = np.std(values) if spread is None else spread
    if tt == 0 or spread == 0:
        return float("nan"), float("nan")
    slope = th / tt
    # The slope's estimating equation sum_i tc_i (hc_i - slope tc_i) = 0,
    # summed by unit: the sandwich variance with a small-sample factor.
    scores = np.bincount(unit, tc * (hc - slope * tc))
    n_units = scores.size
    if n_units < 2:
        return float(slope / spread), float("nan")
    stderr = np.sqrt(float(np.sum(scores * scores)) * n_units / (n_units - 1)) / tt
    if stderr == 0:
        return float(slope / spread), float(np.copysign(np.inf, slope) if slope else 0.0)
    # Student's t with n_units - 1 degrees of freedom, as the normal z-score
    # of the same tail probability (few units have heavier tails).
    t_stat = slope / stderr
    z = np.copysign(stats.norm.isf(stats.t.sf(abs(t_stat), n_units - 1)), t_stat)
    return float(slope / spread), float(z)


def trend_verdict(rate, z, time_scale):
    """Whether a trend counts: ``"loses"``, ``"gains"`` or None, and its change per period.

    Parameters
    ----------
    rate, z : float
        From :func:`energy_trend` (``energy_trend_``, ``energy_trend_z_``).
    time_scale : float
        The learned system's ``time_scale_``; ``2 pi time_scale`` is its
        period.

    Returns
    -------
    verdict : {"loses", "gains"} or None
        ``"loses"``/``"gains"`` when ``|z| >`` :data:`TREND_Z` and the change
        per period exceeds :data:`TREND_SIZE`; None otherwise (also when the
        trend is not available).
    change : float
        ``|rate| * 2 pi time_scale``: the fraction of the spread of ``H~``
        gained or lost per period (NaN when not available; infinite for a
        system that does not move).
    period : float
        ``2 pi time_scale``.
    """
    period = 2 * np.pi * time_scale
    if not (np.isfinite(rate) and np.isfinite(z)):
        return None, float("nan"), period
    change = abs(rate) * period if rate else 0.0
    if np.isnan(change):  # a period that could not be measured: z alone decides
        change = np.inf
    if abs(z) > TREND_Z and change > TREND_SIZE:
        return ("loses" if rate < 0 else "gains"), float(change), period
    return None, float(change), period


def conservation_message(verdict, change, period, z):
    """The :class:`~sk_hamiltonian.ConservationWarning` of a conservative model whose energy trends.

    A loss and a gain call for different remedies: friction can only remove
    energy, so ``damping=True`` is suggested for a loss alone.
    """
    size = (
        f"{change:.1%} of its spread per period of the learned system ({period:.3g} time units)"
        if np.isfinite(change) else "a significant share of its spread"
    )
    if verdict == "loses":
        cause = (
            "Either the data are dissipative (friction: consider damping=True), or the "
            "model does not fit them well where the trajectories go (consider a larger "
            "degree or a larger space)."
        )
    else:
        cause = (
            "Either the data are driven (an external force or a time-dependent term feeds "
            "energy in, which no autonomous Hamiltonian, damped or not, can follow), or the "
            "model misses a force or a term of the dynamics, or fits poorly where the "
            "trajectories go (consider a larger degree or a larger space). Damping would "
            "only remove energy."
        )
    return (
        f"HamiltonianRegressor: the learned energy H~ {verdict} {size} along the training "
        f"trajectories (trend z-score {z:.1f}), but the model conserves it. {cause}"
    )
