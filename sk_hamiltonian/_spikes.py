"""Spikes in recorded trajectories: samples far from the cubic through their neighbours.

A dropped sensor reading (a sample at 1e6, or one moved far off) shapes a
least-squares law everywhere and makes every box wrong. :func:`find_spikes`
marks such samples without a model: each sample is compared with the cubic
through its four nearest neighbours, which a smooth record follows to
``O(dt**4)``; the difference, in units of the noise (the scaled median
absolute deviation of the differences among samples of its size, so that
relative noise, larger where the state is larger, is measured where it is),
beyond :data:`SPIKE_MADS` makes a sample a suspect, and a suspect is a spike
where it also stands :data:`ISOLATION` times above the largest difference of
its neighbours (each from a cubic that leaves the suspects out), and where
it lies between that cubic's nodes, also stands out of it: on an exact
record the cubics' truncation error is smooth, as large at the neighbours
as at the sample, and a sample between two spikes stands out of its own
cubic as a spike does. A spike also disturbs its neighbours' cubics, and at
the ends of a record by more than itself: each pass marks the worst isolated
suspect of every cluster, and is repeated with the marked samples out.

Measured on the robustness study's short records (``benchmarks/robustness_study.py``:
the pendulum, an anharmonic spring, Henon-Heiles and coupled pendula, 200 to
500 records of 41 samples, ten seeds each, exact and with 0.5 to 20 %
additive or relative noise, 360 datasets): no sample marked, Henon-Heiles'
records that escape (growing fortyfold in their last ten samples) included.
On 48 of them (``benchmarks/spike_search.py``: four scenes, six noises, two
seeds) with 1 % of their samples set to 1e6 (6 108 samples): every one of
them marked, and 21 other samples (before the second cubic: 21 missed, 31
others). Moved by half a variable's standard deviation instead, a sample is
found as far as that stands out of the noise: 4 003 of the 6 108, with 294
other samples marked. Tests: ``tests/test_prepare.py``.
"""

import numpy as np

from ._outliers import MAD_TO_STD

# A spike lies this many noise levels (scaled MADs) from the cubic through its neighbours ...
SPIKE_MADS = 10.0
# ... the noise level measured among samples of the same size (this many bins) ...
NOISE_BINS = 10
# ... and beyond this fraction of the variable's spread (round-off of exact data).
SPIKE_FLOOR = 1e-6
# Passes of the spike search (each marks the worst sample of every cluster).
MAX_SPIKE_PASSES = 20
# Trajectories shorter than this are not searched for spikes.
MIN_SPIKE_SAMPLES = 6
# A spike's difference from its cubic exceeds its neighbours' this many times.
ISOLATION = 3.0


def _neighbour_cubics(t, usable):
    """Each sample's four nearest usable neighbours and the weights of their cubic at its time.

    Two on each side where there are, else the four nearest on one side.
    Returns ``nodes`` (n, 4) of indices and ``weights`` (n, 4): ``y[j]`` is
    predicted by ``weights[j] @ y[nodes[j]]``; a sample is never its own node.
    """
    j = np.arange(len(t))
    u = np.flatnonzero(usable)
    left = np.searchsorted(u, j, side="left")
    right = np.searchsorted(u, j, side="right")
    n_other = len(u) - (right - left)  # usable samples other than j
    start = np.clip(left - 2, 0, n_other - 4)
    positions = start[:, None] + np.arange(4)  # in u with j removed
    positions = np.where(positions < left[:, None], positions,
                         positions + (right - left)[:, None])
    nodes = u[positions]
    tn, tj = t[nodes], t[:, None]
    weights = np.ones(nodes.shape)
    for a in range(4):
        for b in range(4):
            if a != b:
                weights[:, a] *= (tj[:, 0] - tn[:, b]) / (tn[:, a] - tn[:, b])
    return nodes, weights


def _cubic_residuals(t, Y, usable):
    """Each sample's difference from its neighbours' cubic, in units of the difference's noise."""
    nodes, weights = _neighbour_cubics(t, usable)
    predicted = np.einsum("jk,jkv->jv", weights, Y[nodes])
    scale = np.sqrt(1.0 + np.sum(weights**2, axis=1))[:, None]
    return np.abs(Y - predicted) / scale


def _first_residuals(times, states):
    """:func:`_cubic_residuals` of every trajectory with every sample usable, and sizes.

    Each trajectory's entry is its differences and the size of each sample's
    neighbourhood (the second smallest magnitude of its nodes, which two
    spikes among them do not move), by which the noise is binned.
    Trajectories sampled at the same times share their cubics' weights: they
    are computed once and applied to all of them together.
    """
    out = [None] * len(times)
    shared = {}
    for k, t in enumerate(times):
        shared.setdefault((len(t), np.asarray(t - t[0]).tobytes()), []).append(k)
    for members in shared.values():
        t = times[members[0]]
        nodes, weights = _neighbour_cubics(t, np.ones(len(t), dtype=bool))
        Y = np.stack([states[k] for k in members])
        around = Y[:, nodes]  # (n_members, n_times, 4, n_states)
        predicted = np.einsum("jk,mjkv->mjv", weights, around)
        scale = np.sqrt(1.0 + np.sum(weights**2, axis=1))[None, :, None]
        residual = np.abs(Y - predicted) / scale
        size = np.sort(np.abs(around), axis=2)[:, :, 1]
        for i, k in enumerate(members):
            out[k] = (residual[i], size[i])
    return out


def _noise_by_size(residuals, sizes):
    """Each sample's noise level: the scaled median absolute residual among samples of its size.

    Relative noise is larger where the state is larger: the samples of each
    variable are binned by the size of their neighbourhood (quantiles,
    :data:`NOISE_BINS` of them), and each bin has its own level.
    """
    noise = np.empty_like(residuals)
    for v in range(residuals.shape[1]):
        size = sizes[:, v]
        edges = np.quantile(size, np.linspace(0, 1, NOISE_BINS + 1)[1:-1])
        bins = np.searchsorted(edges, size)
        level, relative = np.zeros(NOISE_BINS), np.zeros(NOISE_BINS)
        for b in np.unique(bins):
            r, s = residuals[bins == b, v], size[bins == b]
            level[b] = np.median(r)
            relative[b] = np.median(r[s > 0] / s[s > 0]) if np.any(s > 0) else 0.0
        # The top bin holds everything above the 90th percentile of sizes: a
        # record that escapes to states tens of times larger has relative
        # noise tens of times the bin's median, so a sample's level is never
        # below its bin's relative level at its own size.
        noise[:, v] = MAD_TO_STD * np.maximum(level[bins], relative[bins] * size)
    return noise


def find_spikes(times, states):
    """Samples far from the cubic through their neighbours, per trajectory.

    Parameters
    ----------
    times : list of ndarray of shape (n_times_k,)
    states : list of ndarray of shape (n_times_k, n_states)

    Returns
    -------
    spikes : list of ndarray of bool of shape (n_times_k,)
        Whether any variable of the sample is a spike.
    """
    spikes = [np.zeros(len(Y), dtype=bool) for Y in states]
    judged = [k for k, t in enumerate(times) if len(t) >= MIN_SPIKE_SAMPLES]
    if not judged:
        return spikes
    samples = np.concatenate(states)
    spread = MAD_TO_STD * np.median(np.abs(samples - np.median(samples, axis=0)), axis=0)
    floor = SPIKE_FLOOR * np.where(spread > 0, spread, np.max(np.abs(samples), axis=0))
    first = _first_residuals([times[k] for k in judged], [states[k] for k in judged])
    noise = _noise_by_size(np.concatenate([r for r, _ in first]),
                           np.concatenate([size for _, size in first]))
    noise = np.split(noise, np.cumsum([len(states[k]) for k in judged])[:-1])
    for k, level, (residual, _) in zip(judged, noise, first):
        t, Y, flagged = times[k], states[k], spikes[k]
        limit = SPIKE_MADS * level + floor
        if not np.any(residual > limit):
            continue  # most trajectories: nothing to look at twice
        for _ in range(MAX_SPIKE_PASSES):
            score = np.max(residual / limit, axis=1)
            score[flagged] = 0.0
            suspect = score > 1.0
            # The worst isolated suspect of each cluster (a spike disturbs its
            # neighbours' cubics too, and at the ends by more than itself).
            new = []
            for j in np.flatnonzero(suspect)[np.argsort(-score[suspect], kind="stable")]:
                if all(abs(j - i) > 2 for i in new) and _is_spike(t, Y, flagged, j, limit,
                                                                  suspect):
                    new.append(j)
            if not new or np.sum(~flagged) - len(new) < MIN_SPIKE_SAMPLES:
                break
            flagged[new] = True
            residual = _cubic_residuals(t, Y, ~flagged)
        for j in np.flatnonzero(flagged):
            flagged[j] = False
            flagged[j] = _is_spike(t, Y, flagged, j, limit)
    return spikes


def _is_spike(t, Y, flagged, j, limit, suspect=None):
    """Whether sample ``j`` stands out from its neighbours.

    Its difference from the cubic through its four nearest unmarked
    neighbours must exceed ``limit`` and :data:`ISOLATION` times the largest
    of the neighbours' own, each taken from a cubic that leaves out ``j``,
    the marked samples and the other ``suspect`` ones (samples beyond the
    limit, which may be spikes too). On an exact record the cubics' truncation
    error is smooth, as large at the neighbours as at ``j``; a spike stands
    above them.
    """
    own = ~flagged
    residual = _cubic_residuals(t, Y, own)  # j is never a node of its own cubic
    own[j] = False
    others = own if suspect is None else own & ~suspect
    # The neighbours are unmarked and not suspect themselves: a second spike
    # beside j would otherwise be among them, and hide j as j hides it.
    nodes, _ = _neighbour_cubics(t, others | (np.arange(len(t)) == j))
    around = _cubic_residuals(t, Y, others)
    stands = residual[j]
    if suspect is not None and nodes[j].min() < j < nodes[j].max():
        # Among suspects, j must also stand out of the cubic that leaves them
        # out (``around[j]``): beside two spikes (a pendulum's record, spikes
        # at 29, 32 and 33) a sample's own cubic passes near neither, and it
        # looked like a spike, hiding the spikes beside it. Not where that
        # cubic extrapolates (near an end), whose noise would hide a spike.
        stands = np.minimum(stands, around[j])
    # The largest, not the median: on an exact record the truncation error
    # changes sign along it, and beside a near-zero of it an end sample's
    # extrapolation stood 4-8 times above the median of its neighbours (an
    # anharmonic spring sampled every 0.05). Other spikes are not among them
    # (marked or suspect), and noise alone keeps the largest of four within
    # about twice the median, far below the limit's ten noise levels.
    neighbours = np.max(around[nodes[j]], axis=0)
    return bool(np.any((stands > limit[j]) & (stands > ISOLATION * neighbours)))
