"""Stability: where SP, non-SP and PySINDy break, with the failures recorded, not hidden.

Five experiments, each a sweep of one condition under which learning methods
fail; every method is fitted on the same data and simulated from the same
initial states (the paper's ``u0*`` and fresh states whose *true* solution
stays in the domain, so a failure is the model's, not the truth's):

``noise``
    Henon-Heiles (M = 500, J = 40 so that the paper's Q = 5 de-noising
    applies, n = 3), relative noise 0 ... 20 % (finite differences when clean).
    Not the pendulum: its J = 40 trajectories leave the paper's box and inflate
    the fitted domain, so its error is ~0.5 at T = 20 even on clean data and
    noise is not what breaks it.
``n_trajectories``
    Single pendulum, clean, J = 2, n = 6, M from 1000 down to below the number
    of unknowns (SP: 27 unknowns, 6 equations per trajectory; non-SP and
    PySINDy: 28 per component, 3 per trajectory). Records ``cond_`` and the
    sample size the paper's Corollary 3.4 asks for.
``degree``
    Single pendulum, clean, J = 2, M = 30: degree 2 ... 14, i.e. up to and past
    the point where the data no longer determine the model.
``long_horizon``
    Henon-Heiles at 5 % and 20 % noise (as in ``noise``), simulated to
    T = 200 from states whose true orbits stay bounded: when does each learned
    trajectory leave the training box (escape) or become non-finite
    (``SimulationError``, recorded as the failure time)? Errors at T = 200 are
    O(1) for every method (the orbits are chaotic); survival is the measure.
``cherry_blowup``
    Cherry's system (paper setting), whose true solution from ``u0*`` blows up
    at t ~ 28: the blow-up time of each learned model (first ``|u| > 10``) and
    its failure time, against the truth's.

Methods: dense SP (RK4 and AVF) and non-SP, the sparse rows (SP-sparse and
non-SP-STLSQ, threshold by cross-validation), PySINDy-best (bagged STLSQ,
threshold by cross-validation, and on noisy data its own smoothing: a
Savitzky-Golay cubic over the whole trajectory) and PySINDy-poly (fixed
threshold, our derivatives). On noisy data every method but PySINDy-best
uses the paper's Q = 5 de-noising; SP-sparse-Q3 is SP-sparse with Q = 3,
the cubic PySINDy-best's smoothing fits, to separate the smoothing from the
method; SP-CV chooses ``Q`` (3, 4, 5) and the threshold together by
``GridSearchCV`` with the default score, on the data alone.

Error = median over the test states of the relative trajectory error on
``[0, horizon]``; a rollout that fails before the horizon counts as ``inf``.

Outputs, in ``--output`` (default ``benchmarks/results/``): ``stability.csv``,
``stability.png`` (all panels, an overview), ``stability_<panel>.png`` (each
panel alone with larger fonts, for the documentation: ``noise``,
``trajectories``, ``conditioning``, ``degree``, ``long_horizon``, ``cherry``)
and ``stability_plot.pickle`` (what the charts need, so that ``--replot``
redraws them without rerunning). ``python benchmarks/bench_stability.py``
took 6 min 53 s on 2 shared cores with pysindy installed (2026-11-23, load
average about 1); ``--quick`` is a smoke run of about a minute.
"""

import os

# Pin BLAS before numpy is imported (see bench_speed_accuracy.py).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import datetime  # noqa: E402
import itertools  # noqa: E402
import math  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.polynomial import legendre  # noqa: E402
from sklearn.model_selection import GridSearchCV  # noqa: E402
from sklearn.pipeline import make_pipeline  # noqa: E402

import _common as C  # noqa: E402
from sk_hamiltonian import (  # noqa: E402
    DerivativeTransformer,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian.datasets import load_system  # noqa: E402

COLUMNS = [
    "experiment", "method", "param", "value", "status", "error", "horizon", "n_test",
    "n_failed", "fail_time", "n_escaped", "escape_time", "blowup_time", "cond", "n_params",
    "n_equations", "note",
]
METHODS = ("SP-RK4", "SP-AVF", "SP-sparse-RK4", "SP-sparse-Q3-RK4", "SP-CV-RK4", "non-SP-RK4",
           "non-SP-STLSQ-RK4", "PySINDy-best-RK4", "PySINDy-poly-RK4")
STYLE = {
    "SP-RK4": dict(color="tab:blue", marker="o"),
    "SP-AVF": dict(color="tab:cyan", marker="s", ls="--", mfc="none"),
    "SP-sparse-RK4": dict(color="tab:purple", marker="p"),
    "SP-sparse-Q3-RK4": dict(color="tab:pink", marker="h", ls="--"),
    "SP-CV-RK4": dict(color="tab:olive", marker="X"),
    "non-SP-RK4": dict(color="tab:orange", marker="^"),
    "non-SP-STLSQ-RK4": dict(color="tab:brown", marker="<", ls="--"),
    "PySINDy-best-RK4": dict(color="tab:red", marker="*"),
    "PySINDy-poly-RK4": dict(color="tab:green", marker="D", ls=":"),
    "truth": dict(color="k", marker=""),
}
# De-noising degree of the SP-sparse-Q3 rows (noisy scenes only): the cubic
# that PySINDy-best's Savitzky-Golay smoothing fits over the whole trajectory.
LOW_Q = 3
# The SP-CV rows (noisy scenes only): Q and the threshold chosen together by
# GridSearchCV with the default score on the raw trajectories, as a user
# would (no look at the truth).
CV_QS = (3, 4, 5)
# PySINDy-poly's STLSQ threshold in the sweeps (the labelled extra row):
# fixed, as in the earlier runs; bench_speed_accuracy's held-out rule picked
# 0.001-0.1 on the paper's scenes (0.01 on the noisy pendulum).
SINDY_THRESHOLD = 0.01
# Corollary 3.4 with r = 1: K_N <= lambda K / log K, lambda = (3 log 1.5 - 1) / 4.
COROLLARY_R = 1.0


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small smoke run (< 30 s)")
    parser.add_argument("--output", type=Path,
                        default=Path(__file__).resolve().parent / "results",
                        help="directory for CSV and PNG outputs")
    parser.add_argument("--no-sindy", action="store_true", help="skip PySINDy even if installed")
    parser.add_argument("--replot", action="store_true",
                        help="only redraw the charts from stability_plot.pickle in --output")
    parser.add_argument("--experiments", nargs="+", choices=EXPERIMENTS, default=EXPERIMENTS,
                        help="run only these experiments (default all; the overview "
                        "stability.png needs all)")
    parser.add_argument("--n-fresh", type=int, default=4,
                        help="fresh test states of the sweeps (default 4)")
    parser.add_argument("--n-fresh-long", type=int, default=8,
                        help="fresh test states of the long-horizon panel (default 8)")
    return parser.parse_args(argv)


# ---------------------------------------------------------------- Corollary 3.4
def _gradient_basis(X, domain, powers):
    """Gradients (k, m, N) of tensor Legendre polynomials on ``domain``."""
    low, high = domain[:, 0], domain[:, 1]
    xi = (2 * X - (low + high)) / (high - low)
    degree = int(powers.max())
    m = X.shape[1]
    values = np.stack([legendre.legvander(xi[:, i], degree) for i in range(m)], axis=1)
    slopes = np.zeros_like(values)
    for k in range(1, degree + 1):
        unit = np.zeros(k + 1)
        unit[k] = 1.0
        slopes[:, :, k] = legendre.legval(xi, legendre.legder(unit))
    cols = np.arange(m)[:, None]
    V, D = values[:, cols, powers.T], slopes[:, cols, powers.T]
    grads = np.empty((X.shape[0], m, powers.shape[0]))
    for i in range(m):
        grads[:, i] = D[:, i] * np.prod(np.delete(V, i, axis=1), axis=1) * 2 / (high[i] - low[i])
    return grads


def christoffel_sup(domain, degree, grid=41):
    """``K_N = sup_x sum_j |grad phi_j(x)|^2`` for a grad-orthonormal basis (uniform measure).

    The paper's (3.12); basis-independent, so computed from the Legendre basis
    and the exact Gram matrix of its gradients (Gauss quadrature), then
    maximized over a grid of the box (the maximum sits at its corners).
    """
    domain = np.asarray(domain, dtype=float)
    m = domain.shape[0]
    powers = np.array([p for p in itertools.product(range(degree + 1), repeat=m)
                       if 0 < sum(p) <= degree])
    nodes, weights = legendre.leggauss(degree + 1)
    idx = np.array(list(itertools.product(range(degree + 1), repeat=m)))
    points = domain.mean(axis=1) + 0.5 * (domain[:, 1] - domain[:, 0]) * nodes[idx]
    w = np.prod(weights[idx] / 2, axis=1)
    G = _gradient_basis(points, domain, powers)
    gram_inv = np.linalg.inv(np.einsum("k,kiN,kiM->NM", w, G, G))
    axes = [np.linspace(lo, hi, grid) for lo, hi in domain]
    X = np.array(list(itertools.product(*axes)))
    G = _gradient_basis(X, domain, powers)
    return float(np.einsum("kiN,NM,kiM->k", G, gram_inv, G).max())


def corollary_pairs(k_n, r=COROLLARY_R):
    """Smallest number of state pairs K with ``K_N <= lambda K / log K``."""
    lam = (3 * math.log(1.5) - 1) / (2 + 2 * r)
    K = 3.0
    while K / math.log(K) < k_n / lam:
        K *= 1.005
    return K


# ---------------------------------------------------------------- fitting and testing
class Unfit(Exception):
    """A method could not be fitted (e.g. fewer equations than unknowns)."""


def fit_all(scene, Xt, ps, X=None, quick=False):
    """Fit each method; returns {method: (model, cond, n_params, n_equations) or Unfit}.

    Every method works in the panel's polynomial space of degree ``n``: the
    dense fits, the sparse fits (threshold by ``GridSearchCV``, see
    :func:`_common.fit_sparse`), PySINDy-best (``PolynomialLibrary(n)``,
    smoothed derivatives on noisy data, bagging, threshold by CV; ``X`` are
    the raw trajectories it differentiates) and PySINDy-poly (fixed
    threshold, our derivatives).
    """
    K = sum(len(s) for s in C.split_layout(Xt)[0])
    m = Xt[0].shape[1] // 3
    M = len(Xt)
    fitted = {}
    for name, cls in (("SP", HamiltonianRegressor), ("non-SP", VectorFieldRegressor)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # IllConditionedWarning: cond_ is recorded
            try:
                model = cls(scene.degree).fit(Xt)
                info = (model, float(model.cond_), int(model.coef_.size),
                        K * m if name == "SP" else K)
            except ValueError as error:
                info = Unfit(str(error).split(":")[0])
        for method in ("rk4", "avf") if name == "SP" else ("rk4",):
            fitted[f"{name}-{method.upper()}"] = (info, method)
    sparse = [("SP-sparse", HamiltonianRegressor, Xt), ("non-SP-STLSQ", VectorFieldRegressor, Xt)]
    if scene.noise > 0 and X is not None:
        # The smoothing PySINDy-best gets, a cubic over each trajectory, with
        # the paper's de-noising method: SP-sparse on the same footing.
        sparse.append(("SP-sparse-Q3", HamiltonianRegressor, DerivativeTransformer(
            dt=scene.dt, method="polynomial", degree=LOW_Q).fit_transform(X)))
    if scene.noise > 0 and X is not None:
        # Every de-noising degree keeps every sample: the equations are SP's.
        model = _fit_sp_cv(scene, X, quick)
        fitted["SP-CV-RK4"] = ((model, float(model.cond_), int(model.n_terms_), K * m), "rk4")
    for name, cls, data in sparse:
        # Fewer trajectories than folds: one trajectory per fold.
        try:
            model, threshold, _, _, _ = C.fit_sparse(
                cls(scene.degree), data,
                C.SPARSE_THRESHOLDS[::2] if quick else C.SPARSE_THRESHOLDS,
                cv=min(2 if quick else 5, M))
            info = (model, float(model.cond_), int(model.n_terms_),
                    K * m if name.startswith("SP") else K)
        except ValueError as error:
            info = Unfit(str(error).split(":")[0])
        fitted[f"{name}-RK4"] = (info, "rk4")
    if ps is not None:
        states, derivatives, _, _ = C.sindy_best_data(ps, scene, X, Xt)
        threshold, _ = C.cv_sindy_threshold(
            ps, states, derivatives, scene.dt, scene.degree,
            thresholds=C.SINDY_BEST_THRESHOLDS[::2] if quick else C.SINDY_BEST_THRESHOLDS,
            folds=min(2 if quick else 3, M))
        model = C.fit_sindy_best(ps, states, derivatives, scene.dt, threshold, scene.degree,
                                 n_models=5 if quick else C.SINDY_ENSEMBLE_MODELS)
        field = C.SindyField(model, np.concatenate(states)[:200])
        fitted["PySINDy-best-RK4"] = (
            (field, C.design_condition(model, Xt), field.n_params, K), "rk4")
        model = C.fit_sindy(ps, Xt, scene.degree, SINDY_THRESHOLD, scene.dt)
        field = C.SindyField(model, np.concatenate(C.split_layout(Xt)[0])[:200])
        fitted["PySINDy-poly-RK4"] = (
            (field, C.design_condition(model, Xt), field.n_params, K), "rk4")
    return fitted


def _fit_sp_cv(scene, X, quick):
    """SP with ``Q`` and ``threshold`` chosen by ``GridSearchCV`` (default score) on ``X``."""
    pipe = make_pipeline(DerivativeTransformer(dt=scene.dt, method="polynomial"),
                         HamiltonianRegressor(scene.degree))
    grid = {"derivativetransformer__degree": list(CV_QS[::2] if quick else CV_QS),
            "hamiltonianregressor__threshold": list(
                C.SPARSE_THRESHOLDS[::2] if quick else C.SPARSE_THRESHOLDS)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = GridSearchCV(pipe, grid, cv=min(2 if quick else 5, len(X))).fit(X)
    return search.best_estimator_[-1]


def training_box(Xt):
    """Bounding box of the training states: the domain of every method.

    It is what our regressors use when ``domain=None``; PySINDy has no domain,
    so "escaped" means the same box for all.
    """
    X = np.concatenate(C.split_layout(Xt)[0])
    return np.column_stack([X.min(axis=0), X.max(axis=0)])


def evaluate(fitted, x0, truth, t, horizon, base, box):
    """One row per method: median error over the test states, failures, escapes."""
    rows, curves = [], {}
    for name, (info, method) in fitted.items():
        row = dict(base, method=name, horizon=horizon, n_test=x0.shape[0])
        if isinstance(info, Unfit):
            rows.append(dict(row, status="unfit", error=np.nan, note=str(info)))
            continue
        model, cond, n_params, n_eq = info
        Y, fail_time = C.rollout(model, x0, t, method)
        err = C.relative_error(Y, truth, t, horizon)
        escape = C.escape_time(Y, t, box)
        n_failed = int(np.isfinite(fail_time).sum())
        row.update(
            status="failed" if n_failed else ("escaped" if np.isfinite(escape).any() else "ok"),
            error=float(np.median(err)), n_failed=n_failed,
            fail_time=float(fail_time.min()), n_escaped=int(np.isfinite(escape).sum()),
            escape_time=float(escape.min()), cond=cond, n_params=n_params, n_equations=n_eq,
        )
        rows.append(row)
        curves[name] = (Y, fail_time, escape)
    return rows, curves


# ---------------------------------------------------------------- experiments
def sweep(experiment, param, values, make_scene, ps, cfg, extra=None):
    """Fit and test every method at every value of one parameter."""
    rows = []
    tests = {}
    for value in values:
        scene = make_scene(value)
        system, Xt, _, X = C.make_data(scene, raw=True)
        if scene.system not in tests:
            tests[scene.system] = C.test_states(system, cfg["n_fresh"], cfg["horizon"], cfg["h"])
        x0, t, truth = tests[scene.system]
        base = dict(experiment=experiment, param=param, value=value)
        if extra:
            base.update(extra(value))
        new, _ = evaluate(fit_all(scene, Xt, ps, X, cfg["quick"]), x0, truth, t,
                          cfg["horizon"], base,
                          training_box(Xt))
        rows += new
        print(f"  {param}={value}: " + ", ".join(
            f"{r['method']} {C.fmt(r['error'])}{'' if r['status'] == 'ok' else ' ' + r['status']}"
            for r in new), flush=True)
    return rows


def long_horizon(ps, cfg):
    """Survival of learned Henon-Heiles trajectories over a long horizon."""
    rows, curves = [], {}
    for noise in cfg["long_noises"]:
        scene = C.Scene(f"Henon-Heiles {noise:.0%}", "henon_heiles", 3, cfg["M"], 40,
                        noise=noise)
        system, Xt, _, X = C.make_data(scene, raw=True)
        x0, t, truth = C.test_states(system, cfg["n_fresh_long"], cfg["long_horizon"],
                                     cfg["h_long"])
        base = dict(experiment="long_horizon", param="noise", value=noise)
        new, c = evaluate(fit_all(scene, Xt, ps, X, cfg["quick"]), x0, truth, t,
                          cfg["long_horizon"], base,
                          training_box(Xt))
        rows += new
        curves[noise] = (t, truth, c)
        print(f"  noise={noise}: " + ", ".join(
            f"{r['method']} failed {r.get('n_failed', '-')}/{r['n_test']} "
            f"escaped {r.get('n_escaped', '-')}" for r in new), flush=True)
    return rows, curves


def cherry_blowup(ps, cfg):
    """Blow-up times of the learned Cherry systems against the truth's."""
    scene = C.Scene("Cherry", "cherry", 3, cfg["M"], 2)
    system, Xt, _, X = C.make_data(scene, raw=True)
    t = np.arange(0.0, cfg["cherry_horizon"] + cfg["h"] / 2, cfg["h"])
    u0 = system.initial_state[None]
    truth, truth_fail = C.reference(system, u0, t)
    norms = {"truth": (np.linalg.norm(truth[0], axis=-1), truth_fail[0])}

    def blowup(Y):
        big = np.linalg.norm(Y, axis=-1) > 10
        return float(t[np.argmax(big)]) if big.any() else np.inf

    t_true = blowup(truth[0])
    rows = [dict(experiment="cherry_blowup", method="truth", param="u0", value="u0*",
                 status="blows up", blowup_time=t_true, fail_time=float(truth_fail[0]),
                 horizon=t[-1], n_test=1)]
    for name, (info, method) in fit_all(scene, Xt, ps, X, cfg["quick"]).items():
        model, cond, n_params, n_eq = info
        Y, fail_time = C.rollout(model, u0, t, method)
        # Error only where the truth is still tame (|u| < 1 up to t = 25).
        window = t <= 25.0
        err = C.relative_error(Y[:, window], truth[:, window], t[window], 25.0)[0]
        t_blow = blowup(Y[0])
        rows.append(dict(experiment="cherry_blowup", method=name, param="u0", value="u0*",
                         status="blows up" if np.isfinite(t_blow) else "bounded",
                         error=float(err), horizon=25.0, n_test=1, blowup_time=t_blow,
                         fail_time=float(fail_time[0]), cond=cond, n_params=n_params,
                         n_equations=n_eq,
                         note=f"blow-up {t_blow - t_true:+.2f} vs truth" if np.isfinite(t_blow)
                         else "no blow-up by the horizon"))
        norms[name] = (np.linalg.norm(Y[0], axis=-1), fail_time[0])
    for r in rows:
        print(f"  {r['method']}: |u|>10 at t={C.fmt(r['blowup_time'], 4)}, "
              f"non-finite at t={C.fmt(r['fail_time'], 4)}", flush=True)
    return rows, (t, norms)


# ---------------------------------------------------------------- chart

# Multiplies the hand-set font sizes of the panels: 1 in the combined 2 x 3
# overview, larger when a panel is drawn alone for the documentation.
FONT_SCALE = 1.0


def _fs(size):
    """A panel font size, scaled by ``FONT_SCALE``."""
    return size * FONT_SCALE


def _mark_failures(ax, rows, x_key, top):
    """Mark what went wrong at each point instead of dropping it.

    * all or most rollouts failed (median error is inf): bold x in the top
      band, one row per method, with the first failure time written below;
    * some rollouts failed: bold x over the point, with "k/n failed";
    * a rollout left the training box (escaped) without failing: open ring;
    * the method could not be fitted at all: thin x in the top band.
    """
    for r in rows:
        style = STYLE[r["method"]]
        x = r[x_key]
        band = top * 0.7 ** METHODS.index(r["method"])  # one row per method
        if r["status"] == "unfit":
            ax.scatter(x, band, marker="x", s=45, color=style["color"], linewidths=0.9)
        elif not np.isfinite(r["error"]):
            ax.scatter(x, band, marker="x", s=80, color=style["color"], linewidths=2.4)
            ax.annotate(f"t={r['fail_time']:.2g}", (x, band), textcoords="offset points",
                        xytext=(-2, -4), fontsize=_fs(5.5), color=style["color"], rotation=90,
                        ha="center", va="top")
        elif r["status"] == "failed":
            ax.scatter(x, r["error"], marker="x", s=80, color=style["color"], linewidths=2.4,
                       zorder=4)
            ax.annotate(f"{r['n_failed']}/{r['n_test']} failed", (x, r["error"]),
                        textcoords="offset points", xytext=(4, 4), fontsize=_fs(5.5),
                        color=style["color"])
        elif r["status"] == "escaped":
            ax.scatter(x, r["error"], marker="o", s=130, facecolors="none",
                       edgecolors=style["color"], linewidths=1.2, zorder=4)


def _error_panel(ax, rows, x_key, xlabel, title, logx=False):
    finite = [r["error"] for r in rows if np.isfinite(r["error"]) and r["error"] > 0]
    top = 10 ** np.ceil(np.log10(max(finite))) * 10 if finite else 10.0
    for method in METHODS:
        sub = [r for r in rows if r["method"] == method]
        if not sub:
            continue
        ok = [r for r in sub if np.isfinite(r["error"])]
        ax.plot([r[x_key] for r in ok], [r["error"] for r in ok], label=method,
                lw=1.2, ms=5, **STYLE[method])
        _mark_failures(ax, sub, x_key, top)
    ax.axhline(top * 0.7 ** len(METHODS), color="0.6", lw=0.8, ls=":")
    ax.set_yscale("log")
    if logx:
        ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("median rel. error on [0, 20]")
    ax.set_title(title, fontsize=_fs(9.5))
    ax.grid(True, which="both", alpha=0.3)


def _panel_noise(ax, rows, long_curves, cherry, cor, cfg):
    sub = [r for r in rows if r["experiment"] == "noise"]
    for r in sub:
        r["pct"] = 100 * r["value"]
    _error_panel(ax, sub, "pct", "relative noise [%]",
                 f"noise: Henon-Heiles, M={cfg['M']}, J=40, n=3")
    ax.legend(fontsize=_fs(7), loc="lower right")


def _panel_trajectories(ax, rows, long_curves, cherry, cor, cfg):
    sub = [r for r in rows if r["experiment"] == "n_trajectories"]
    _error_panel(ax, sub, "value", "trajectories M (J=2, K=3M state pairs)",
                 "fewer trajectories: pendulum clean, n=6", logx=True)
    ax.axvline(27 / 6, color="tab:blue", ls="--", lw=0.8)
    ax.axvline(28 / 3, color="tab:orange", ls="--", lw=0.8)
    ax.text(27 / 6, 0.02, " SP: M=4.5 equations=unknowns", rotation=90, fontsize=_fs(6.5),
            color="tab:blue", transform=ax.get_xaxis_transform())
    ax.text(28 / 3, 0.02, " non-SP: M=9.3", rotation=90, fontsize=_fs(6.5), color="tab:orange",
            transform=ax.get_xaxis_transform())
    if cor and cor["M"] <= 3 * max(r["value"] for r in sub):
        ax.axvline(cor["M"], color="k", ls=":", lw=0.8)


def _panel_conditioning(ax, rows, long_curves, cherry, cor, cfg):
    sub = [r for r in rows if r["experiment"] == "n_trajectories"]
    for method in METHODS:
        pts = [(r["value"], r["cond"]) for r in sub
               if r["method"] == method and np.isfinite(r.get("cond", np.nan))]
        if pts:
            ax.plot(*zip(*pts), label=method, lw=1.2, ms=5, **STYLE[method])
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("trajectories M (J=2)")
    ax.set_ylabel("cond of the column-scaled design")
    title = "conditioning vs M (pendulum clean, n=6)"
    if cor:
        title += (f"\nCor. 3.4 (r=1): K_N={cor['K_N']:.0f}, needs K>={cor['K']:.2g} pairs "
                  f"(M>={cor['M']:.2g})")
    ax.set_title(title, fontsize=_fs(9.5))
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=_fs(7))


def _panel_degree(ax, rows, long_curves, cherry, cor, cfg):
    deg = [r for r in rows if r["experiment"] == "degree"]
    _error_panel(ax, deg, "value", "polynomial degree n",
                 "degree too high for the data: pendulum clean, M=30, J=2")
    twin = ax.twinx()
    for method in ("SP-RK4", "non-SP-RK4"):
        pts = [(r["value"], r["cond"]) for r in deg
               if r["method"] == method and np.isfinite(r.get("cond", np.nan))]
        if pts:
            twin.plot(*zip(*pts), ls=":", lw=1, color=STYLE[method]["color"])
    twin.set_yscale("log")
    twin.set_ylabel("cond (dotted)", fontsize=_fs(8))


def _panel_long_horizon(ax, rows, long_curves, cherry, cor, cfg):
    for noise, (t, truth, curves) in long_curves.items():
        for method, (Y, fail_time, escape) in curves.items():
            # Survival: fraction of test states still finite and inside the domain.
            alive = (escape[:, None] > t[None]).mean(axis=0)
            ls = "-" if noise == min(long_curves) else "--"
            ax.plot(t, alive, ls=ls, lw=1.3, color=STYLE[method]["color"],
                    label=f"{method}, {noise:.0%} noise")
            for ft in fail_time[np.isfinite(fail_time)]:
                ax.scatter(ft, -0.04, marker="x", s=40, color=STYLE[method]["color"],
                           clip_on=False)
    summary = [f"{r['method']:<12s} {r['value']:>4.0%}: failed {r['n_failed']}/{r['n_test']}, "
               f"escaped {r['n_escaped']}/{r['n_test']}"
               for r in rows if r["experiment"] == "long_horizon" and r["status"] != "unfit"]
    ax.text(0.98, 0.35, "\n".join(summary), transform=ax.transAxes, fontsize=_fs(6.5), ha="right",
            va="bottom", family="monospace",
            bbox=dict(facecolor="white", alpha=0.85, edgecolor="0.7"))
    ax.set_ylim(-0.08, 1.05)
    ax.set_xlabel("t")
    ax.set_ylabel("fraction of test states still inside the domain")
    noises = " / ".join(f"{n:.0%}" for n in sorted(long_curves))
    ax.set_title(f"long horizon: Henon-Heiles, M={cfg['M']}, J=40, noise {noises} "
                 f"(solid / dashed);\n"
                 "x on the axis = non-finite (SimulationError) at that t", fontsize=_fs(9.5))
    ax.legend(fontsize=_fs(6.5), loc="center left")
    ax.grid(True, alpha=0.3)


def _panel_cherry(ax, rows, long_curves, cherry, cor, cfg):
    if cherry is not None:
        t, norms = cherry
        for method, (norm, fail) in norms.items():
            style = STYLE.get(method, STYLE["truth"])
            ax.plot(t, norm, lw=1.3 if method != "truth" else 2.2, color=style["color"],
                    ls="-" if method != "truth" else "--", label=method)
            if np.isfinite(fail):
                ax.scatter(fail, 1e3, marker="x", s=80, color=style["color"], linewidths=2)
        lines = [f"{r['method']}: |u|>10 at {C.fmt(r['blowup_time'], 4, 'never')}, "
                 f"non-finite at {C.fmt(r['fail_time'], 4, 'never')}"
                 for r in rows if r["experiment"] == "cherry_blowup"]
        ax.text(0.02, 0.6, "\n".join(lines), transform=ax.transAxes, fontsize=_fs(7),
                va="top", family="monospace",
                bbox=dict(facecolor="white", alpha=0.85, edgecolor="0.7"))
        ax.axhline(10, color="0.5", lw=0.8, ls=":")
        ax.set_ylim(1e-2, 3e3)
        ax.set_yscale("log")
        ax.set_xlabel("t")
        ax.set_ylabel("|u(t)|")
        ax.set_title("Cherry: true blow-up vs learned (x = non-finite)", fontsize=_fs(9.5))
        ax.legend(fontsize=_fs(7), loc="upper left")
        ax.grid(True, which="both", alpha=0.3)


# Panel name (suffix of its own PNG) and drawing function, in the combined
# figure's reading order.
PANELS = (("noise", _panel_noise), ("trajectories", _panel_trajectories),
          ("conditioning", _panel_conditioning), ("degree", _panel_degree),
          ("long_horizon", _panel_long_horizon), ("cherry", _panel_cherry))
# The experiment each panel draws (for runs of some experiments only).
PANEL_EXPERIMENT = {"noise": "noise", "trajectories": "n_trajectories",
                    "conditioning": "n_trajectories", "degree": "degree",
                    "long_horizon": "long_horizon", "cherry": "cherry_blowup"}
EXPERIMENTS = ("noise", "n_trajectories", "degree", "long_horizon", "cherry_blowup")
FAILURE_KEY = ("Error panels: above the dotted line, bold x = most rollouts failed (non-finite; "
               "t = first failure), thin x = could not be fitted (fewer equations than unknowns); "
               "on a curve, x = some rollouts failed (k/n), o = a rollout left the training box.")


def plot(rows, long_curves, cherry, cor, cfg, path):
    """``stability.png`` (all panels, 2 x 3) and one readable PNG per panel.

    The combined figure is an overview; at page width its small print is
    unreadable, so each panel is also saved alone (``stability_<panel>.png``)
    with fonts scaled up, for the documentation.
    """
    global FONT_SCALE
    FONT_SCALE = 1.0
    ran = {r["experiment"] for r in rows}
    panels = [(name, draw) for name, draw in PANELS if PANEL_EXPERIMENT[name] in ran]
    if len(panels) == len(PANELS):  # the overview needs every panel
        fig, axes = plt.subplots(2, 3, figsize=(17, 10))
        for ax, (_, draw) in zip(axes.flat, PANELS):
            draw(ax, rows, long_curves, cherry, cor, cfg)
        fig.suptitle("Where the methods fail (failures marked, not dropped)", fontsize=12)
        fig.text(0.5, 0.004, FAILURE_KEY, ha="center", va="bottom", fontsize=8.5,
                 color="0.25")
        fig.tight_layout(rect=(0, 0.02, 1, 1))
        fig.savefig(path, dpi=110)
        plt.close(fig)
    FONT_SCALE = 1.6
    try:
        with plt.rc_context({"font.size": 13, "axes.titlesize": 14, "axes.labelsize": 13,
                             "xtick.labelsize": 12, "ytick.labelsize": 12}):
            for name, draw in panels:
                fig, ax = plt.subplots(figsize=(10, 6.2))
                draw(ax, rows, long_curves, cherry, cor, cfg)
                # In the overview one legend serves the row; alone, each
                # panel needs its own.
                if ax.get_legend() is None and ax.get_legend_handles_labels()[1]:
                    ax.legend(fontsize=11)
                fig.tight_layout()
                fig.savefig(path.with_name(f"{path.stem}_{name}.png"), dpi=100)
                plt.close(fig)
    finally:
        FONT_SCALE = 1.0


# ---------------------------------------------------------------- summary
def cell(r):
    """One table cell: the error, or what went wrong."""
    if r["status"] == "unfit":
        return "unfit"
    if not np.isfinite(r["error"]):
        return f"FAIL t={C.fmt(r['fail_time'], 3)}"
    text = C.fmt(r["error"])
    if r["status"] == "failed":
        text += f" ({r['n_failed']}/{r['n_test']} fail)"
    elif r["status"] == "escaped":
        text += " (esc)"
    return text


def pivot(rows, experiment, with_cond=False):
    """Parameter values down, methods across: what the README pastes."""
    sub = [r for r in rows if r["experiment"] == experiment]
    methods = [m for m in METHODS if any(r["method"] == m for r in sub)]
    table = []
    for value in dict.fromkeys(r["value"] for r in sub):
        by = {r["method"]: r for r in sub if r["value"] == value}
        line = {"param": f"{sub[0]['param']}={value:g}"}
        line.update({m: cell(by[m]) for m in methods if m in by})
        if with_cond:
            line["cond SP / non-SP / PySINDy-poly"] = " / ".join(
                C.fmt(by[m].get("cond", np.nan), 2) if m in by else "-"
                for m in ("SP-RK4", "non-SP-RK4", "PySINDy-poly-RK4") if m in methods)
        # Kept terms of the sparse fits (SP-sparse's unknowns, the nonzero
        # coefficients of the others).
        line["terms sparse / STLSQ / best"] = " / ".join(
            C.fmt(by[m].get("n_params", np.nan)) if m in by and by[m]["status"] != "unfit"
            else "-" for m in ("SP-sparse-RK4", "non-SP-STLSQ-RK4", "PySINDy-best-RK4")
            if m in methods)
        table.append(line)
    columns = ["param"] + methods + (["cond SP / non-SP / PySINDy-poly"] if with_cond else [])
    columns.append("terms sparse / STLSQ / best")
    C.print_table(table, columns)


# ---------------------------------------------------------------- main
def main(argv=None):
    args = parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    if args.replot:
        with open(args.output / "stability_plot.pickle", "rb") as handle:
            plot(*pickle.load(handle), args.output / "stability.png")
        print(f"# redrew the charts in {args.output}")
        return 0
    ps, reason = (None, "disabled by --no-sindy") if args.no_sindy else C.sindy_status()
    if args.quick:
        cfg = dict(M=60, n_fresh=1, horizon=20.0, h=0.02, noises=(0.0, 0.2),
                   Ms=(300, 10, 4), degrees=(3, 8, 13), long_noises=(0.2,),
                   n_fresh_long=1, long_horizon=10.0, h_long=0.05, cherry_horizon=30.0,
                   quick=True)
    else:
        cfg = dict(M=500, n_fresh=args.n_fresh, horizon=20.0, h=0.01,
                   noises=(0.0, 0.01, 0.02, 0.05, 0.1, 0.2),
                   Ms=(1000, 300, 100, 50, 30, 20, 15, 12, 10, 8, 6, 5, 4),
                   degrees=tuple(range(2, 15)), long_noises=(0.05, 0.2),
                   n_fresh_long=args.n_fresh_long, long_horizon=200.0, h_long=0.02,
                   cherry_horizon=40.0, quick=False)
    start = time.perf_counter()
    print(f"# bench_stability {'--quick ' if args.quick else ''}"
          f"{datetime.datetime.now().isoformat(timespec='seconds')}; numpy {np.__version__}, "
          f"{os.cpu_count()} cores, BLAS threads pinned to 1")
    print(f"# PySINDy rows skipped: {reason}" if ps is None
          else f"# baseline: {reason}; PySINDy-poly STLSQ threshold {SINDY_THRESHOLD}")
    rows = []

    todo = set(args.experiments)
    long_curves, cherry, cor = {}, None, None
    if "noise" in todo:
        print("# noise sweep", flush=True)
        rows += sweep("noise", "noise", cfg["noises"],
                      lambda v: C.Scene("Henon-Heiles", "henon_heiles", 3, cfg["M"], 40,
                                        noise=v),
                      ps, cfg)

    if "n_trajectories" in todo:
        k_n = christoffel_sup(load_system("single_pendulum").domain, 6)
        K = corollary_pairs(k_n)
        cor = dict(K_N=k_n, K=K, M=K / 3)
        print(f"# fewer trajectories (Corollary 3.4, r=1: K_N={k_n:.1f} for n=6 -> "
              f"K >= {K:.0f} pairs, M >= {K / 3:.0f} at J=2)", flush=True)
        rows += sweep("n_trajectories", "M", cfg["Ms"],
                      lambda v: C.Scene("pendulum", "single_pendulum", 6, v, 2), ps, cfg,
                      extra=lambda v: dict(note=f"K={3 * v} pairs; Cor. 3.4 wants K>={K:.0f}"))

    if "degree" in todo:
        print("# degree sweep (M=30, J=2)", flush=True)
        rows += sweep("degree", "degree", cfg["degrees"],
                      lambda v: C.Scene("pendulum", "single_pendulum", v, 30, 2), ps, cfg)

    if "long_horizon" in todo:
        print(f"# long horizon T={cfg['long_horizon']:g}", flush=True)
        new, long_curves = long_horizon(ps, cfg)
        rows += new

    if "cherry_blowup" in todo:
        print(f"# Cherry blow-up, T={cfg['cherry_horizon']:g}", flush=True)
        new, cherry = cherry_blowup(ps, cfg)
        rows += new

    for r in rows:
        for key in COLUMNS:
            r.setdefault(key, np.nan if key not in ("note", "status") else "")
    C.write_csv(args.output / "stability.csv", rows, COLUMNS)
    # The curves behind the long-horizon and Cherry panels are not in the
    # CSV; keep everything the charts need so that --replot can redraw them.
    with open(args.output / "stability_plot.pickle", "wb") as handle:
        pickle.dump((rows, long_curves, cherry, cor, cfg), handle)
    plot(rows, long_curves, cherry, cor, cfg, args.output / "stability.png")
    # Summaries; every number is also in stability.csv.
    for experiment, title, with_cond in (
        ("noise", "noise (Henon-Heiles): median rel. error on [0, 20]", False),
        ("n_trajectories", "fewer trajectories (pendulum, J=2, n=6)", True),
        ("degree", "degree (pendulum, M=30, J=2)", True),
    ):
        if experiment in todo:
            print(f"\n## {title}")
            pivot(rows, experiment, with_cond)
    if "long_horizon" in todo:
        print(f"\n## long horizon (Henon-Heiles, T={cfg['long_horizon']:g}): failed / "
              "escaped test states")
        C.print_table([r for r in rows if r["experiment"] == "long_horizon"],
                      ["method", "value", "n_test", "n_failed", "fail_time", "n_escaped",
                       "escape_time", "error"],
                      ["method", "noise", "n_test", "n_failed", "first_fail_t", "n_escaped",
                       "first_escape_t", "median_err"])
    if "cherry_blowup" in todo:
        print("\n## Cherry from u0*: blow-up (|u| > 10) and non-finite times")
        C.print_table([r for r in rows if r["experiment"] == "cherry_blowup"],
                      ["method", "blowup_time", "fail_time", "error", "n_params"],
                      ["method", "blowup_t", "nonfinite_t", "err_0_25", "n_params"])
    print(f"# wrote {args.output}/stability.csv, stability.png in "
          f"{time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
