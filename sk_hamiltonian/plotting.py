"""Small plotting helpers for learned and true trajectories (needs matplotlib).

Every function takes plain arrays and an optional matplotlib ``Axes``, draws on
it (or on a new figure) and returns the ``Axes``. matplotlib is imported only
when a function is called, so the package does not depend on it.
"""

import numpy as np


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
    return ax


def _state_names(n_states, state_names):
    if state_names is not None:
        if len(state_names) != n_states:
            raise ValueError(
                f"state_names must have one name per state variable ({n_states}); "
                f"got {len(state_names)}."
            )
        return list(state_names)
    d = n_states // 2
    if d == 1:
        return ["p", "q"]
    return [f"p{i + 1}" for i in range(d)] + [f"q{i + 1}" for i in range(d)]


def _check_curves(curves, n_times=None, what="curves"):
    if not isinstance(curves, dict) or not curves:
        raise ValueError(f"{what} must be a non-empty dict mapping labels to arrays.")
    out = {}
    for label, Y in curves.items():
        Y = np.asarray(Y, dtype=float)
        if n_times is not None and Y.shape[0] != n_times:
            raise ValueError(
                f"{what}[{label!r}] has {Y.shape[0]} times, but t has {n_times}."
            )
        out[label] = Y
    return out


def plot_trajectories(t, trajectories, *, state_names=None, ax=None):
    """Plot every state variable of one or several trajectories against time.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Times.
    trajectories : dict of str to array-like of shape (n_times, n_states)
        Labelled trajectories, e.g. ``{"true": U, "learned": V}``. The first
        one is drawn solid, the others dashed.
    state_names : list of str, default=None
        Names of the state variables; None uses ``p, q`` or ``p1.., q1..``.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.

    Returns
    -------
    ax : matplotlib Axes

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.plotting import plot_trajectories
    >>> t = np.linspace(0, 6, 50)
    >>> ax = plot_trajectories(t, {"true": np.column_stack([-np.sin(t), np.cos(t)])})
    """
    t = np.asarray(t, dtype=float)
    curves = _check_curves(trajectories, t.shape[0], "trajectories")
    ax = _axes(ax)
    n_states = next(iter(curves.values())).shape[1]
    names = _state_names(n_states, state_names)
    colors = [f"C{i}" for i in range(n_states)]
    for k, (label, Y) in enumerate(curves.items()):
        style = "-" if k == 0 else ("--", ":", "-.")[(k - 1) % 3]
        for i in range(n_states):
            ax.plot(t, Y[:, i], style, color=colors[i], lw=1.2,
                    label=f"{names[i]} ({label})")
    ax.set_xlabel("t")
    ax.legend(fontsize="small", ncol=max(1, len(curves)))
    return ax


def plot_phase(trajectories, *, pair=0, state_names=None, ax=None, scatter=None):
    """Phase portrait ``(q_i, p_i)`` of one or several trajectories.

    Parameters
    ----------
    trajectories : dict of str to array-like of shape (n_times, n_states)
        Labelled trajectories.
    pair : int, default=0
        Which degree of freedom ``i`` to draw.
    state_names : list of str, default=None
        Names of the state variables, for the axis labels.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.
    scatter : array-like of shape (n_points, n_states), default=None
        Points drawn faintly underneath, e.g. the training observations.

    Returns
    -------
    ax : matplotlib Axes
    """
    curves = _check_curves(trajectories, what="trajectories")
    ax = _axes(ax)
    n_states = next(iter(curves.values())).shape[1]
    d = n_states // 2
    if not 0 <= pair < d:
        raise ValueError(f"pair must be in [0, {d - 1}]; got {pair!r}.")
    names = _state_names(n_states, state_names)
    if scatter is not None:
        S = np.asarray(scatter, dtype=float).reshape(-1, n_states)
        ax.plot(S[:, d + pair], S[:, pair], ".", color="0.8", ms=1, label="observations")
    for k, (label, Y) in enumerate(curves.items()):
        style = "-" if k == 0 else ("--", ":", "-.")[(k - 1) % 3]
        ax.plot(Y[:, d + pair], Y[:, pair], style, lw=1.2, label=label)
    ax.set_xlabel(names[d + pair])
    ax.set_ylabel(names[pair])
    ax.legend(fontsize="small")
    return ax


def plot_energy(t, energies, *, deviation=True, ax=None):
    """Energy (or its deviation from the start) along trajectories.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Times.
    energies : dict of str to array-like of shape (n_times,)
        Labelled energies, e.g. ``{"RK4": H_rk4, "AVF": H_avf}``.
    deviation : bool, default=True
        Plot ``|H(t) - H(0)|`` on a logarithmic axis (values below 1e-17,
        exact conservation, are drawn at 1e-17); otherwise ``H(t)``.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.

    Returns
    -------
    ax : matplotlib Axes
    """
    t = np.asarray(t, dtype=float)
    curves = _check_curves(energies, t.shape[0], "energies")
    ax = _axes(ax)
    for label, H in curves.items():
        if deviation:
            ax.semilogy(t, np.maximum(np.abs(H - H[0]), 1e-17), lw=1.2, label=label)
        else:
            ax.plot(t, H, lw=1.2, label=label)
    ax.set_xlabel("t")
    ax.set_ylabel("|H(t) - H(0)|" if deviation else "H(t)")
    ax.legend(fontsize="small")
    return ax
