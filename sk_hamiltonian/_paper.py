"""Shared plumbing of the gallery examples that reproduce the paper (private).

The scripts in ``examples/`` reproduce the five numerical examples of Wu, Qin &
Xiu. What they share lives here, so that each script reads as the experiment it
runs: the quick-mode switch, rollouts that stop at a blow-up instead of raising,
relative errors, the Hamiltonian-deviation table (the paper's Table 1), result
files and the figure helpers. Not public API. Matplotlib is imported only by the
plotting helpers.
"""

import json
import math
import os
import sys
from pathlib import Path

import numpy as np
from scipy.integrate import trapezoid

from ._integrate import RK4, integrate
from .datasets import PAPER_DT, make_trajectories
from .plotting import plot_energy

QUICK_ENV = "SK_HAMILTONIAN_QUICK"
LONG_ENV = "SK_HAMILTONIAN_LONG"
FIGURES_ENV = "SK_HAMILTONIAN_FIGURES"

#: Degree ``Q`` of the de-noising polynomial for noisy data (paper, Section 4).
DENOISE_DEGREE = 5
#: RK4 step of the reference solutions: against a step of 1e-4 they differ by
#: at most 2e-10 relative up to T = 20, negligible next to any learning error.
REFERENCE_STEP = PAPER_DT / 10
#: RK4 step of the learned systems. At this step RK4 moves H~ by 1e-7 or less
#: (Table 1), far below the model errors being compared.
MODEL_STEP = PAPER_DT
#: A trajectory with ``max |u_i| > BLOWUP_BOUND`` has left every domain of the
#: paper by far; from there on it counts as blown up (Cherry's system).
BLOWUP_BOUND = 10.0


def quick_mode():
    """Whether ``SK_HAMILTONIAN_QUICK`` asks for the quick variant of the examples."""
    return os.environ.get(QUICK_ENV, "").strip().lower() not in ("", "0", "false", "no")


def long_runs():
    """Whether ``SK_HAMILTONIAN_LONG`` asks for the runs marked as long."""
    return os.environ.get(LONG_ENV, "").strip().lower() not in ("", "0", "false", "no")


def pick(full, quick):
    """``quick`` in quick mode, ``full`` otherwise."""
    return quick if quick_mode() else full


def time_grid(t_end, dt=PAPER_DT):
    """Output times ``0, dt, ..., t_end``."""
    return dt * np.arange(int(round(t_end / dt)) + 1)


def checkpoints(t_end, candidates=(10.0, 50.0, 100.0)):
    """Times at which errors are reported: the candidates up to ``t_end``, and ``t_end``."""
    return sorted({T for T in candidates if T <= t_end} | {float(t_end)})


def _run(integrator, x0, t, max_step):
    Y, failed_at = integrate(integrator, np.atleast_2d(np.asarray(x0, dtype=float)), t, max_step)
    U = Y[:, 0].copy()
    U[failed_at[0] :] = np.nan
    with np.errstate(invalid="ignore"):
        escaped = np.flatnonzero(np.abs(U).max(axis=1) > BLOWUP_BOUND)
    if escaped.size:
        U[escaped[0] :] = np.nan
    return U


def reference(system, t, x0=None):
    """The true trajectory from ``u0*`` (or ``x0``) by RK4 at ``REFERENCE_STEP``.

    Rows from a blow-up on are NaN, see :func:`blowup_time`.
    """
    x0 = system.initial_state if x0 is None else x0
    return _run(RK4(system.vector_field), x0, t, REFERENCE_STEP)


def rollout(model, x0, t, *, method="rk4", max_step=MODEL_STEP):
    """Trajectory of a fitted regressor, like ``simulate`` but NaN past a blow-up."""
    return _run(model._integrator(method), x0, t, max_step)


def compare(system, models, t):
    """Roll the true system and each model out from ``u0*``.

    Parameters
    ----------
    system : HamiltonianSystem
        The true system.
    models : dict
        Label -> fitted regressor.
    t : ndarray
        Output times.

    Returns
    -------
    trajectories : dict
        ``"exact"`` and each label -> trajectory of shape (n_times, n_states),
        NaN past a blow-up.
    errors : dict
        Each label -> relative error over time.
    """
    trajectories = {"exact": reference(system, t)}
    for label, model in models.items():
        trajectories[label] = rollout(model, system.initial_state, t)
    errors = {
        label: relative_error(U, trajectories["exact"])
        for label, U in trajectories.items()
        if label != "exact"
    }
    return trajectories, errors


def along(fun, U):
    """``fun(U)`` on the rows of a trajectory before its blow-up, NaN after."""
    finite = ~np.isnan(U).any(axis=1)
    values = np.full(U.shape[0], np.nan)
    values[finite] = fun(U[finite])
    return values


def over_data_sets(system, fit_models, seeds, t_end):
    """Mean relative error over ``[0, t_end]`` of models refitted on fresh data.

    Each seed draws a new data set with the paper's settings of ``system``
    (initial states and noise); ``fit_models(X)`` returns ``label -> fitted
    model``. One data set is one draw, so this shows which differences between
    the models are systematic.

    Returns
    -------
    errors : dict
        ``label -> list`` of mean relative errors, one per seed.
    """
    settings = system.paper_settings
    t = time_grid(t_end)
    u = reference(system, t)
    errors = {}
    for seed in seeds:
        X = make_trajectories(
            system, settings["n_trajectories"], settings["n_intervals"], PAPER_DT,
            noise=settings["noise"], random_state=seed,
        )
        for label, model in fit_models(X).items():
            err = relative_error(rollout(model, system.initial_state, t), u)
            errors.setdefault(label, []).append(float(np.mean(err)))
    return errors


def data_set_summary(errors, comparisons):
    """Median and range per model, and how often ``a`` beat ``b`` for each pair.

    Returns
    -------
    rows : list of dict
        ``model, median, min, max``.
    wins : dict
        ``"a < b" -> number of data sets`` where ``a`` had the smaller error.
    """
    rows = [
        {"model": label, "median": float(np.median(v)), "min": float(np.min(v)),
         "max": float(np.max(v))}
        for label, v in errors.items()
    ]
    wins = {
        f"{a} < {b}": int(np.sum(np.array(errors[a]) < np.array(errors[b])))
        for a, b in comparisons
    }
    return rows, wins


def mean_period(t, U, component):
    """Mean time between upward zero crossings of ``U[:, component]``.

    For an oscillation about zero, its period; linear interpolation between
    output times locates each crossing.
    """
    x = U[:, component]
    k = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    crossings = t[k] - x[k] * (t[k + 1] - t[k]) / (x[k + 1] - x[k])
    return float(np.mean(np.diff(crossings))) if crossings.size > 1 else math.nan


def blowup_time(t, U):
    """First time at which ``U`` is NaN (blown up), or ``inf``."""
    bad = np.flatnonzero(np.isnan(U).any(axis=1))
    return float(t[bad[0]]) if bad.size else math.inf


def relative_error(U, U_true):
    """``||U(t) - U_true(t)|| / ||U_true(t)||`` at every time, the paper's error."""
    return np.linalg.norm(U - U_true, axis=1) / np.linalg.norm(U_true, axis=1)


def value_at(t, values, when):
    """``values`` at the output time closest to each time in ``when`` (NaN past ``t``)."""
    out = {}
    for T in when:
        k = int(np.argmin(np.abs(t - T)))
        out[f"{T:g}"] = float(values[k]) if abs(t[k] - T) < 1e-9 * max(1.0, T) else math.nan
    return out


def error_table(t, errors, checkpoints):
    """Rows ``{"model", "T=<T>" for each checkpoint, "mean"}`` of relative errors.

    ``mean`` is the time average over the whole horizon, NaN if a trajectory
    blew up before its end.
    """
    rows = []
    for label, err in errors.items():
        row = {"model": label}
        row.update({f"T={T}": v for T, v in value_at(t, err, checkpoints).items()})
        row["mean"] = float(np.mean(err))
        rows.append(row)
    return rows


def _domain_sample(system, n_samples=20_000, random_state=0):
    rng = np.random.default_rng(random_state)
    D = system.domain
    return rng.uniform(D[:, 0], D[:, 1], size=(n_samples, D.shape[0]))


def hamiltonian_offset(model, system):
    """The constant ``C`` of Theorem 3.5: the mean of ``H - H~`` over the domain.

    ``H~ + C`` is the learned Hamiltonian closest to ``H`` in ``L2`` of the
    uniform measure on the domain, so it can be plotted next to ``H``.
    """
    X = _domain_sample(system)
    return float(np.mean(system.hamiltonian(X) - model.hamiltonian(X)))


def hamiltonian_scale(model, system):
    """Range of ``H~`` over the domain: the scale for relative deviations.

    ``H~`` is defined up to a constant, so its value at a state is no scale.
    """
    return float(np.ptp(model.hamiltonian(_domain_sample(system))))


def conservation(model, system, t):
    """Largest relative deviation of ``H~`` along RK4 and AVF solutions from ``u0*``.

    Both use the step :data:`MODEL_STEP`; the horizon is ``t[-1]``, or the
    blow-up time of the RK4 solution if earlier.

    Returns
    -------
    drift : dict
        ``{"rk4": ..., "avf": ...}``, each ``max_t |H~(u(t)) - H~(u0)|``
        divided by :func:`hamiltonian_scale`.
    """
    scale = hamiltonian_scale(model, system)
    drift = {}
    for method in ("rk4", "avf"):
        U = rollout(model, system.initial_state, t, method=method)
        if method == "rk4":
            # The AVF solution cannot go past a blow-up either: stop both there.
            t = t[~np.isnan(U).any(axis=1)]
        H = model.hamiltonian(U[: t.shape[0]])
        drift[method] = float(np.max(np.abs(H - H[0])) / scale)
    return drift


def hamiltonian_deviation(model, system, t_end, steps, method="rk4"):
    """Deviation ``H~(u(t)) - H~(u0)`` of a numerical solution, per step size.

    The learned system conserves ``H~`` exactly, so the deviation is the
    integrator's alone (the paper's Table 1 and Figure 2).

    Parameters
    ----------
    model : HamiltonianRegressor
        Fitted model.
    system : HamiltonianSystem
        Gives the initial state ``u0*`` and the domain.
    t_end : float
        Horizon.
    steps : sequence of float
        Step sizes ``tau``, decreasing; the deviation is sampled at every step.
    method : {"rk4", "avf"}
        Integrator.

    Returns
    -------
    rows : list of dict
        Per step: ``step``, the norms ``linf`` (max), ``l2``
        (``(int_0^T dH^2 dt)^(1/2)``, trapezoid rule) and ``tv`` (total
        variation, the sum of the absolute increments), ``relative``
        (``linf`` over :func:`hamiltonian_scale`) and observed orders
        ``order_<norm>`` against the previous row (NaN for the first).
    curves : dict
        ``tau -> (t, dH)``, for plotting.
    """
    x0 = system.initial_state
    h0 = float(model.hamiltonian(x0[None])[0])
    scale = hamiltonian_scale(model, system)
    rows, curves = [], {}
    for tau in steps:
        t = tau * np.arange(int(round(t_end / tau)) + 1)
        dH = model.hamiltonian(rollout(model, x0, t, method=method, max_step=None)) - h0
        row = {
            "step": float(tau),
            "linf": float(np.max(np.abs(dH))),
            "l2": float(np.sqrt(trapezoid(dH**2, t))),
            "tv": float(np.sum(np.abs(np.diff(dH)))),
        }
        row["relative"] = row["linf"] / scale
        for norm in ("linf", "l2", "tv"):
            row[f"order_{norm}"] = (
                math.log(rows[-1][norm] / row[norm]) / math.log(rows[-1]["step"] / tau)
                if rows and row[norm] > 0
                else math.nan
            )
        rows.append(row)
        curves[tau] = (t, dH)
    return rows, curves


def format_table(rows, columns, formats=None):
    """Plain-text table of dicts, to print in an example's output."""
    formats = formats or {}
    cells = [
        [
            (formats.get(c, "{:.3e}").format(r[c]) if isinstance(r[c], float) else str(r[c]))
            for c in columns
        ]
        for r in rows
    ]
    widths = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(columns)]
    lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths))]
    lines += ["  ".join(v.rjust(w) for v, w in zip(row, widths)) for row in cells]
    return "\n".join(lines)


def figures_dir():
    """Where figures and result files go: ``examples/figures``.

    ``SK_HAMILTONIAN_FIGURES`` overrides it. A script run as ``python
    path/plot_x.py`` writes next to itself; under sphinx-gallery, which runs
    each example from its own directory, next to the working directory.
    """
    if os.environ.get(FIGURES_ENV):
        path = Path(os.environ[FIGURES_ENV])
    else:
        script = Path(sys.argv[0]) if sys.argv and sys.argv[0] else Path()
        base = script.resolve().parent if script.name.startswith("plot_") else Path.cwd()
        path = base / "figures"
    path.mkdir(parents=True, exist_ok=True)
    return path


def save_figure(fig, name):
    """Save ``fig`` as ``<figures_dir>/<name>.png`` (sphinx-gallery scrapes it too)."""
    fig.savefig(figures_dir() / f"{name}.png", dpi=110)


def save_results(name, results):
    """Write the measured numbers of an example to ``<figures_dir>/<name>.json``."""
    results = dict(results, quick_mode=quick_mode(), long_runs=long_runs())
    path = figures_dir() / f"{name}.json"
    path.write_text(json.dumps(results, indent=2, default=float, allow_nan=True))


def state_names(n_states):
    """Math-text names of the states ``p_1..p_d, q_1..q_d`` (``p, q`` for one pair)."""
    d = n_states // 2
    if d == 1:
        return ["$p$", "$q$"]
    return [f"${s}_{i}$" for s in "pq" for i in range(1, d + 1)]


def plot_errors(ax, t, errors, title="Relative error"):
    """Semi-log plot of ``label -> relative error over time``."""
    for label, err in errors.items():
        ax.semilogy(t, err, label=label)
    ax.set(xlabel="$t$", ylabel="relative error", title=title)
    ax.legend(fontsize="small")


def plot_errors_and_hamiltonian(system, t, trajectories, errors, sp, sp_label="SP"):
    """The paper's two-panel figure: relative errors, and Hamiltonians over time.

    The right panel shows ``H`` along the exact solution, ``H~ + C`` along the
    SP solution (``C`` from :func:`hamiltonian_offset`, so that the two are
    comparable) and the true ``H`` along the SP solution.
    """
    import matplotlib.pyplot as plt

    fig, (ax_err, ax_ham) = plt.subplots(1, 2, figsize=(11, 4))
    plot_errors(ax_err, t, errors)
    u_sp = trajectories[sp_label]
    plot_energy(t, {
        "$H(u(t))$, exact": system.hamiltonian(trajectories["exact"]),
        rf"$\tilde H(\tilde u(t)) + C$, {sp_label}": along(sp.hamiltonian, u_sp)
        + hamiltonian_offset(sp, system),
        rf"$H(\tilde u(t))$, {sp_label}": system.hamiltonian(u_sp),
    }, deviation=False, ax=ax_ham)
    ax_ham.set_title("Hamiltonian along the trajectories")
    fig.tight_layout()
    return fig


def plot_states(t, exact, approx, title, n_markers=120):
    """One panel per state: exact solution (black) and a learned one (circles).

    The learned curve carries about ``n_markers`` circles, as in the paper's
    figures, so that the exact curve stays visible.
    """
    import matplotlib.pyplot as plt

    names = state_names(exact.shape[1])
    fig, axes = plt.subplots(2, exact.shape[1] // 2, figsize=(10, 5.5), squeeze=False)
    every = max(1, t.shape[0] // n_markers)
    for i, ax in enumerate(axes.T.ravel()):
        ax.plot(t, exact[:, i], "k-", lw=1, label="exact")
        ax.plot(t, approx[:, i], "-o", lw=0.8, ms=3, mfc="none", markevery=every, label=title)
        ax.set(xlabel="$t$", ylabel=names[i])
    axes.flat[0].legend(fontsize="small")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def plot_phase(trajectories, pairs, title="Phase plots"):
    """Phase plots: one row per ``(i, j)`` state pair, one column per trajectory.

    ``trajectories`` maps a label to a trajectory of shape (n_times, n_states);
    panel ``(i, j)`` plots state ``j`` against state ``i``.
    """
    import matplotlib.pyplot as plt

    names = state_names(next(iter(trajectories.values())).shape[1])
    fig, axes = plt.subplots(
        len(pairs), len(trajectories), figsize=(3.4 * len(trajectories), 3.2 * len(pairs)),
        squeeze=False, sharex="row", sharey="row",
    )
    for row, (i, j) in zip(axes, pairs):
        for ax, (label, U) in zip(row, trajectories.items()):
            ax.plot(U[:, i], U[:, j], lw=0.6)
            ax.set(xlabel=names[i], ylabel=names[j], title=label)
    fig.suptitle(title)
    fig.tight_layout()
    return fig
