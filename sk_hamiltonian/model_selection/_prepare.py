"""Stage 0 of the search: the data as its folds will see them, and what was left out.

Before any model sees them, the trajectories are checked for what shapes a
law without being physics, and for what the folds need:

1. **Spikes.** A sample far from its neighbours (a dropped sensor reading) is
   left out, and its trajectory cut there into pieces
   (:func:`~sk_hamiltonian._spikes.find_spikes`: the cubic through its four
   nearest neighbours, ten noise levels off and three times above the
   neighbours' own differences). A missing reading (a sample with a NaN or
   infinite value) is left out alike, the spikes sought among the others.
   Pieces shorter than :data:`MIN_PIECE_SAMPLES` are left out too, and a
   trajectory with more than :data:`MAX_SPIKE_FRACTION` of its samples
   marked is left out whole.
2. **Duplicates.** A trajectory equal to an earlier one adds no information,
   only weight: it is left out.
3. **Few long records.** With fewer than :data:`MIN_PER_FOLD` trajectories per
   fold, the records are cut into contiguous segments, about
   :data:`SEGMENTS_PER_FOLD` per fold, of at most :data:`MAX_SEGMENT_SAMPLES`
   and at least :data:`MIN_SEGMENT_SAMPLES` samples, and the folds hold out
   contiguous stretches of them (blocked cross-validation: no sample is in a
   training and a test fold; a ``cv`` splitter object is given the stretches
   as ``groups``, and one that ignores groups, a shuffled ``KFold``, splits
   the segments as asked, which ``preparation_`` says). Otherwise the folds
   are those of ``cv`` over the user's trajectories, and the pieces of one
   trajectory share its fold.
4. **Clean data.** The noise the data show by themselves (their sixth
   differences, :func:`~sk_hamiltonian._trajectory_fit.difference_noise_model`)
   below :data:`CLEAN_LEVEL` of every variable's spread marks them as exact.
5. **Units.** Where the momenta's spread and the positions' differ by more
   than :data:`~._units.BALANCE_BOUND`, the momenta are multiplied by the
   power of ten nearest their ratio (:mod:`._units`), so that the rows of
   both kinds weigh alike in the candidates' misfits.

Everything left out is named, as in the user's ``X``, in an
:class:`~sk_hamiltonian.OutlierWarning` and in the search's ``preparation_``.
"""

import warnings

import numpy as np
from sklearn.model_selection import GroupKFold, check_cv

from .._outliers import listed
from .._spikes import find_spikes
from .._trajectories import check_time_stamps
from .._trajectory_fit import difference_noise_model
from .._trajectory_fit.noise import mean_variance
from .._warnings import warn
from ..exceptions import OutlierWarning
from ._cv_tools import segment_starts
from ._units import momentum_factor, times_momenta

# A trajectory with more than this fraction of spikes is left out whole.
MAX_SPIKE_FRACTION = 0.2
# Pieces between spikes shorter than this are left out: the de-noising
# polynomials of the search need degree + 2 samples, and its largest default
# degree is 8.
MIN_PIECE_SAMPLES = 10
# Trajectories each fold should hold out before long records are cut.
MIN_PER_FOLD = 2
# Segments per fold when records are cut, and their bounds.
SEGMENTS_PER_FOLD = 4
MIN_SEGMENT_SAMPLES = 21
MAX_SEGMENT_SAMPLES = 400
# Noise below this fraction of every variable's root-mean-square: exact data.
CLEAN_LEVEL = 1e-5


class Prepared:
    """The search's data after stage 0.

    Attributes
    ----------
    X : ndarray of shape (n, n_times, n_columns) or list of ndarray
        What the pipelines are fitted on.
    trajectories : list of ndarray
        The same, one array each.
    folds : list of ndarray of int
        Held-out trajectories (rows of ``X``) of each fold.
    origin : ndarray of int of shape (n, 3)
        Where each row of ``X`` comes from: the user's trajectory, its first
        sample and its stop (exclusive).
    report : dict
        ``left_out`` (the user's trajectory index to the sample indices left
        out of it), ``dropped`` (trajectories left out whole, with why),
        ``missing`` (the user's trajectory index to its samples with a NaN or
        infinite value, also in ``left_out``), ``duplicates`` (index to the
        earlier trajectory it repeats),
        ``segments`` (None, or how records were cut), ``noise`` (the data's
        own noise model, ``(a_i, b_i)`` per variable, or None), ``clean`` and
        ``momentum_scale`` (the factor the momenta of ``X`` are multiplied
        by, 1.0 where the units were left as they are).
    momentum_scale : float
        That factor.
    user_X, user_trajectories : ndarray or list of ndarray, and list of ndarray
        ``X`` and ``trajectories`` in the user's units (the same objects
        where the momentum scale is 1).
    """

    def __init__(self, X, trajectories, folds, origin, report, user_trajectories):
        self.X, self.trajectories, self.folds, self.report = X, trajectories, folds, report
        self.origin = origin
        self.momentum_scale = report["momentum_scale"]
        self.user_trajectories = user_trajectories
        self.user_X = X if user_trajectories is trajectories else _stacked(user_trajectories)


def _pieces(flags):
    """Runs of unflagged samples, as (start, stop) pairs."""
    edges = np.flatnonzero(np.diff(np.concatenate([[True], flags, [True]]).astype(int)))
    return list(zip(edges[::2], edges[1::2]))


def prepare(trajectories, dt, cv, groups):
    """Stage 0: spikes and duplicates left out, long records segmented, the folds, the units.

    Parameters
    ----------
    trajectories : list of ndarray
        The user's trajectories, checked (time stamps first when ``dt`` is None).
    dt : float or None
    cv : int, cross-validation generator or iterable
    groups : array-like or None
        Group labels of the user's trajectories.

    Returns
    -------
    prepared : Prepared

    Raises
    ------
    ValueError
        If ``cv`` gives fewer than 2 folds, the data are too few for the folds
        even cut into segments, or
        (``dt`` None) a trajectory's time stamps are not finite or do not
        strictly increase.
    """
    offset = 1 if dt is None else 0
    if dt is None:  # before the spike screen reads them
        check_time_stamps(trajectories)
    states = [T[:, offset:] for T in trajectories]
    report = dict(left_out={}, missing={}, dropped={}, duplicates={}, segments=None,
                  noise=None, clean=False)
    pieces, origin = _without_spikes(trajectories, states, report)
    pieces, origin = _without_duplicates(pieces, origin, report)
    if not pieces:
        raise ValueError(
            "No trajectory is left once spikes and duplicates are left out "
            f"({_left_out_words(report)}): the data cannot be fitted. Inspect X.")
    _warn_left_out(report, len(trajectories))
    n_splits = _n_splits(cv)
    if np.unique(origin[:, 0]).size >= MIN_PER_FOLD * n_splits:
        folds = _trajectory_folds(cv, len(trajectories), origin[:, 0], groups)
    else:
        pieces, origin, folds = _segmented(pieces, origin, n_splits, cv, report)
    if len(folds) < 2:
        raise ValueError(f"cv must give at least 2 folds; got {len(folds)}.")
    report["momentum_scale"] = momentum_factor([P[:, offset:] for P in pieces])
    user_pieces, pieces = pieces, times_momenta(pieces, report["momentum_scale"], offset)
    noise = difference_noise_model([P[:, offset:] for P in pieces])
    report["noise"] = noise
    if noise is not None:
        samples = np.concatenate([P[:, offset:] for P in pieces])
        rms = np.sqrt(np.mean(samples**2, axis=0))
        level = np.sqrt(mean_variance(noise, samples))
        report["clean"] = bool(np.all(level <= CLEAN_LEVEL * np.where(rms > 0, rms, 1.0)))
    return Prepared(_stacked(pieces), pieces, folds, origin, report, user_pieces)


def _stacked(pieces):
    """One array where the pieces are of one length, else the list."""
    return np.stack(pieces) if len({len(P) for P in pieces}) == 1 else pieces


def _without_spikes(trajectories, states, report):
    """Pieces of the trajectories between spikes, and where each comes from (``origin``)."""
    offset = trajectories[0].shape[1] - states[0].shape[1]
    times = [T[:, 0] if offset else np.arange(len(T), dtype=float) for T in trajectories]
    # Spikes are sought among the readings that are there.
    present = [np.isfinite(Y).all(axis=1) for Y in states]
    found = find_spikes([t[m] for t, m in zip(times, present)],
                        [Y[m] for Y, m in zip(states, present)])
    flags = []
    for k, (m, spikes) in enumerate(zip(present, found)):
        flagged = ~m
        flagged[m] = spikes
        flags.append(flagged)
        if not m.all():
            report["missing"][k] = [int(j) for j in np.flatnonzero(~m)]
    pieces, origin = [], []
    for k, (T, flagged) in enumerate(zip(trajectories, flags)):
        if not flagged.any():
            pieces.append(T)
            origin.append((k, 0, len(T)))
            continue
        if flagged.mean() > MAX_SPIKE_FRACTION:
            report["dropped"][k] = (f"{flagged.sum()} of its {len(T)} samples are spikes or "
                                    f"missing")
            continue
        left = list(np.flatnonzero(flagged))
        for start, stop in _pieces(flagged):
            if stop - start >= MIN_PIECE_SAMPLES:
                pieces.append(T[start:stop])
                origin.append((k, start, stop))
            else:
                left.extend(range(start, stop))
        report["left_out"][k] = sorted(int(j) for j in left)
    return pieces, np.array(origin, dtype=np.intp).reshape(-1, 3)


def _without_duplicates(pieces, origin, report):
    """The pieces with every repeat of an earlier whole trajectory left out."""
    seen, keep = {}, []
    for i, P in enumerate(pieces):
        key = (P.shape, P.tobytes())
        k = origin[i, 0]
        if key in seen and origin[seen[key], 0] != k:
            report["duplicates"][int(k)] = int(origin[seen[key], 0])
            continue
        seen.setdefault(key, i)
        keep.append(i)
    return [pieces[i] for i in keep], origin[keep]


def _left_out_words(report):
    parts = []
    if report["left_out"]:
        n = sum(len(v) for v in report["left_out"].values())
        missing = sum(len(v) for k, v in report["missing"].items() if k in report["left_out"])
        parts.append(f"{n} samples of trajectories {listed(sorted(report['left_out']))} as spikes"
                     + (f" or missing readings ({missing} NaN or infinite)" if missing else ""))
    if report["dropped"]:
        parts.append(f"trajectories {listed(sorted(report['dropped']))} whole, mostly spikes"
                     + (" or missing readings" if report["missing"] else ""))
    if report["duplicates"]:
        parts.append(f"trajectories {listed(sorted(report['duplicates']))}, repeats of earlier "
                     f"ones")
    return "; ".join(parts)


def _warn_left_out(report, n_trajectories):
    words = _left_out_words(report)
    if not words:
        return
    named = sorted(set(report["left_out"]) | set(report["dropped"]) | set(report["duplicates"]))
    warn(
        OutlierWarning(
            f"HamiltonianSearchCV: of {n_trajectories} trajectories (numbered as in X), left "
            f"out {words}. Spikes are samples far from their neighbours (dropped readings); "
            f"each trajectory is cut at them"
            + (" and at its missing readings" if report["missing"] else "")
            + " and the pieces fitted. The search's preparation_ lists every sample left out.",
            trajectories=named,
        ),
        OutlierWarning,
    )


def _n_splits(cv):
    splitter = check_cv(cv)
    try:
        return int(splitter.get_n_splits())
    except TypeError:  # splitters that need the data to count: at most this many
        return 2


def _trajectory_folds(cv, n_trajectories, owners, groups):
    """The folds of ``cv`` over the user's trajectories, each piece in its trajectory's fold.

    Trajectories left out whole are in no fold; a fold left empty by them is
    dropped.
    """
    splitter = check_cv(cv)
    folds = []
    for _, test in splitter.split(np.zeros((n_trajectories, 1)), groups=groups):
        fold = np.flatnonzero(np.isin(owners, test))
        if fold.size:
            folds.append(fold)
    return folds


def _segmented(pieces, origin, n_splits, cv, report):
    """Few long records: contiguous segments, where each comes from, and blocked folds of them."""
    total = sum(len(P) for P in pieces)
    length = min(MAX_SEGMENT_SAMPLES, total // (SEGMENTS_PER_FOLD * n_splits))
    n_records = np.unique(origin[:, 0]).size
    if length < MIN_SEGMENT_SAMPLES:
        raise ValueError(
            f"Too few data for {n_splits} folds: {n_records} "
            f"{'trajectory' if n_records == 1 else 'trajectories'} of {total} samples in all. The search holds out whole trajectories, at least {MIN_PER_FOLD} per "
            f"fold ({MIN_PER_FOLD * n_splits} in all), or cuts longer records into "
            f"{SEGMENTS_PER_FOLD} segments of at least {MIN_SEGMENT_SAMPLES} samples per fold "
            f"({SEGMENTS_PER_FOLD * n_splits * MIN_SEGMENT_SAMPLES} samples in all). Give "
            # Two folds are the fewest: suggesting fewer would send the user
            # in a circle.
            + ("more or longer trajectories, or fewer folds (cv)." if n_splits > 2 else
               "more or longer trajectories: 2 folds are already the fewest (cv).")
        )
    segments, where = [], []
    for P, (k, first, _) in zip(pieces, origin):
        starts = segment_starts(len(P), int(length))
        for start, stop in zip(starts, starts[1:] + [len(P)]):
            segments.append(P[start:stop])
            where.append((k, first + start, first + stop))
    blocks = np.concatenate([np.full(run.size, g) for g, run in
                             enumerate(np.array_split(np.arange(len(segments)), n_splits))])
    splitter = GroupKFold(n_splits) if isinstance(cv, (int, np.integer)) else check_cv(cv)
    with warnings.catch_warnings():
        # A splitter without groups (KFold) splits the segments as the user
        # asked; the report below says so, not scikit-learn's warning.
        warnings.filterwarnings("ignore", message="The groups parameter is ignored")
        folds = [test for _, test in splitter.split(np.zeros((len(segments), 1)),
                                                    groups=blocks)]
    blocked = all(np.array_equal(np.sort(test), np.arange(test.min(), test.max() + 1))
                  for test in folds if test.size)
    report["segments"] = dict(
        n_records=int(n_records), length=int(length), n_segments=len(segments),
        rule=(f"{n_records} records cannot fill {n_splits} folds with {MIN_PER_FOLD} each: "
              f"cut into {len(segments)} contiguous segments of {length} samples "
              f"(the last of a record up to {2 * length - 1}), "
              + ("each fold holding out a contiguous stretch of them" if blocked else
                 "the folds of cv over the segments (not contiguous stretches)")),
    )
    return segments, np.array(where, dtype=np.intp), folds
