"""The default search against the best model in its own grid, the old default and PySINDy.

For each scene and data seed:

``search``
    :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` with its
    defaults (5 folds of whole trajectories, shuffled by the seed): its
    pick, the terms it keeps, its time, every finalist's error, and the
    error of the same pick without the refinement on the trajectories
    (``refine=None``: its least-squares refit).
``oracle``
    Every candidate the search evaluated (its ``cv_results_``), refitted on
    all the data and judged by the truth: the best of them is "the grid's
    best". It is chosen by looking at the truth, which no search can do.
``paper-grid``
    The command's old default (``--paper-grid``): a GridSearchCV over
    de-noising Q in (fd, 3, 5, 8) and degree n in (4, 6, 8, 10) in the
    polynomial space, the same folds, refit = best mean score; timed in the
    same process as the search, so that their ratio is the budget's measure.
``sindy``, ``sindy-weak``
    PySINDy 2 at its best and honestly cross-validated (the scene's library
    chosen as an expert would, smoothing window and threshold by
    cross-validation on held-out trajectories, never on the truth; bagging),
    strong and weak form (``benchmarks/sindy_anchor.py``). Skipped with a
    note when PySINDy is not importable.

The error of a model is the *fresh-state error*: the median over 10 initial
states drawn uniformly from the system's domain (the distribution the data's
initial states come from; one fixed set per scene, keeping the states whose
true orbit stays within three times the box up to T) of the relative state error
``||x~(T) - x(T)|| / ||x(T)||`` at ``T = 20`` (angle differences taken the short
way round for the pendula), each model simulated with its own default
integrator and step, the truth by RK4 with steps of 1e-3.

Run::

    python benchmarks/search_study.py                       # every scene, seeds 0-4
    python benchmarks/search_study.py --scenes pendulum --seeds 0 1
    python benchmarks/search_study.py --methods search oracle paper-grid
    python benchmarks/search_study.py --report              # tables from the saved rows

Each (scene, seed, method) is saved in ``--output`` (default
``benchmarks/results/search_study``) as it finishes, and reused by later runs;
``--report`` prints the tables and writes ``search_study.csv`` and the chart.
"""

import argparse
import json
import math
import os
import pickle
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from sklearn.base import clone  # noqa: E402
from sklearn.model_selection import GridSearchCV, KFold  # noqa: E402
from sklearn.pipeline import Pipeline  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.datasets import (  # noqa: E402
    double_well,
    henon_heiles,
    make_trajectories,
    single_pendulum,
    torsion_pendulum,
)
from sk_hamiltonian.inspection import format_hamiltonian  # noqa: E402
from sk_hamiltonian.model_selection import HamiltonianSearchCV  # noqa: E402

HERE = Path(__file__).resolve().parent
T_END = 20.0
N_FRESH = 10
FOLDS = 5
SCENES = {
    "pendulum": dict(system=single_pendulum, n_trajectories=500, n_intervals=40, dt=0.01,
                     noise=0.08, angles=[1], terms={"p^2", "cos(q)"},
                     sindy=dict(poly_degree=2, fourier=1, angles=[1])),
    "henon_heiles": dict(system=henon_heiles, n_trajectories=300, n_intervals=40, dt=0.05,
                         noise=0.02, angles=[],
                         terms={"p1^2", "p2^2", "q1^2", "q2^2", "q1^2*q2", "q2^3"},
                         sindy=dict(poly_degree=3)),
    "torsion_pendulum": dict(system=torsion_pendulum, n_trajectories=300, n_intervals=40,
                             dt=0.02, noise=0.05, angles=[],
                             terms={"p^2", "q^2", "cos(q)"},
                             sindy=dict(poly_degree=2, fourier=1, angles=[1], mixed=True)),
    "double_well": dict(system=double_well, n_trajectories=300, n_intervals=40, dt=0.05,
                        noise=0.05, angles=[], terms={"p^2", "q^2", "q^4"},
                        sindy=dict(poly_degree=4)),
}
PAPER_GRID = [
    {"derivativetransformer__method": ["finite_difference"],
     "hamiltonianregressor__degree": [4, 6, 8, 10]},
    {"derivativetransformer__method": ["polynomial"], "derivativetransformer__degree": [3, 5, 8],
     "hamiltonianregressor__degree": [4, 6, 8, 10]},
]
METHODS = ("search", "oracle", "paper-grid", "sindy", "sindy-weak")


def pipeline(dt):
    return Pipeline([("derivativetransformer", DerivativeTransformer(dt=dt)),
                     ("hamiltonianregressor", HamiltonianRegressor())])


def scene_data(name, seed):
    cfg = SCENES[name]
    system = cfg["system"]()
    X = make_trajectories(system, cfg["n_trajectories"], cfg["n_intervals"], cfg["dt"],
                          noise=cfg["noise"], random_state=seed)
    return cfg, system, X, KFold(FOLDS, shuffle=True, random_state=seed)


def fresh_states(system, angles=()):
    """One fixed set of initial states per scene, uniform in the domain, and the truth at T.

    Only states whose true orbit stays bounded (within three times the
    domain's box up to T, angles aside, which may turn round and round) are
    kept: most of Henon-Heiles' box lies above its escape energy, and an
    orbit that runs off to infinity has no error to speak of.
    """
    rng = np.random.default_rng(12345)
    low, high = system.domain[:, 0], system.domain[:, 1]
    centre, half = (low + high) / 2, (high - low) / 2
    x0 = rng.uniform(low, high, size=(40 * N_FRESH, system.domain.shape[0]))
    t = np.linspace(0.0, T_END, 201)
    orbit = system.solve(x0, t, max_step=1e-3, on_failure="nan")
    with np.errstate(invalid="ignore"):
        inside = np.abs(orbit - centre) <= 3 * half
    inside[..., list(angles)] = np.isfinite(orbit[..., list(angles)])
    bounded = np.all(inside, axis=(1, 2))
    keep = np.flatnonzero(bounded)[:N_FRESH]
    return x0[keep], orbit[keep, -1]


def fresh_error(simulate, x0, truth, angles):
    """Median relative state error at T over the fresh states (inf where a rollout fails)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            Y = np.asarray(simulate(x0))
    except Exception:  # noqa: BLE001 -- a model that cannot be simulated fails
        return math.inf
    d = Y - truth
    if angles:
        d[:, angles] = (d[:, angles] + np.pi) % (2 * np.pi) - np.pi
    with np.errstate(invalid="ignore", over="ignore"):
        e = np.linalg.norm(d, axis=1) / np.linalg.norm(truth, axis=1)
    return float(np.median(np.where(np.isfinite(e), e, np.inf)))


def model_error(model, x0, truth, angles):
    return fresh_error(lambda x: model.simulate(x, [0.0, T_END], on_failure="nan")[:, -1],
                       x0, truth, angles)


def run_search(name, seed):
    cfg, system, X, cv = scene_data(name, seed)
    x0, truth = fresh_states(system, cfg["angles"])
    start = time.process_time()
    search = HamiltonianSearchCV(dt=cfg["dt"], cv=cv).fit(X)
    seconds = time.process_time() - start
    r = search.cv_results_
    model = search.best_estimator_[-1]
    finalists = np.flatnonzero(r["stage"] == "finalist")
    finalist_errors = {}
    for i in finalists:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            refit = clone(pipeline(cfg["dt"])).set_params(**r["params"][i]).fit(X)
        finalist_errors[int(i)] = model_error(refit[-1], x0, truth, cfg["angles"])
    from sk_hamiltonian.inspection import hamiltonian_terms

    kept = {term.text for term in hamiltonian_terms(model)}
    # The same pick without stage 4 (refine=None): its least-squares refit.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        least_squares = clone(pipeline(cfg["dt"])).set_params(**search.best_params_).fit(X)
    return dict(
        seconds=seconds, error=model_error(model, x0, truth, cfg["angles"]),
        error_least_squares=model_error(least_squares[-1], x0, truth, cfg["angles"]),
        refinement=search.refinement_,
        params=search.best_params_, n_terms=int(model.n_terms_),
        formula=format_hamiltonian(model), exact_support=kept == cfg["terms"],
        kept_spaces=search.kept_spaces_, finalist_errors=finalist_errors,
        cv_results={k: v for k, v in r.items() if not k.startswith("param_")},
    )


def run_oracle(name, seed, search_row):
    """The truth's best among the candidates the search evaluated."""
    from sk_hamiltonian.model_selection._fold_problems import FoldProblems

    cfg, system, X, _ = scene_data(name, seed)
    x0, truth = fresh_states(system, cfg["angles"])
    groups = {}
    for params in search_row["cv_results"]["params"]:
        space = {k.split("__", 1)[1]: v for k, v in params.items()
                 if k.startswith("hamiltonianregressor__")
                 and k.split("__", 1)[1] not in ("degree", "threshold")}
        layout = (params["derivativetransformer__method"],
                  params.get("derivativetransformer__degree"))
        groups.setdefault((layout, json.dumps(space, sort_keys=True)), []).append(params)
    best = dict(error=math.inf)
    errors = []
    for ((method, Q), space), candidates in groups.items():
        transformer = DerivativeTransformer(dt=cfg["dt"], method=method,
                                            **({} if Q is None else {"degree": Q}))
        Xt = transformer.fit_transform(X)
        largest = max(p["hamiltonianregressor__degree"] for p in candidates)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            problems = FoldProblems(json.loads(space), Xt, [np.arange(len(X))], largest)
        for params in candidates:
            n = params["hamiltonianregressor__degree"]
            threshold = params["hamiltonianregressor__threshold"]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, solution = problems.solve(n, threshold)
                model = problems.fitted(n, threshold, solution)
            error = model_error(model, x0, truth, cfg["angles"])
            errors.append(error)
            if error < best["error"]:
                best = dict(error=error, params=params, n_terms=int(model.n_terms_),
                            formula=format_hamiltonian(model))
    return dict(**best, n_candidates=len(errors), errors=errors)


def run_paper_grid(name, seed):
    cfg, system, X, cv = scene_data(name, seed)
    x0, truth = fresh_states(system, cfg["angles"])
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        grid = GridSearchCV(pipeline(cfg["dt"]), PAPER_GRID, cv=cv).fit(X)
    seconds = time.process_time() - start
    model = grid.best_estimator_[-1]
    return dict(seconds=seconds, error=model_error(model, x0, truth, cfg["angles"]),
                params=grid.best_params_, n_terms=int(model.n_terms_),
                formula=format_hamiltonian(model))


def run_sindy(name, seed, weak):
    try:
        sys.path.insert(0, str(HERE))
        from sindy_anchor import fit_sindy_cv
    except ImportError as error:
        return dict(skipped=f"PySINDy anchor not importable ({error})")
    cfg, system, X, cv = scene_data(name, seed)
    x0, truth = fresh_states(system, cfg["angles"])
    folds = [test for _, test in cv.split(X)]
    # CPU time, as for the others (the anchor's own fit_time is wall-clock).
    start = time.process_time()
    anchor = fit_sindy_cv(X, cfg["dt"], library=cfg["sindy"], folds=folds, weak=weak,
                          seed=seed)
    seconds = time.process_time() - start
    t = np.linspace(0.0, T_END, int(round(T_END / cfg["dt"])) + 1)
    error = fresh_error(lambda x: anchor.simulate(x, t)[:, -1], x0, truth, cfg["angles"])
    return dict(seconds=seconds, error=error, n_terms=int(anchor.n_terms),
                params=getattr(anchor, "params", {}))


def compute(name, seed, method, output):
    path = output / f"{name}_{seed}_{method}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    if method == "search":
        row = run_search(name, seed)
    elif method == "oracle":
        row = run_oracle(name, seed, compute(name, seed, "search", output))
    elif method == "paper-grid":
        row = run_paper_grid(name, seed)
    else:
        row = run_sindy(name, seed, weak=method == "sindy-weak")
    path.write_bytes(pickle.dumps(row))
    summary = {k: v for k, v in row.items() if k in ("seconds", "error", "n_terms", "formula",
                                                       "skipped", "exact_support")}
    print(f"{name} seed {seed} {method}: {summary}", flush=True)
    return row


def geometric_mean(values):
    values = np.asarray(values, dtype=float)
    return float(np.exp(np.mean(np.log(values)))) if np.all(np.isfinite(values)) else math.inf


def _rows(output, name, method, seeds):
    rows = {}
    for seed in seeds:
        path = output / f"{name}_{seed}_{method}.pkl"
        if path.exists():
            row = pickle.loads(path.read_bytes())
            if "skipped" not in row:
                rows[seed] = row
    return rows


def report(scenes, seeds, output):
    """Print the per-seed table and the summary (also as reStructuredText); write the CSV."""
    import csv

    rows, summary = [], []
    for name in scenes:
        by_method = {method: _rows(output, name, method, seeds) for method in METHODS}
        for method, results in by_method.items():
            for seed, r in results.items():
                rows.append(dict(scene=name, method=method, seed=seed, error=r["error"],
                                 error_least_squares=r.get("error_least_squares", ""),
                                 n_terms=r.get("n_terms"), cpu_seconds=r.get("seconds"),
                                 exact_support=r.get("exact_support", ""),
                                 formula=r.get("formula", "")))
        search = by_method["search"]
        if not search:
            continue
        line = dict(scene=name, seeds=len(search))
        line["exact"] = sum(bool(r["exact_support"]) for r in search.values())
        line["terms"] = "/".join(str(r["n_terms"]) for r in search.values())
        for method, results in by_method.items():
            line[method] = geometric_mean([r["error"] for r in results.values()]) \
                if results else math.nan
        unrefined = [r["error_least_squares"] for r in search.values()
                     if "error_least_squares" in r]
        line["search-ls"] = geometric_mean(unrefined) if unrefined else math.nan
        common = [s for s in search if s in by_method["oracle"]]
        line["pick/best"] = geometric_mean(
            [search[s]["error"] / by_method["oracle"][s]["error"] for s in common]) \
            if common else math.nan
        paired = [s for s in search if s in by_method["paper-grid"]]
        line["search_s"] = float(np.median([search[s]["seconds"] for s in search]))
        line["grid_s"] = float(np.median([by_method["paper-grid"][s]["seconds"]
                                          for s in paired])) if paired else math.nan
        line["time ratio"] = float(np.median([search[s]["seconds"]
                                              / by_method["paper-grid"][s]["seconds"]
                                              for s in paired])) if paired else math.nan
        summary.append(line)
        print(f"\n{name}:")
        for method, results in by_method.items():
            if results:
                print(f"  {method:11s} " + " ".join(
                    f"{seed}:{r['error']:.3g}({r.get('n_terms', '-')})"
                    for seed, r in results.items()))
    keys = ["scene", "seeds", "exact", "terms", "search", "search-ls", "oracle", "pick/best",
            "paper-grid",
            "sindy", "sindy-weak", "search_s", "grid_s", "time ratio"]
    print("\n" + "  ".join(f"{k:>12s}" for k in keys))
    for line in summary:
        print("  ".join(f"{line[k]:>12.4g}" if isinstance(line[k], float) else f"{line[k]!s:>12s}"
                        for k in keys))
    if rows:
        with open(output / "search_study.csv", "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
    return summary


STYLE = {"search": ("o", "C0", "HamiltonianSearchCV (default)"),
         "paper-grid": ("s", "C1", "paper's grid (polynomial GridSearchCV)"),
         "sindy": ("^", "C2", "PySINDy, strong form (cross-validated)"),
         "sindy-weak": ("v", "C3", "PySINDy, weak form (cross-validated)")}


def chart(scenes, seeds, output):
    """Error against CPU time, one panel per scene; the grid's best as a dashed line.

    A model whose rollout fails (blows up or leaves the float range) is
    drawn at the top edge of its panel with a cross, never left out.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    columns = min(2, len(scenes))
    rows_ = -(-len(scenes) // columns)
    fig, axes = plt.subplots(rows_, columns, figsize=(4.6 * columns, 3.4 * rows_ + 1.0),
                             squeeze=False)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    for ax, name in zip(axes.flat, scenes):
        rows = {m: _rows(output, name, m, seeds) for m in METHODS}
        finite = [r["error"] for m in STYLE for r in rows[m].values() if np.isfinite(r["error"])]
        top = 2 * max(finite) if finite else 1.0
        for method, (marker, colour, label) in STYLE.items():
            seconds = [r["seconds"] for r in rows[method].values()]
            errors = [r["error"] for r in rows[method].values()]
            if not seconds:
                continue
            ok = np.isfinite(errors)
            ax.scatter(np.array(seconds)[ok], np.array(errors)[ok], marker=marker, color=colour,
                       label=label, alpha=0.8)
            if (~ok).any():
                ax.scatter(np.array(seconds)[~ok], np.full((~ok).sum(), top), marker="x",
                           color=colour, label=f"{label}: rollout fails")
            unrefined = [r.get("error_least_squares", np.nan) for r in rows[method].values()]
            if method == "search" and np.isfinite(unrefined).any():
                ax.scatter(seconds, unrefined, marker=marker, facecolors="none",
                           edgecolors=colour, alpha=0.8,
                           label="its pick without the refinement (refine=None)")
        if rows["oracle"]:
            ax.axhline(geometric_mean([r["error"] for r in rows["oracle"].values()]),
                       color="0.4", ls="--", lw=1, label="best candidate by the truth")
        ax.set(xscale="log", yscale="log", title=name.replace("_", " "),
               xlabel="CPU seconds (one core)", ylabel=f"relative state error at T={T_END:g}")
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(FormatStrFormatter("%g"))
            axis.set_minor_formatter(NullFormatter())
    handles = {}
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=2, frameon=False)
    fig.tight_layout(rect=(0, 1.0 / (3.4 * rows_ + 1.0), 1, 1))
    fig.savefig(output / "search_study.png", dpi=110)
    plt.close(fig)
    return output / "search_study.png"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4])
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--output", type=Path, default=HERE / "results" / "search_study")
    parser.add_argument("--report", action="store_true", help="only print the saved rows")
    args = parser.parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    if not args.report:
        for name in args.scenes:
            for seed in args.seeds:
                for method in args.methods:
                    compute(name, seed, method, args.output)
    report(args.scenes, args.seeds, args.output)
    try:
        print("chart:", chart(args.scenes, args.seeds, args.output))
    except ImportError:
        print("no chart: matplotlib is not installed (pip install sk_hamiltonian[plot])")


if __name__ == "__main__":
    main()
