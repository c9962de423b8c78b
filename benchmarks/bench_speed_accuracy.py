"""Speed against accuracy: SP, non-SP and PySINDy on the paper's systems and beyond, in one run.

For each scene (a system, its training data and a polynomial degree) the three
methods are fitted on the same states and time derivatives, then simulated from
the paper's test state ``u0*`` and from a few fresh initial states, and compared
with the true solution. Everything is timed side by side in the same process,
so the printed ratios (e.g. SP fit time / PySINDy fit time) are comparable even
on a busy machine; absolute seconds are not the point.

Rows (``method``):

``SP-RK4``, ``SP-AVF``
    :class:`~sk_hamiltonian.HamiltonianRegressor`, one fit, simulated with
    classical RK4 and with the energy-conserving averaged vector field.
``SP-LEAPFROG``
    The same fit, with the explicit symplectic leapfrog (separable scenes).
``non-SP-RK4``
    :class:`~sk_hamiltonian.VectorFieldRegressor` (the paper's baseline), in
    the same model space as SP.
``SP-simpson-RK4``
    ``HamiltonianRegressor(fit_on="simpson")`` in the same space: Simpson's
    rule over pairs of consecutive observed steps (the layout's states, no
    derivative estimate), simulated with RK4; scenes with at least two
    intervals per trajectory.
``SP-sparse-RK4``, ``non-SP-STLSQ-RK4``
    The same regressors with ``threshold`` (STLSQ in the readable basis),
    chosen by ``GridSearchCV`` with the default score over
    ``_common.SPARSE_THRESHOLDS`` (:func:`_common.fit_sparse`), in the scene's
    sparse model space (the pendulum: periodic in ``q``, quadratic in ``p``,
    degree 8). ``fit_s`` is the final fit; ``select_s`` the whole search.
``PySINDy-best-RK4``
    PySINDy at its best reasonable configuration for the scene
    (``Scene.sindy_best``): a library fitted to the scene (sines and cosines
    of the angles times a polynomial in the momenta; polynomial of the true
    degree otherwise), ``SmoothedFiniteDifference`` on noisy data, bagging
    (``EnsembleOptimizer``, 20 models) and the STLSQ threshold chosen by
    3-fold cross-validation (:func:`_common.cv_sindy_threshold`;
    ``select_s``). Stepped by the same RK4 on its vectorized model; the time
    through ``predict`` is measured on at most ``PREDICT_STEPS`` steps and
    scaled to the horizon.
``PySINDy-poly-RK4``
    The labelled extra row: PySINDy's ``PolynomialLibrary`` at the scene's
    degree with plain ``STLSQ``, fed our derivatives, its threshold the largest
    of (0, 0.001, 0.01, 0.1) whose derivative error on held-out trajectories
    is within 1.25x of the best.
``PySINDy-LSODA``
    With ``--lsoda``: the polynomial model through PySINDy's own ``simulate``
    (``solve_ivp`` LSODA, rtol = atol = 1e-12, its defaults); from ``u0*``
    only, as it takes seconds per trajectory.

Outputs, in ``--output`` (default ``benchmarks/results/``):
``speed_accuracy.csv``, ``speed_ratios.csv``, ``speed_vs_accuracy.png`` and,
for the scenes beyond the paper alone, ``speed_vs_accuracy_scenes.png``
(``--replot`` redraws the charts from the CSV).

``--front`` runs a sweep instead, on the paper's scenes: SP and non-SP at
several degrees (``FRONT_DEGREES``) and PySINDy at several STLSQ thresholds
(``FRONT_THRESHOLDS``, library degree of the scene), each simulated with RK4
from ``u0*`` and the fresh states. It writes ``speed_front.csv`` and
``speed_vs_accuracy_front.png``: one line per method per scene, error at
``T = 20`` against fit + simulation time, so each method is seen as a front
over its own knob rather than as one point. PySINDy's simulation time there
is RK4 on its vectorized model (:class:`_common.SindyField`), not through
``predict`` (about 100 times slower), which favours PySINDy.

Run ``python benchmarks/bench_speed_accuracy.py`` (see ``benchmarks/README.md``
for the time it takes) or with ``--quick`` (a smoke run: two paper scenes and
a four-particle chain).
"""

import os

# Pin BLAS before numpy is imported: timings must not depend on how many
# threads other users leave free, and one thread is what a fair per-core
# comparison of the three methods needs.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

import _common as C  # noqa: E402
from sk_hamiltonian import (  # noqa: E402
    DomainWarning,
    HamiltonianRegressor,
    SimulationError,
    VectorFieldRegressor,
)

# The paper's settings (M, J, n, noise) with dt = 0.01 (the paper gives none).
# Sparse rows: the pendulum in its periodic mechanical space (H = p^2/2 -
# g cos q has two terms there); PySINDy-best with the matching library (sines
# and cosines of q up to frequency 3 times 1, p, p^2). Henon-Heiles and Cherry
# are polynomial: the scene's space, and PySINDy's polynomial library of
# degree 3 (the true vector fields have degree 2).
PENDULUM_SPARSE = dict(sparse_degree=8,
                       sparse_space=dict(periodic=[False, True], momentum_degree=2),
                       sindy_best=dict(degree=2, fourier=3, periodic=[False, True]))
POLYNOMIAL_BEST = dict(sindy_best=dict(degree=3))
SCENES = [
    C.Scene("pendulum 8% noise", "single_pendulum", 6, 500, 40, noise=0.08, **PENDULUM_SPARSE),
    C.Scene("pendulum clean", "single_pendulum", 6, 500, 40, **PENDULUM_SPARSE),
    C.Scene("Henon-Heiles", "henon_heiles", 3, 500, 2, **POLYNOMIAL_BEST),
    C.Scene("Cherry", "cherry", 3, 500, 2, **POLYNOMIAL_BEST),
]
# Scenes beyond the paper, each in the model space its physics suggests (SP and
# non-SP alike).
# - Double pendulum (unit masses and rods, g = 1), both angles over the whole
#   circle, momenta drawn in [-1, 1]: Fourier in the angles, quadratic in the
#   momenta. Its u0* = (0, 0, 0, 2) reaches |p1| = 2.1, outside the data, so
#   the test box (which fresh test orbits must stay in) is wider in p: the
#   rollouts also test extrapolation in the momenta. PySINDy gets its
#   polynomial library of the same degree and, fairer here, a library of the
#   same shape as ours (quadratic in p times sines and cosines of each angle up
#   to frequency 5, 726 features per component).
# - FPUT-beta chain, 8 particles, fixed ends: separable and pairwise (400
#   terms instead of 4 844), bursts drawn in half the default box, where the
#   smooth u0* lives. PySINDy's library has degree 3, the degree of the true
#   vector field (969 features per component; degree 4 would be 4 845).
# Both have 3 000 bursts: PySINDy gets their states as one array (the same
# least squares, see _common.fit_sindy), as a list its fit alone took ~400 s.
# Its predict costs ~66 ms a call with these libraries, so RK4 through predict
# is timed on 50 steps and scaled, and its own LSODA simulate (predict at
# every evaluation; it ran for minutes towards a blow-up) is left out.
NEW_SCENE_SINDY = dict(sindy_one_array=True, sindy_predict_steps=50, sindy_lsoda=False)
DOUBLE_PENDULUM_FULL = dict(
    params=dict(g=1.0), space=dict(periodic=True, momentum_degree=2),
    sindy_best=dict(degree=2, fourier=5),
    test_domain=[[-2.5, 2.5], [-2.5, 2.5], [-np.pi, np.pi], [-np.pi, np.pi]],
    **NEW_SCENE_SINDY)
FPUT = dict(params=dict(n_particles=8), space=dict(separable=True, max_interaction=2),
            data_fraction=0.5, sindy_degree=3, sindy_best=dict(degree=3), **NEW_SCENE_SINDY)
BEYOND_PAPER = [
    C.Scene("double pendulum full circle", "double_pendulum_full_circle", 10, 3000, 2,
            **DOUBLE_PENDULUM_FULL),
    C.Scene("FPUT chain 8", "fput_chain", 4, 3000, 2, **FPUT),
]
PAPER_SCENES = list(SCENES)
SCENES += BEYOND_PAPER
# The quick run keeps one scene beyond the paper, the cheapest (a short chain):
# the double pendulum's trigonometric AVF rollouts alone would take half the
# smoke run's budget.
QUICK_SCENES = [
    C.Scene("pendulum 8% noise", "single_pendulum", 6, 100, 40, noise=0.08, **PENDULUM_SPARSE),
    C.Scene("Henon-Heiles", "henon_heiles", 3, 100, 2, **POLYNOMIAL_BEST),
]
QUICK_BEYOND_PAPER = [
    C.Scene("FPUT chain 4", "fput_chain", 4, 100, 2, **dict(FPUT, params=dict(n_particles=4))),
]
QUICK_SCENES += QUICK_BEYOND_PAPER
# The front sweep: the knob each method has (SP, non-SP: degree; PySINDy: the
# STLSQ threshold at the scene's degree). Degrees stop where the fits become
# ill-conditioned or slow enough to dominate the run.
FRONT_DEGREES = {"single_pendulum": (2, 4, 6, 8, 10), "henon_heiles": (2, 3, 4, 5, 6),
                 "cherry": (2, 3, 4, 5, 6)}
FRONT_THRESHOLDS = (0.0, 0.001, 0.01, 0.1, 0.3, 1.0)
FRONT_COLUMNS = ["scene", "method", "knob", "n_params", "fit_s", "sim_s", "total_s",
                 "err_T20", "fresh_err_T20", "fresh_failed", "n_fresh", "note"]
HORIZONS = (10.0, 20.0)
THRESHOLDS = (0.0, 0.001, 0.01, 0.1)  # PySINDy's default is 0.1
# RK4 through PySINDy's predict (about 3 ms a call whatever the batch) is
# timed on at most this many steps and scaled to the horizon.
PREDICT_STEPS = 200

COLUMNS = [
    "scene", "method", "n_params", "cond", "fit_s", "sim_s", "total_s", "select_s",
    "sim_vectorized_s",
    "err_T10", "err_T20", "fresh_err_T10", "fresh_err_T20", "fresh_failed", "n_fresh",
    "fail_time", "energy_drift", "model_energy_drift", "note",
]
RATIO_COLUMNS = ["scene", "ratio", "value"]


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="small smoke run (< 30 s): 2 scenes, M=100, coarser steps")
    parser.add_argument("--output", type=Path,
                        default=Path(__file__).resolve().parent / "results",
                        help="directory for CSV and PNG outputs")
    parser.add_argument("--no-sindy", action="store_true", help="skip PySINDy even if installed")
    parser.add_argument("--repeats", type=int, default=None,
                        help="timing repeats, best kept (default 3, quick 1)")
    parser.add_argument("--n-fresh", type=int, default=None,
                        help="fresh test initial states (default 8, quick 2)")
    parser.add_argument("--scenes", choices=("all", "paper", "beyond"), default="all",
                        help="which scenes of the full run: the paper's, those beyond it, or all "
                        "(the scenes beyond the paper alone fit in one shorter run)")
    parser.add_argument("--front", action="store_true",
                        help="sweep degrees (SP, non-SP) and thresholds (PySINDy) on the "
                        "paper's scenes; writes speed_front.csv and speed_vs_accuracy_front.png")
    parser.add_argument("--replot", action="store_true",
                        help="only redraw the charts from speed_accuracy.csv in --output")
    parser.add_argument("--lsoda", action="store_true",
                        help="also run PySINDy's own simulate (LSODA) from u0*, seconds per scene")
    return parser.parse_args(argv)


def model_energy(model, Y):
    """Drift of the learned Hamiltonian along its own trajectory (SP only)."""
    H = model.hamiltonian(Y)
    return float(np.max(np.abs(H - H[0])))


def accuracy(Y, fail_time, truth, t, system, n_fresh_found):
    """Error columns from rollouts of [u0*, fresh...] against the truth."""
    row = {}
    for T in HORIZONS:
        err = C.relative_error(Y, truth, t, T, system.periodic)
        row[f"err_T{T:g}"] = err[0]
        fresh = err[1:]
        # Median: one diverging state must not hide how the others did, and
        # inf (failure) still wins when most of them failed.
        row[f"fresh_err_T{T:g}"] = float(np.median(fresh)) if fresh.size else np.nan
    row["fresh_failed"] = int(np.sum(np.isfinite(fail_time[1:]) | ~np.isfinite(
        C.relative_error(Y[1:], truth[1:], t, HORIZONS[-1], system.periodic))))
    row["n_fresh"] = n_fresh_found
    row["fail_time"] = float(fail_time[0])
    with np.errstate(all="ignore"):
        drift = np.abs(system.hamiltonian(Y[0]) - system.hamiltonian(truth[0, 0]))
    row["energy_drift"] = float(np.max(drift)) if np.isfinite(drift).all() else np.inf
    return row


def time_simulation(model, x0, t, method, repeats):
    """Wall time of ``model.simulate(u0*)`` over the whole horizon (NaN if it fails)."""
    try:
        seconds, _ = C.best_time(lambda: model.simulate(x0, t, method=method), repeats)
    except SimulationError:
        return np.nan
    return seconds


def run_scene(scene, args, ps):
    """All rows of one scene."""
    system, Xt, deriv_s, X_raw = C.make_data(scene, raw=True)
    h = 0.02 if args.quick else scene.dt
    test_domain = scene.test_domain if scene.test_domain is not None else scene.data_domain(system)
    x0, t, truth = C.test_states(system, args.n_fresh, HORIZONS[-1], h, seed=scene.seed + 1,
                                 domain=test_domain)
    n_fresh = x0.shape[0] - 1
    u0 = system.initial_state
    rows = []

    def add(method, model, fit_s, sim_s, Y, fail_time, n_params, cond, note=""):
        row = dict(scene=scene.label, method=method, n_params=n_params, cond=cond,
                   fit_s=fit_s, sim_s=sim_s, total_s=fit_s + sim_s, select_s=np.nan,
                   sim_vectorized_s=np.nan, note=note)
        row.update(accuracy(Y, fail_time, truth, t, system, n_fresh))
        row["model_energy_drift"] = (
            model_energy(model, Y[0]) if isinstance(model, HamiltonianRegressor)
            and np.isfinite(Y[0]).all() else np.nan
        )
        rows.append(row)

    space = scene.model_params(system)
    # A separable model also has the explicit symplectic leapfrog.
    sp_methods = ("rk4", "avf", "leapfrog") if space.get("separable") else ("rk4", "avf")
    for name, cls, methods in (("SP", HamiltonianRegressor, sp_methods),
                               ("non-SP", VectorFieldRegressor, ("rk4",))):
        fit_s, model = C.best_time(lambda: cls(scene.degree, **space).fit(Xt), args.repeats)
        for method in methods:
            sim_s = time_simulation(model, u0, t, method, args.repeats)
            Y, fail_time = C.rollout(model, x0, t, method)
            add(f"{name}-{method.upper()}", model, deriv_s + fit_s, sim_s, Y, fail_time,
                int(np.count_nonzero(model.coef_)), float(model.cond_))

    # The Simpson fit (pairs of consecutive observed steps, no derivative
    # estimate), where trajectories have at least three samples.
    if scene.n_intervals >= 2:
        fit_s, model = C.best_time(
            lambda: HamiltonianRegressor(scene.degree, fit_on="simpson", **space).fit(Xt),
            args.repeats)
        sim_s = time_simulation(model, u0, t, "rk4", args.repeats)
        Y, fail_time = C.rollout(model, x0, t, "rk4")
        add("SP-simpson-RK4", model, deriv_s + fit_s, sim_s, Y, fail_time,
            int(np.count_nonzero(model.coef_)), float(model.cond_))

    # The sparse rows: threshold chosen by cross-validation on the training
    # data, in the scene's sparse space.
    sparse_space = scene.model_params(system, sparse=True)
    sparse_degree = scene.sparse_degree or scene.degree
    for name, cls in (("SP-sparse", HamiltonianRegressor), ("non-SP-STLSQ", VectorFieldRegressor)):
        # The smoke run searches a shorter grid on 2 folds.
        model, _, select_s, refit_s, note = C.fit_sparse(
            cls(sparse_degree, **sparse_space), Xt,
            C.SPARSE_THRESHOLDS[::2] if args.quick else C.SPARSE_THRESHOLDS,
            cv=2 if args.quick else 5)
        sim_s = time_simulation(model, u0, t, "rk4", args.repeats)
        Y, fail_time = C.rollout(model, x0, t, "rk4")
        add(f"{name}-RK4", model, deriv_s + refit_s, sim_s, Y, fail_time, int(model.n_terms_),
            float(model.cond_), f"{note}; degree {sparse_degree}, space {sparse_space}")
        rows[-1]["select_s"] = select_s

    if ps is None:
        return rows
    best = sindy_best_row(scene, args, ps, system, X_raw, Xt, x0, t, u0, add, rows)
    print(f"#   PySINDy-best: {best['note']}", flush=True)
    model, threshold, polynomial = sindy_rows(scene, args, ps, system, Xt, deriv_s, x0, t, u0,
                                              "PySINDy-poly-RK4", None, add, rows)
    # PySINDy's own simulate, for the polynomial model.
    if args.lsoda and not args.quick and scene.sindy_lsoda:
        start = time.perf_counter()
        Y_own = np.asarray(model.simulate(u0, t))
        sim_s = time.perf_counter() - start
        Y = np.full((x0.shape[0], t.size, x0.shape[1]), np.nan)
        Y[0, : Y_own.shape[0]] = Y_own  # solve_ivp stops early on failure
        fail_time = np.full(x0.shape[0], np.nan)
        fail_time[0] = t[Y_own.shape[0]] if Y_own.shape[0] < t.size else np.inf
        row_note = f"threshold={threshold:g}; its simulate(); u0* only"
        add("PySINDy-LSODA", None, polynomial["fit_s"], sim_s, Y, fail_time,
            polynomial["n_params"], polynomial["cond"], row_note)
        for key in ("fresh_err_T10", "fresh_err_T20", "fresh_failed"):
            rows[-1][key] = np.nan  # not run from fresh states (seconds per trajectory)
    return rows


def sindy_best_row(scene, args, ps, system, X_raw, Xt, x0, t, u0, add, rows):
    """PySINDy at its best configuration for the scene; adds its row and returns it."""
    cfg = dict(scene.sindy_best)
    degree, fourier = cfg.get("degree", scene.degree), cfg.get("fourier")
    periodic = np.asarray(cfg.get("periodic", system.periodic), dtype=bool)
    states, derivatives, deriv_s, how = C.sindy_best_data(ps, scene, X_raw, Xt)
    start = time.perf_counter()
    threshold, scores = C.cv_sindy_threshold(
        ps, states, derivatives, scene.dt, degree, fourier, periodic,
        thresholds=C.SINDY_BEST_THRESHOLDS[::2] if args.quick else C.SINDY_BEST_THRESHOLDS,
        folds=2 if args.quick else 3, one_array=scene.sindy_one_array)
    n_models = 5 if args.quick else C.SINDY_ENSEMBLE_MODELS
    fit_s, model = C.best_time(
        lambda: C.fit_sindy_best(ps, states, derivatives, scene.dt, threshold, degree, fourier,
                                 periodic, n_models=n_models, one_array=scene.sindy_one_array),
        args.repeats)
    select_s = time.perf_counter() - start
    library = dict(fourier=fourier, periodic=periodic)
    field = C.SindyField(model, np.concatenate(states)[:200], **library)
    cond = C.design_condition(model, Xt, field)
    library_note = (f"degree {degree} in p x sin/cos up to frequency {fourier} per angle"
                    if fourier is not None else f"PolynomialLibrary(degree={degree})")
    note = (f"threshold={threshold:g} by 3-fold CV (mean held-out MSE " + ", ".join(
        f"{k:g}: {v:.3g}" for k, v in scores.items()) + f"); {library_note}; {how}; "
        f"EnsembleOptimizer(bagging, {n_models} models)")
    sindy_simulate(scene, args, model, field, x0, t, u0, "PySINDy-best-RK4", deriv_s + fit_s,
                   cond, note, add, rows)
    rows[-1]["select_s"] = select_s
    return rows[-1]


def sindy_simulate(scene, args, model, field, x0, t, u0, label, fit_s, cond, note, add, rows):
    """Roll a fitted PySINDy model out (vectorized RK4), time it through predict; adds the row."""
    Y, fail_time = C.rollout(field, x0, t)
    if args.quick:
        # predict costs ~3 ms a call: too slow for a smoke run, so time the
        # (identical) vectorized evaluation instead and say so.
        sim_s, _ = C.best_time(lambda: C.rk4_rollout(field, u0, t), args.repeats)
        note += "; quick: timed vectorized RK4, not predict"
    else:
        def predict(y):
            # predict refuses non-finite states and features (sklearn's check):
            # a model that blows up inside an RK4 step then fails like the
            # vectorized one, with NaN.
            try:
                return np.asarray(model.predict(y))
            except ValueError:
                return np.full_like(y, np.nan)

        steps = min(scene.sindy_predict_steps or PREDICT_STEPS, t.size - 1)
        sim_s, (Y_predict, _) = C.best_time(
            lambda: C.rk4_rollout(predict, u0, t[: steps + 1]), 1)
        sim_s *= (t.size - 1) / steps
        head = Y[0, : steps + 1]
        gap = np.nanmax(np.abs(Y_predict[0] - head)) if np.isfinite(head).any() else 0.0
        note += f"; |RK4(predict) - RK4(vectorized)| = {gap:.1e}"
        if steps < t.size - 1:
            note += f" (predict timed on {steps} steps, scaled to {t.size - 1})"
    add(label, None, fit_s, sim_s, Y, fail_time, field.n_params, cond, note)
    # The same model and RK4 without predict's per-call overhead: what the
    # model itself costs, to separate it from the API.
    rows[-1]["sim_vectorized_s"], _ = C.best_time(lambda: C.rk4_rollout(field, u0, t),
                                                  args.repeats)


def sindy_rows(scene, args, ps, system, Xt, deriv_s, x0, t, u0, label, fourier, add, rows):
    """Tune, fit, time and roll out one PySINDy library; adds its row.

    Returns
    -------
    model : pysindy.SINDy
    threshold : float
    row : dict
        The row added.
    """
    degree = scene.sindy_degree or scene.degree
    library = dict(fourier=fourier, periodic=system.periodic)
    if fourier is not None:
        degree = scene.space.get("momentum_degree", degree)  # degree in the momenta
    threshold, scores = C.tune_sindy_threshold(ps, Xt, degree, scene.dt,
                                               THRESHOLDS[::2] if args.quick else THRESHOLDS,
                                               one_array=scene.sindy_one_array, **library)
    fit_s, model = C.best_time(
        lambda: C.fit_sindy(ps, Xt, degree, threshold, scene.dt,
                            one_array=scene.sindy_one_array, **library), args.repeats)
    field = C.SindyField(model, np.concatenate(C.split_layout(Xt)[0])[:200], **library)
    cond = C.design_condition(model, Xt, field)
    note = f"threshold={threshold:g} (held-out MSE " + ", ".join(
        f"{k:g}: {v:.3g}" for k, v in scores.items()) + ")"
    if fourier is not None:
        note += f"; library: degree {degree} in p x sin/cos up to frequency {fourier} per angle"
    elif degree != scene.degree:
        note += f"; PolynomialLibrary(degree={degree})"
    if scene.sindy_one_array:
        note += "; states as one array"
    sindy_simulate(scene, args, model, field, x0, t, u0, label, deriv_s + fit_s, cond, note,
                   add, rows)
    return model, threshold, rows[-1]


def ratios(rows):
    """Same-run ratios per scene: < 1 means SP is faster / more accurate."""
    out = []
    scenes = dict.fromkeys(r["scene"] for r in rows)
    for scene in scenes:
        by = {r["method"]: r for r in rows if r["scene"] == scene}

        def ratio(label, a, b, key):
            if a in by and b in by:
                with np.errstate(all="ignore"):
                    value = np.float64(by[a][key]) / np.float64(by[b][key])
                out.append(dict(scene=scene, ratio=label, value=float(value)))

        ratio("fit: SP / non-SP", "SP-RK4", "non-SP-RK4", "fit_s")
        ratio("fit: SP / PySINDy-poly", "SP-RK4", "PySINDy-poly-RK4", "fit_s")
        ratio("simulate: SP-AVF / SP-RK4", "SP-AVF", "SP-RK4", "sim_s")
        ratio("simulate: SP-RK4 / non-SP-RK4", "SP-RK4", "non-SP-RK4", "sim_s")
        ratio("simulate: SP-RK4 / PySINDy-poly-RK4(predict)", "SP-RK4", "PySINDy-poly-RK4",
              "sim_s")
        ratio("simulate: SP-RK4 / PySINDy-LSODA", "SP-RK4", "PySINDy-LSODA", "sim_s")
        ratio("simulate: SP-sparse / SP-RK4 (dense)", "SP-sparse-RK4", "SP-RK4", "sim_s")
        ratio("err T=20 u0*: SP-RK4 / non-SP", "SP-RK4", "non-SP-RK4", "err_T20")
        ratio("err T=20 fresh: SP-RK4 / non-SP", "SP-RK4", "non-SP-RK4", "fresh_err_T20")
        # The sparse rows against each other and against the dense fit.
        for key, where in (("err_T20", "u0*"), ("fresh_err_T20", "fresh")):
            for other in ("SP-RK4", "non-SP-STLSQ-RK4", "PySINDy-best-RK4",
                          "PySINDy-poly-RK4"):
                ratio(f"err T=20 {where}: SP-sparse / {other.replace('-RK4', '')}",
                      "SP-sparse-RK4", other, key)
        ratio("fit: SP-sparse / PySINDy-best (selection excluded)", "SP-sparse-RK4",
              "PySINDy-best-RK4", "fit_s")
        ratio("fit + selection: SP-sparse / PySINDy-best", "SP-sparse-RK4", "PySINDy-best-RK4",
              "select_s")
        for key, where in (("err_T20", "u0*"), ("fresh_err_T20", "fresh")):
            for other in ("SP-RK4", "PySINDy-best-RK4"):
                ratio(f"err T=20 {where}: SP-simpson / {other.replace('-RK4', '')}",
                      "SP-simpson-RK4", other, key)
        # Separable scenes: the explicit symplectic method against RK4.
        ratio("simulate: SP-LEAPFROG / SP-RK4", "SP-LEAPFROG", "SP-RK4", "sim_s")
    return out


MARKERS = {"SP-RK4": "o", "SP-AVF": "s", "SP-LEAPFROG": "P", "non-SP-RK4": "^",
           "SP-sparse-RK4": "p", "SP-simpson-RK4": "X", "non-SP-STLSQ-RK4": "<", "PySINDy-best-RK4": "*",
           "PySINDy-poly-RK4": "D", "PySINDy-LSODA": "v"}


def plot_charts(rows, output):
    """``speed_vs_accuracy.png`` of every scene, and ``speed_vs_accuracy_scenes.png``
    of the scenes beyond the paper when the run has them."""
    plot(rows, output / "speed_vs_accuracy.png")
    beyond = {scene.label for scene in BEYOND_PAPER + QUICK_BEYOND_PAPER}
    subset = [r for r in rows if r["scene"] in beyond]
    if subset:
        plot(subset, output / "speed_vs_accuracy_scenes.png")


def read_rows(path):
    """Rows of a ``speed_accuracy.csv`` written by this script (for ``--replot``)."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    for row in rows:
        for key, value in row.items():
            if key not in ("scene", "method", "note"):
                row[key] = float(value) if value not in ("", "nan") else np.nan
    return rows


def plot(rows, path):
    """Error against total time (fit + simulate), log-log; failures marked."""
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    colors = dict(zip(scenes, plt.cm.tab10.colors))
    fig, axes = plt.subplots(1, 2, figsize=(15, 5.2), sharey=True)
    for ax, key, title in ((axes[0], "err_T20", "from the paper's u0*"),
                           (axes[1], "fresh_err_T20", "median over fresh initial states")):
        finite = [r[key] for r in rows if np.isfinite(r[key]) and r[key] > 0]
        top = 10 ** np.ceil(np.log10(max(finite))) * 3 if finite else 10.0
        for r in rows:
            x, y = r["total_s"], r[key]
            if not np.isfinite(x) or np.isnan(y):
                continue  # not run (e.g. LSODA from fresh states)
            color = colors[r["scene"]]
            if np.isinf(y):
                ax.scatter(x, top, marker="x", s=90, color=color, linewidths=2.5, zorder=3)
                ax.annotate("failed", (x, top), textcoords="offset points", xytext=(4, 4),
                            fontsize=7, color=color)
            else:
                ax.scatter(x, y, marker=MARKERS.get(r["method"], "o"), s=60, color=color,
                           edgecolors="k", linewidths=0.5, zorder=3)
        ax.axhline(top, color="0.6", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("fit + simulate time to T=20 [s] (log)")
        ax.set_title(f"relative error on [0, 20], {title}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("relative trajectory error (log); x at the top = failed")
    method_handles = [plt.Line2D([], [], marker=m, ls="", color="0.3", label=k)
                      for k, m in MARKERS.items() if any(r["method"] == k for r in rows)]
    scene_handles = [plt.Line2D([], [], marker="o", ls="", color=colors[s], label=s)
                     for s in scenes]
    fig.legend(handles=method_handles + scene_handles, fontsize=8, loc="center right")
    fig.suptitle("Speed vs accuracy (lower left is better); one run, BLAS pinned to 1 thread",
                 fontsize=11)
    fig.tight_layout(rect=(0, 0, 0.86, 1))
    fig.savefig(path, dpi=120)
    plt.close(fig)


def front_scene(scene, args, ps):
    """Rows of the front sweep on one scene: one per (method, degree or threshold).

    A fit that raises (e.g. fewer equations than unknowns) or a rollout that
    blows up is a row with infinite error, so failures are drawn, not dropped.
    """
    system, Xt, deriv_s = C.make_data(scene)
    x0, t, truth = C.test_states(system, args.n_fresh, HORIZONS[-1], scene.dt,
                                 seed=scene.seed + 1, domain=scene.data_domain(system))
    u0 = system.initial_state
    rows = []

    def add(method, knob, n_params, fit_s, sim_s, Y, note=""):
        err = C.relative_error(Y, truth, t, HORIZONS[-1], system.periodic)
        fresh = err[1:]
        rows.append(dict(scene=scene.label, method=method, knob=knob, n_params=n_params,
                         fit_s=fit_s, sim_s=sim_s,
                         total_s=fit_s + sim_s if np.isfinite(sim_s) else fit_s,
                         err_T20=err[0],
                         fresh_err_T20=float(np.median(fresh)) if fresh.size else np.nan,
                         fresh_failed=int(np.sum(~np.isfinite(fresh))),
                         n_fresh=fresh.size, note=note))

    failed = np.full((x0.shape[0], t.size, x0.shape[1]), np.nan)
    for name, cls in (("SP-RK4", HamiltonianRegressor), ("non-SP-RK4", VectorFieldRegressor)):
        for degree in FRONT_DEGREES[scene.system]:
            try:
                fit_s, model = C.best_time(lambda: cls(degree).fit(Xt), args.repeats)
            except Exception as error:  # a failed fit is a point of the front
                add(name, degree, 0, np.nan, np.nan, failed, f"fit failed: {error}"[:120])
                continue
            sim_s = time_simulation(model, u0, t, "rk4", args.repeats)
            Y, _ = C.rollout(model, x0, t, "rk4")
            # A rollout from u0* that fails has no simulation time: the point
            # is drawn at its fit time (as a failure) and the CSV says NaN.
            add(name, degree, int(np.count_nonzero(model.coef_)), deriv_s + fit_s, sim_s, Y,
                "" if np.isfinite(sim_s) else "simulation from u0* failed")
    if ps is None:
        return rows
    for threshold in FRONT_THRESHOLDS:
        fit_s, model = C.best_time(
            lambda: C.fit_sindy(ps, Xt, scene.degree, threshold, scene.dt), args.repeats)
        field = C.SindyField(model, np.concatenate(C.split_layout(Xt)[0])[:200])
        sim_s, _ = C.best_time(lambda: C.rk4_rollout(field, u0, t), args.repeats)
        Y, _ = C.rollout(field, x0, t)
        add("PySINDy-RK4", threshold, field.n_params, deriv_s + fit_s, sim_s, Y,
            f"degree {scene.degree}; vectorized RK4")
    return rows


def _two_and_five(x, _):
    """Tick label ``x`` if it is 2 or 5 times a power of ten, else none."""
    mantissa = x / 10 ** np.floor(np.log10(x))
    return f"{x:g}" if np.isclose(mantissa, 2) or np.isclose(mantissa, 5) else ""


FRONT_STYLE = {"SP-RK4": ("o", "-", "C0"), "non-SP-RK4": ("^", "--", "C1"),
               "PySINDy-RK4": ("D", ":", "C2")}


def plot_front(rows, path):
    """One panel per scene, one line per method over its knob; failures at the top."""
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    ncols = 2
    nrows = -(-len(scenes) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(13, 5.2 * nrows), squeeze=False)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    for ax, scene in zip(axes.flat, scenes):
        here = [r for r in rows if r["scene"] == scene]
        finite = [r["err_T20"] for r in here if np.isfinite(r["err_T20"]) and r["err_T20"] > 0]
        top = 10 ** np.ceil(np.log10(max(finite))) * 3 if finite else 10.0
        times = [r["total_s"] for r in here if np.isfinite(r["total_s"])]
        for method, (marker, ls, color) in FRONT_STYLE.items():
            line = [r for r in here if r["method"] == method]
            if not line:
                continue
            xs = [r["total_s"] if np.isfinite(r["total_s"]) else min(times) for r in line]
            ys = [r["err_T20"] if np.isfinite(r["err_T20"]) else top for r in line]
            # The line joins the knob's values in order through the points
            # that did not fail; failures stand alone at the top.
            ok = [(x, y) for r, x, y in zip(line, xs, ys) if np.isfinite(r["err_T20"])]
            ax.plot(*(zip(*ok) if ok else ([], [])), ls=ls, color=color, lw=1.5, label=method)
            for r, x, y in zip(line, xs, ys):
                bad = not np.isfinite(r["err_T20"])
                ax.scatter(x, y, marker="x" if bad else marker, s=90 if bad else 55,
                           color=color, edgecolors=None if bad else "k",
                           linewidths=2.5 if bad else 0.5, zorder=3)
                knob = (f"n={int(r['knob'])}" if method != "PySINDy-RK4"
                        else f"thr={r['knob']:g}")
                ax.annotate(knob, (x, y), textcoords="offset points", xytext=(5, 3),
                            fontsize=9, color=color)
        ax.axhline(top, color="0.6", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        # Matplotlib labels every minor tick of a narrow log axis, and they
        # overlap; label 2 and 5 of each decade only.
        ax.xaxis.set_minor_formatter(matplotlib.ticker.FuncFormatter(_two_and_five))
        ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda x, _: f"{x:g}"))
        ax.set_title(scene, fontsize=13)
        ax.set_xlabel("fit + RK4 simulation to T=20 [s] (log)", fontsize=11)
        ax.set_ylabel("relative error on [0, 20] from u0* (log)", fontsize=11)
        ax.tick_params(labelsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=10, loc="best")
    fig.suptitle("Speed vs accuracy fronts: SP and non-SP over degrees n, PySINDy over its "
                 "STLSQ threshold (x at the dotted line = failed); one run, BLAS on 1 thread",
                 fontsize=12)
    fig.tight_layout(rect=(0, 0, 1, 0.96))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    args = parse_args(argv)
    # The full-circle pendulum's test orbits leave the momentum box of its data
    # by design (extrapolation in p is part of that test); the rollouts already
    # ignore the warning, and so do the timed runs.
    warnings.filterwarnings("ignore", category=DomainWarning)
    args.repeats = args.repeats or (1 if args.quick else 3)
    args.n_fresh = args.n_fresh if args.n_fresh is not None else (2 if args.quick else 8)
    args.output.mkdir(parents=True, exist_ok=True)
    if args.replot:
        if args.front:
            plot_front(read_rows(args.output / "speed_front.csv"),
                       args.output / "speed_vs_accuracy_front.png")
            print(f"# redrew the front chart in {args.output}")
            return 0
        plot_charts(read_rows(args.output / "speed_accuracy.csv"), args.output)
        print(f"# redrew the charts in {args.output}")
        return 0
    ps, reason = (None, "disabled by --no-sindy") if args.no_sindy else C.sindy_status()
    start = time.perf_counter()
    print(f"# bench_speed_accuracy {'--quick ' if args.quick else ''}"
          f"{datetime.datetime.now().isoformat(timespec='seconds')}; "
          f"python {platform.python_version()}, numpy {np.__version__}, "
          f"{os.cpu_count()} cores, BLAS threads pinned to 1")
    if ps is None:
        print(f"# PySINDy rows skipped: {reason}")
    else:
        print(f"# baseline: {reason}")
    if args.front:
        rows = []
        scenes = QUICK_SCENES[:2] if args.quick else PAPER_SCENES
        for scene in scenes:
            print(f"# front {scene.label}: M={scene.n_trajectories}, J={scene.n_intervals}, "
                  f"dt={scene.dt}, noise={scene.noise}, degrees "
                  f"{FRONT_DEGREES[scene.system]}, thresholds {FRONT_THRESHOLDS}", flush=True)
            rows += front_scene(scene, args, ps)
        C.write_csv(args.output / "speed_front.csv", rows, FRONT_COLUMNS)
        plot_front(rows, args.output / "speed_vs_accuracy_front.png")
        C.print_table(rows, FRONT_COLUMNS[:-1])
        for r in rows:
            if r["note"] and "failed" in r["note"]:
                print(f"# {r['scene']} / {r['method']} {r['knob']}: {r['note']}")
        print(f"# wrote {args.output}/speed_front.csv, speed_vs_accuracy_front.png "
              f"in {time.perf_counter() - start:.0f} s")
        return 0
    rows = []
    scenes = QUICK_SCENES if args.quick else {
        "all": SCENES, "paper": PAPER_SCENES, "beyond": BEYOND_PAPER}[args.scenes]
    for scene in scenes:
        print(f"# scene {scene.label}: M={scene.n_trajectories}, J={scene.n_intervals}, "
              f"dt={scene.dt}, noise={scene.noise}, degree={scene.degree}", flush=True)
        rows += run_scene(scene, args, ps)
    ratio_rows = ratios(rows)
    C.write_csv(args.output / "speed_accuracy.csv", rows, COLUMNS)
    C.write_csv(args.output / "speed_ratios.csv", ratio_rows, RATIO_COLUMNS)
    plot_charts(rows, args.output)
    print()
    C.print_table(rows, ["scene", "method", "n_params", "cond", "fit_s", "sim_s",
                         "err_T10", "err_T20", "fresh_err_T20", "fresh_failed", "energy_drift",
                         "model_energy_drift"])
    print()
    C.print_table(ratio_rows, RATIO_COLUMNS)
    notes = [(r["scene"], r["method"], r["note"]) for r in rows if r.get("note")]
    for scene, method, note in notes:
        print(f"# {scene} / {method}: {note}")
    print(f"# wrote {args.output}/speed_accuracy.csv, speed_ratios.csv, speed_vs_accuracy.png "
          f"in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
