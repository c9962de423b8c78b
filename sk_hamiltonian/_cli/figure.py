"""The figure of the ``sk-hamiltonian`` report (report.png)."""

import numpy as np


def draw_report(path, t, curves, truth, errors, model, rk4, avf, observed, names, title):
    """Write the four-panel figure of the command's report to ``path``.

    ``observed`` is ``(times, states)``: the time stamps of the first
    trajectory relative to its start, and the states of every trajectory.
    """
    # A bare Figure, not pyplot: no GUI backend, no global state touched.
    from matplotlib.figure import Figure

    from ..plotting import plot_energy, plot_phase, plot_trajectories

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
    times, states = observed
    if truth is None:
        # The rollouts start at the first observation of trajectory 0: show
        # the observations they should follow.
        shown_times = times <= t[-1]
        first = np.asarray(states[0])[shown_times]
        for i in range(first.shape[1]):
            axes[0, 0].plot(times[shown_times], first[:, i], ".", color=f"C{i}", ms=3)
    title_0 = " vs the true system" if truth is not None else " (dots: observations)"
    axes[0, 0].set_title("trajectories" + title_0)
    plot_phase(shown, state_names=names, ax=axes[0, 1], scatter=np.concatenate(states))
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
