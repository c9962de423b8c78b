"""Pieces of the ``sk-hamiltonian`` command: data files and the figure."""

import os

import numpy as np


class UsageError(Exception):
    """A problem with the command line or the user's file: one line, exit code 2."""


def default_state_names(n_states):
    d = n_states // 2
    if d == 1:
        return ["p", "q"]
    return [f"p{i + 1}" for i in range(d)] + [f"q{i + 1}" for i in range(d)]


def load_trajectories(path):
    """Read trajectories from ``.npz`` or ``.csv``; return (X, state names).

    ``.npz``: the array under key ``trajectories``, or the only array, of shape
    (n_trajectories, n_times, 2d). ``.csv``: a header line, then one row per
    sample with the columns ``trajectory, p_1..p_d, q_1..q_d`` (the trajectory
    id first; rows of a trajectory in time order). Trajectories in a CSV may
    have different lengths; they are returned as a list.
    """
    if not os.path.isfile(path):
        raise UsageError(f"file not found: {path}")
    suffix = os.path.splitext(path)[1].lower()
    if suffix == ".npz":
        return _load_npz(path)
    if suffix == ".csv":
        return _load_csv(path)
    raise UsageError(f"unsupported file type {suffix or '(none)'!r} for {path}: use .npz or .csv")


def _check_states(n_states, path):
    if n_states < 2 or n_states % 2:
        raise UsageError(
            f"{path}: found {n_states} state column(s); a Hamiltonian system needs an even "
            f"number, ordered p_1..p_d, q_1..q_d"
        )


def _load_npz(path):
    try:
        with np.load(path, allow_pickle=False) as archive:
            keys = list(archive.keys())
            if "trajectories" in archive:
                X = archive["trajectories"]
            elif len(keys) == 1:
                X = archive[keys[0]]
            else:
                raise UsageError(
                    f"{path} holds arrays {keys}: name the trajectories array 'trajectories'"
                )
    except UsageError:
        raise
    except Exception as error:  # a corrupt archive: report it in one line
        raise UsageError(f"cannot read {path} as .npz: {error}") from None
    if X.ndim != 3:
        raise UsageError(
            f"{path}: the array has shape {X.shape}; expected (n_trajectories, n_times, 2d) "
            f"(for a single trajectory T, save T[None])"
        )
    if not np.issubdtype(X.dtype, np.number):
        raise UsageError(f"{path}: the array is not numeric (dtype {X.dtype})")
    _check_states(X.shape[2], path)
    if not np.isfinite(X).all():
        raise UsageError(f"{path}: the trajectories contain NaN or infinity")
    return X.astype(float), default_state_names(X.shape[2])


def _load_csv(path):
    with open(path, encoding="utf-8") as stream:
        header = stream.readline().strip()
    names = [name.strip() for name in header.split(",")]
    if len(names) < 3 or names[0].lower() != "trajectory":
        raise UsageError(
            f"{path}: the header must read 'trajectory,<p_1>,..,<p_d>,<q_1>,..,<q_d>'; "
            f"got {header[:60]!r}"
        )
    _check_states(len(names) - 1, path)
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError as error:
        raise UsageError(f"{path}: not a numeric CSV after the header ({error})") from None
    if data.shape[1] != len(names):
        raise UsageError(f"{path}: rows have {data.shape[1]} columns, the header {len(names)}")
    if not np.isfinite(data).all():
        raise UsageError(f"{path}: the data contain NaN or infinity")
    ids = data[:, 0]
    # Keep the order of first appearance; a trajectory's rows must be contiguous.
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    if np.unique(ids).size != starts.size:
        raise UsageError(f"{path}: the rows of each trajectory must be contiguous")
    pieces = np.split(data[:, 1:], starts[1:])
    lengths = {piece.shape[0] for piece in pieces}
    X = np.stack(pieces) if len(lengths) == 1 else pieces
    return X, names[1:]


def draw_report(path, t, curves, truth, errors, model, rk4, avf, X, names, title):
    """Write the four-panel figure of the command's report to ``path``."""
    # A bare Figure, not pyplot: no GUI backend, no global state touched.
    from matplotlib.figure import Figure

    from .plotting import plot_energy, plot_phase, plot_trajectories

    fig = Figure(figsize=(11, 8), layout="constrained")
    axes = fig.subplots(2, 2)
    shown = {}
    if truth is not None:
        shown["true"] = truth
    for label, (Y, ok) in curves.items():
        # Past a failure the states are frozen; hide them.
        Y = np.where(np.arange(len(t))[:, None] < ok, Y, np.nan)
        shown[label] = Y
    plot_trajectories(t, shown, state_names=names, ax=axes[0, 0])
    if truth is None:
        # The rollouts start at the first observation of trajectory 0: show
        # the observations they should follow.
        first = np.asarray(X[0])[: len(t)]
        for i in range(first.shape[1]):
            axes[0, 0].plot(t[: len(first)], first[:, i], ".", color=f"C{i}", ms=3)
    title_0 = " vs the true system" if truth is not None else " (dots: observations)"
    axes[0, 0].set_title("trajectories" + title_0)
    observed = np.concatenate([np.asarray(T) for T in X])
    plot_phase(shown, state_names=names, ax=axes[0, 1], scatter=observed)
    axes[0, 1].set_title("phase plot (first degree of freedom)")
    ax = axes[1, 0]
    if errors:
        for label, e in errors.items():
            ax.semilogy(t, e, lw=1.2, label=label)
        ax.set_xlabel("t")
        ax.set_ylabel("relative error")
        ax.set_title("relative error against the true system")
        ax.legend(fontsize="small")
    else:
        energies = {label: model.hamiltonian(np.nan_to_num(Y)) for label, Y in shown.items()}
        plot_energy(t, energies, deviation=False, ax=ax)
        ax.set_ylabel("H~(t)")
        ax.set_title("learned energy H~ along the SP and non-SP trajectories")
    energies = {}
    for label, (Y, ok) in (("RK4", rk4), ("AVF", avf)):
        H = np.full(t.shape, np.nan)
        H[:ok] = model.hamiltonian(Y[:ok])
        energies[label] = H
    plot_energy(t, energies, ax=axes[1, 1])
    axes[1, 1].set_ylabel("|H~(t) - H~(0)|")
    axes[1, 1].set_title("drift of the learned energy H~ along the SP trajectory")
    fig.suptitle(title, fontsize="medium")
    fig.savefig(path, dpi=110)
