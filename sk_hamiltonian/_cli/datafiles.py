"""Data files of the ``sk-hamiltonian`` command: .npz and .csv, with or without time stamps."""

import os
import warnings
from collections import namedtuple

import numpy as np

from .errors import UsageError

#: Header names of a time column (right after ``trajectory`` in a CSV).
TIME_NAMES = ("t", "time")
# Fewest samples a trajectory needs for any derivative estimate.
MIN_SAMPLES = 3

DataFile = namedtuple("DataFile", ["trajectories", "names", "ids", "stamped"])
DataFile.__doc__ = """Trajectories read from a file.

``trajectories``: a 3-D array when all have the same length, else a list of
2-D arrays, with the time stamps as first column when ``stamped``;
``names``: the state names; ``ids``: a label per trajectory (the CSV id or
the index in the file), for messages.
"""


def default_state_names(n_states):
    """``p, q`` for one degree of freedom, else ``p1.., q1..``."""
    d = n_states // 2
    if d == 1:
        return ["p", "q"]
    return [f"p{i + 1}" for i in range(d)] + [f"q{i + 1}" for i in range(d)]


def load_trajectories(path):
    """Read trajectories from ``.npz`` or ``.csv``.

    ``.npz``: the array under key ``trajectories`` (or the only array other
    than ``times``), of shape (n_trajectories, n_times, 2d); time stamps
    either as an array ``times`` of shape (n_trajectories, n_times) or as the
    first column of the trajectories (then 1 + 2d columns). ``.csv``: a header
    line, then one row per sample with the columns ``trajectory, [t,]
    p_1..p_d, q_1..q_d`` (the trajectory id first, then optionally a time
    column named ``t`` or ``time``; the rows of a trajectory contiguous and in
    time order). A state's missing reading is NaN (an empty CSV field reads
    as one); the ids and the time stamps must be finite.

    Returns
    -------
    data : DataFile
    """
    if os.path.isdir(path):
        raise UsageError(
            f"{path} is a directory: give a data file (.npz or .csv) inside it, e.g. "
            f"{os.path.join(path, 'runs.npz')}"
        )
    if not os.path.isfile(path):
        raise UsageError(f"file not found: {path}")
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".npz":
        data = _load_npz(path)
    elif suffix == ".csv":
        data = _load_csv(path)
    else:
        raise UsageError(
            f"unsupported file type {suffix or '(none)'!r} for {path}: use .npz or .csv"
        )
    return data


def _check_states(n_states, path):
    if n_states < 2 or n_states % 2:
        raise UsageError(
            f"{path}: found {n_states} state column(s); a Hamiltonian system needs an even "
            f"number, ordered p_1..p_d, q_1..q_d"
        )


def _check_times(data, path, hint=""):
    for label, T in zip(data.ids, data.trajectories):
        steps = np.diff(T[:, 0])
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise UsageError(
                f"{path}: the time stamps of trajectory {label} must be strictly increasing; "
                f"its sample {i + 1} has t={T[i + 1, 0]:g} after t={T[i, 0]:g}{hint}"
            )


def _load_npz(path):
    try:
        with np.load(path, allow_pickle=False) as archive:
            keys = list(archive.keys())
            others = [key for key in keys if key != "times"]
            if "trajectories" in archive:
                X = archive["trajectories"]
            elif len(others) == 1:
                X = archive[others[0]]
            else:
                raise UsageError(
                    f"{path} holds arrays {keys}: name the trajectories array 'trajectories'"
                )
            times = archive["times"] if "times" in archive else None
    except UsageError:
        raise
    except ValueError as error:
        if "allow_pickle" not in str(error):
            raise UsageError(f"cannot read {path} as .npz: {error}") from None
        # An object array: what np.savez makes of trajectories of different
        # lengths. Loading it would unpickle, which can run code from the file.
        raise UsageError(
            f"{path} holds an object array (trajectories of different lengths?), which the "
            f"command does not unpickle: save them as one .csv with a trajectory column "
            f"(ragged lengths allowed), or pad or cut them to one length and save "
            f"np.stack(trajectories) as 'trajectories'"
        ) from None
    except Exception as error:  # a corrupt archive: report it in one line
        raise UsageError(f"cannot read {path} as .npz: {error}") from None
    if X.ndim != 3:
        raise UsageError(
            f"{path}: the array has shape {X.shape}; expected (n_trajectories, n_times, 2d) "
            f"(for a single trajectory T, save T[None])"
        )
    if not np.issubdtype(X.dtype, np.number):
        raise UsageError(f"{path}: the array is not numeric (dtype {X.dtype})")
    if X.shape[1] < MIN_SAMPLES and X.shape[2] > X.shape[1] and times is None:
        # Read as it is, the long axis would pass for columns (an odd count for
        # time stamps), and the error would be about those.
        raise UsageError(
            f"{path}: the array has shape {X.shape}, {X.shape[1]} samples of {X.shape[2]} "
            f"columns per trajectory, which looks transposed: save it as "
            f"X.transpose(0, 2, 1), of shape (n_trajectories, n_times, 2d)"
        )
    X = X.astype(float)
    if times is not None:
        if X.shape[2] % 2:
            raise UsageError(
                f"{path}: the trajectories have {X.shape[2]} columns and a 'times' array is "
                f"given: with 'times', give the states only (2d columns)"
            )
        if times.shape != X.shape[:2] or not np.issubdtype(times.dtype, np.number):
            raise UsageError(
                f"{path}: 'times' must be numeric of shape (n_trajectories, n_times) = "
                f"{X.shape[:2]}; got shape {times.shape}"
            )
        X = np.concatenate([times.astype(float)[..., None], X], axis=2)
    stamped = X.shape[2] % 2 == 1
    _check_states(X.shape[2] - stamped, path)
    if stamped and not np.isfinite(X[..., 0]).all():
        raise UsageError(f"{path}: the time stamps contain NaN or infinity")
    names = default_state_names(X.shape[2] - stamped)
    data = DataFile(X, names, [str(k) for k in range(X.shape[0])], stamped)
    if stamped:
        odd = times is None
        _check_times(data, path, " (the first of an odd number of columns is the time)" * odd)
    return data


def _number_or_missing(field):
    """A CSV field as a float; an empty field as NaN."""
    return float(field) if field.strip() else np.nan


def _csv_problem(path, n_columns, error):
    """Which row of a CSV numpy could not read, and why, in the file's own terms."""
    with open(path, encoding="utf-8") as stream:
        next(stream)
        for number, line in enumerate(stream, start=2):
            if not line.strip():
                continue
            fields = line.rstrip("\n").split(",")
            if len(fields) != n_columns:
                return (
                    f"line {number} has {len(fields)} columns, the header {n_columns}: every "
                    f"row needs one value per header column"
                )
            for field in fields:
                try:
                    _number_or_missing(field)
                except ValueError:
                    return f"line {number} holds {field.strip()[:20]!r}, which is not a number"
    # Not found line by line (e.g. quoting): numpy's own words, first sentence only.
    return f"not a numeric CSV after the header ({str(error).split('.')[0]})"


def _load_csv(path):
    with open(path, encoding="utf-8") as stream:
        header = stream.readline().strip()
    names = [name.strip() for name in header.split(",")]
    if len(names) < 3 or names[0].lower() != "trajectory":
        raise UsageError(
            f"{path}: the header must read 'trajectory,[t,]<p_1>,..,<p_d>,<q_1>,..,<q_d>'; "
            f"got {header[:60]!r}"
        )
    stamped = names[1].lower() in TIME_NAMES
    _check_states(len(names) - 1 - stamped, path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy warns on a file without rows
            try:
                data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
            except ValueError:
                # An empty field is a missing reading (NaN), as spreadsheets export it.
                data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2,
                                  converters=_number_or_missing)
    except ValueError as error:
        raise UsageError(f"{path}: {_csv_problem(path, len(names), error)}") from None
    if data.shape[0] == 0:
        raise UsageError(f"{path}: the file has a header but no data rows")
    if data.shape[1] != len(names):
        raise UsageError(f"{path}: rows have {data.shape[1]} columns, the header {len(names)}")
    # Missing readings (NaN) of the states are the search's to leave out.
    if not np.isfinite(data[:, : 1 + stamped]).all():
        raise UsageError(f"{path}: the trajectory ids or time stamps contain NaN or infinity")
    ids = data[:, 0]
    # Keep the order of first appearance; a trajectory's rows must be contiguous.
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    if np.unique(ids).size != starts.size:
        raise UsageError(f"{path}: the rows of each trajectory must be contiguous")
    pieces = np.split(data[:, 1:], starts[1:])
    lengths = {piece.shape[0] for piece in pieces}
    X = np.stack(pieces) if len(lengths) == 1 else pieces
    labels = [f"{value:g}" for value in ids[starts]]
    data = DataFile(X, names[1 + stamped :], labels, stamped)
    if stamped:
        _check_times(data, path)
    return data
