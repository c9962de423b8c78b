"""The figure of the ``sk-hamiltonian`` report (report.png).

Five panels: the trajectories over the whole span, a zoomed window of them
where they can be told apart (both with the resampled refits' prediction band
when the model was resampled), the phase plot, the errors against the true
system (or the learned energy along the rollouts), and the drift of the
learned energy. Every legend sits below its panel, off the data.
"""

import numpy as np

# The zoomed window's share of the simulated span.
ZOOM_SHARE = 1 / 8
# Fewest sampling steps the zoomed window covers.
ZOOM_MIN_STEPS = 10


def draw_report(path, t, curves, truth, errors, model, rk4, avf, observed, names, title,
                band=None):
    """Write the figure of the command's report to ``path``.

    ``curves`` maps a label ("SP", "non-SP") to ``(states, n_valid_times)``
    of a rollout; ``truth`` is the true system's trajectory or None;
    ``observed`` is ``(times, states)``: the time stamps of the first
    trajectory relative to its start, and the states of every trajectory;
    ``band`` is ``(low, high)``, the resampled refits' prediction band along
    ``t``, shaded under the trajectories, or None.
    """
    # A bare Figure, not pyplot: no GUI backend, no global state touched.
    from matplotlib.figure import Figure

    from ..plotting import plot_energy, plot_phase

    fig = Figure(figsize=(11, 12), layout="constrained")
    axes = fig.subplot_mosaic(
        [["trajectories", "trajectories"], ["zoom", "phase"], ["errors", "drift"]],
        height_ratios=[1, 1.15, 1],
    )
    shown = {}
    if truth is not None:
        shown["true"] = truth
    for label, (Y, ok) in curves.items():
        # Past a failure the states are frozen; hide them.
        Y = np.where(np.arange(len(t))[:, None] < ok, Y, np.nan)
        shown[label] = Y
    times, states = observed
    # The frame follows the truth, the SP model and the observations; a
    # runaway baseline (1e85 seen) leaves it instead of flattening the rest.
    reference = {k: Y for k, Y in shown.items() if k != "non-SP"}
    if truth is None:
        reference["observations"] = np.asarray(states[0])
    runaway = {k: Y for k, Y in shown.items() if k == "non-SP"}
    start, stop = _zoom_window(t, times, truth is not None)
    ax = axes["trajectories"]
    _draw_trajectories(ax, t, shown, names, truth, times, states)
    _draw_band(ax, t, band, model)
    ax.axvspan(start, stop, color="0.92", zorder=0, label="zoomed below")
    _legend_below(ax, ncols=len(shown) + 1)
    _note_left(ax, _frame(ax.set_ylim, reference.values(), runaway))
    zoom = axes["zoom"]
    _draw_trajectories(zoom, t, shown, names, truth, times, states)
    _draw_band(zoom, t, band, model)
    zoom.get_legend().remove()  # the same curves as above, and their legend
    zoom.set_xlim(start, stop)
    inside, seen = (t >= start) & (t <= stop), (times >= start) & (times <= stop)
    window = {k: Y[inside] for k, Y in reference.items() if k != "observations"}
    if truth is None:
        window["observations"] = reference["observations"][seen]
    _frame(zoom.set_ylim, window.values(), {k: Y[inside] for k, Y in runaway.items()},
           always=True)
    zoom.set_title(
        f"zoom on t in [{start:.3g}, {stop:.3g}]"
        + (" (the end, where the errors are largest)" if truth is not None
           else " (where the first trajectory was observed)")
    )
    ax = axes["phase"]
    everything = np.concatenate(states)
    plot_phase(shown, state_names=names, ax=ax, scatter=everything)
    _widen_truth(ax, "true")
    # The baseline's curve, drawn after the SP model's, would hide it where
    # the two overlap: the SP model's goes on top.
    for line in ax.get_lines():
        if line.get_label() == "SP":
            line.set_zorder(max(other.get_zorder() for other in ax.get_lines()) + 1)
    ax.set_title("phase plot (first degree of freedom)")
    _legend_below(ax, ncols=2)
    d = everything.shape[1] // 2  # the phase plot draws p_1 against q_1
    phase_reference = [Y for k, Y in shown.items() if k != "non-SP"] + [everything]
    left = _frame(ax.set_xlim, [Y[:, d] for Y in phase_reference],
                  {k: Y[:, d] for k, Y in runaway.items()})
    left += _frame(ax.set_ylim, [Y[:, 0] for Y in phase_reference],
                   {k: Y[:, 0] for k, Y in runaway.items()})
    _note_left(ax, left)
    ax = axes["errors"]
    if errors:
        for label, e in errors.items():
            ax.semilogy(t, e, lw=1.2, label=label)
        ax.set_xlabel("t")
        ax.set_ylabel("relative error")
        ax.set_title("relative error against the true system")
    else:
        energies = {label: _energy(model, t, run) for label, run in curves.items()}
        plot_energy(t, energies, deviation=False, ax=ax)
        ax.set_ylabel("H~(t)")
        ax.set_title("learned energy H~ along the SP and non-SP trajectories")
    _legend_below(ax, ncols=len(shown))
    energies = {label: _energy(model, t, run) for label, run in (("RK4", rk4), ("AVF", avf))}
    plot_energy(t, energies, ax=axes["drift"])
    axes["drift"].set_ylabel("|H~(t) - H~(0)|")
    axes["drift"].set_title(
        # With friction H~ falls by design: the panel shows that loss, not a drift.
        "learned energy H~ lost to the friction along the SP trajectory" if model.damping
        else "drift of the learned energy H~ along the SP trajectory")
    _legend_below(axes["drift"], ncols=2)
    fig.suptitle(title, fontsize="medium")
    fig.savefig(path, dpi=110)


def _draw_band(ax, t, band, model):
    """Shade the prediction band (the trajectory fit's, or the refits'), one colour per state variable."""
    if band is None:
        return
    low, high = band
    if getattr(model, "coef_covariance_", None) is not None:
        label = "90% band of the trajectory fit's coefficients"
    else:
        label = f"90% band of {model.resampled_coef_.shape[0]} resampled refits"
    for i in range(low.shape[1]):
        ax.fill_between(t, low[:, i], high[:, i], color=f"C{i}", alpha=0.2, lw=0,
                        label=label if i == 0 else None)


def _energy(model, t, run):
    """H~ along a rollout ``(states, n_valid_times)``, NaN past its failure."""
    Y, ok = run
    H = np.full(t.shape, np.nan)
    # A runaway baseline reaches states (1e85 seen) where H~'s polynomials
    # overflow: those points come out non-finite and are not drawn.
    with np.errstate(over="ignore", invalid="ignore"):
        H[:ok] = model.hamiltonian(Y[:ok])
    return H


def _draw_trajectories(ax, t, shown, names, truth, times, states):
    """The states against time; the truth broad and pale, so that curves on it show."""
    from ..plotting import plot_trajectories

    plot_trajectories(t, shown, state_names=names, ax=ax)
    if truth is not None:
        for name in names:
            _widen_truth(ax, f"{name} (true)")
    else:
        # The rollouts start at the first observation of trajectory 0: show
        # the observations they should follow.
        shown_times = times <= t[-1]
        first = np.asarray(states[0])[shown_times]
        for i in range(first.shape[1]):
            ax.plot(times[shown_times], first[:, i], ".", color=f"C{i}", ms=3,
                    label="observations" if i == 0 else None)
    ax.set_title("trajectories" + (" vs the true system" if truth is not None
                                   else " (dots: observations)"))


def _widen_truth(ax, label):
    """Draw the curve named ``label`` broad and pale: a model's curve on it stays visible."""
    for line in ax.get_lines():
        if line.get_label() == label:
            line.set(lw=4, alpha=0.35)


def _zoom_window(t, times, has_truth):
    """Where the curves can be told apart: the end against the truth, else the observations."""
    step = t[1] - t[0]
    if has_truth:
        width = max(ZOOM_SHARE * (t[-1] - t[0]), ZOOM_MIN_STEPS * step)
        return max(t[0], t[-1] - width), t[-1]
    return t[0], min(t[-1], max(times[-1], t[0] + ZOOM_MIN_STEPS * step))


def _frame(set_limits, reference, others, always=False):
    """Limits around the reference values (half their range beyond each side).

    Set when a curve of ``others`` (label to values) reaches outside them;
    else, with ``always``, set tight around every curve (matplotlib's own
    limits span the whole of each line, not only what a zoom shows). Returns
    the labels of the curves outside.
    """
    values = np.concatenate([np.ravel(piece) for piece in reference])
    values = values[np.isfinite(values)]
    if not values.size:
        return []
    low, high = values.min(), values.max()
    pad = 0.5 * (high - low) or 0.5
    low, high = low - pad, high + pad
    left = [label for label, piece in others.items()
            if np.any((np.asarray(piece) < low) | (np.asarray(piece) > high))]
    if left:
        set_limits(low, high)
    elif always:
        values = np.concatenate([values, *(np.ravel(piece) for piece in others.values())])
        values = values[np.isfinite(values)]
        pad = 0.05 * (values.max() - values.min()) or 0.5
        set_limits(values.min() - pad, values.max() + pad)
    return left


def _note_left(ax, left):
    """Say in the title which curves leave the frame."""
    if left:
        labels = ", ".join(dict.fromkeys(left))
        ax.set_title(f"{ax.get_title()}\n({labels} runs off the frame)")


def _legend_below(ax, ncols):
    """Move the panel's legend under its axes, where it covers no data."""
    handles, labels = ax.get_legend_handles_labels()
    ax.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.14),
              ncols=max(1, ncols), fontsize="small", frameon=False)
