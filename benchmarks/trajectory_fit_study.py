"""The trajectory fit for pipeline users: its intervals' coverage and width, its cost, and its error.

Three questions about ``HamiltonianRegressor(fit_on="trajectories")``:

``coverage`` (``--table coverage``)
    For each scene and data seed, the pipeline
    ``make_pipeline(DerivativeTransformer(dt, degree=Q), HamiltonianRegressor(..., fit_on="trajectories"))``
    in the scene's space, whose fit keeps the true terms; each true term's
    90 % interval (:func:`sk_hamiltonian.inspection.term_intervals`, the
    trajectory fit's covariance). Over the seeds: the share of
    intervals that hold the truth (target 85-95 %), the mean bias against the
    mean half-width, and, on the pendulum, the mean standard deviation
    against the Cramer-Rao bound (every initial state unknown, the true
    noise: the information of the true coefficients at the true
    trajectories, computed by the package's own sensitivities).
``cost`` (``--table cost``)
    On the pendulum (seed 0), the pipeline with ``fit_on="derivatives"``,
    with ``fit_on="trajectories"``, and the trajectory fit's covariance
    alone, in one process with BLAS on one thread (best of ``--repeats``).
``pipeline`` (``--table pipeline``)
    The error at T = 20 (the search study's fresh-state error) of a
    ``GridSearchCV`` over the pipeline with ``fit_on="trajectories"``
    (de-noising degree and degree; the default rollout score) against
    :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV`, on the
    paper's pendulum and on Henon-Heiles, over data seeds.

Run::

    python benchmarks/trajectory_fit_study.py --table coverage --seeds 40
    python benchmarks/trajectory_fit_study.py --table cost pipeline
    python benchmarks/trajectory_fit_study.py --report

Rows are saved in ``--output`` (default ``benchmarks/results/trajectory_fit_study``)
as they finish and reused by later runs.
"""

import argparse
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
from sklearn.model_selection import GridSearchCV, KFold  # noqa: E402
from sklearn.pipeline import make_pipeline  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.datasets import (  # noqa: E402
    double_well,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian.inspection import hamiltonian_terms, term_intervals  # noqa: E402
from sk_hamiltonian.model_selection import HamiltonianSearchCV  # noqa: E402

HERE = Path(__file__).resolve().parent
LEVEL = 0.9
SCENES = {
    "pendulum": dict(system=single_pendulum, n=500, dt=0.01, noise=0.08, Q=3,
                     fit=dict(degree=4, periodic=[False, True], momentum_degree=2,
                              threshold=0.03),
                     truth={"p^2": 0.5, "cos(q)": -9.8}),
    "double_well": dict(system=double_well, n=300, dt=0.05, noise=0.05, Q=5,
                        fit=dict(degree=4, momentum_degree=2, threshold=0.01),
                        truth={"p^2": 0.5, "q^2": -0.5, "q^4": 0.25}),
    "henon_heiles": dict(system=henon_heiles, n=300, dt=0.05, noise=0.02, Q=5,
                         fit=dict(degree=3, momentum_degree=2, threshold=0.03),
                         truth={"p1^2": 0.5, "p2^2": 0.5, "q1^2": 0.5, "q2^2": 0.5,
                                "q1^2*q2": 1.0, "q2^3": -1 / 3}),
}


def data(name, seed):
    cfg = SCENES[name]
    X = make_trajectories(cfg["system"](), cfg["n"], 40, cfg["dt"], noise=cfg["noise"],
                          random_state=seed)
    return cfg, X


def pipeline(cfg, fit_on="trajectories"):
    return make_pipeline(DerivativeTransformer(dt=cfg["dt"], degree=cfg["Q"]),
                         HamiltonianRegressor(**cfg["fit"], fit_on=fit_on))


def run_coverage(name, seed):
    cfg, X = data(name, seed)
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = pipeline(cfg).fit(X)[-1]
    seconds = time.process_time() - start
    row = dict(seconds=seconds, status=model.trajectory_fit_status_, intervals={})
    if row["status"] == "refined":
        row["intervals"] = {t.text: (t.coefficient, t.low, t.high)
                            for t in term_intervals(model, level=LEVEL)}
    return row


def cramer_rao(name, seed=0):
    """Standard deviations of the true coefficients at the bound, every initial state unknown.

    The information of the true coefficients at the true (noise-free)
    trajectories, weighted by the true noise (uniform relative noise of
    ``noise``: variance ``noise**2 / 3 x**2``; each sample weighing at most
    ten times the average, as the package weighs them), the initial states
    profiled out, inverted.
    """
    from sk_hamiltonian._trajectory_fit import KeptTerms, segmented, split_times
    from sk_hamiltonian._trajectory_fit.noise import noise_weights
    from sk_hamiltonian._trajectory_fit.covariance import information as fisher
    from sk_hamiltonian._trajectory_fit.solver import _groups, flow

    cfg = SCENES[name]
    clean = make_trajectories(cfg["system"](), cfg["n"], 40, cfg["dt"], random_state=seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = pipeline(cfg, fit_on="derivatives").fit(clean)[-1]
    terms = KeptTerms(model)
    text = {t.powers: t.text for t in hamiltonian_terms(model)}
    names = [text[tuple(int(p) for p in model._space.powers[j])] for j in terms.terms]
    theta = np.array([cfg["truth"][n] for n in names])
    times, states = split_times(list(clean), cfg["dt"])
    groups = _groups(segmented(model, times, states)[0])
    noise = np.array([[0.0, cfg["noise"] ** 2 / 3]] * clean.shape[-1])
    runs = []
    for g in groups:
        run = flow(terms.model, theta, g.Y[:, 0], g.steps)
        scale = np.sqrt(np.mean(g.Y.reshape(-1, g.Y.shape[-1]) ** 2, axis=0))
        g.weigh(noise_weights(noise, run[0], scale, g.mask))
        g.Y = run[0]  # no residual: the information needs only the sensitivities
        runs.append(run)
    matrix, _ = fisher(terms.model, groups, runs)
    return dict(zip(names, np.sqrt(np.diag(np.linalg.inv(matrix))).tolist()))


def run_cost(repeats):
    from threadpoolctl import threadpool_limits

    from sk_hamiltonian._trajectory_fit import refine

    cfg, X = data("pendulum", 0)
    best = {}
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(repeats):
            for what in ("derivatives", "trajectories", "unchecked"):
                start = time.process_time()
                if what == "unchecked":
                    model = pipeline(cfg, "derivatives").fit(X)[-1]
                    refine(model, list(X), cfg["dt"])
                else:
                    pipeline(cfg, what).fit(X)
                seconds = time.process_time() - start
                best[what] = min(best.get(what, math.inf), seconds)
    return best


def fresh_error(model, name):
    sys.path.insert(0, str(HERE))
    import search_study

    study = search_study.SCENES[name]
    x0, truth = search_study.fresh_states(SCENES[name]["system"](), study["angles"])
    return search_study.model_error(model, x0, truth, study["angles"])


def run_pipeline(name, seed):
    cfg, X = data(name, seed)
    cv = KFold(5, shuffle=True, random_state=seed)
    grid = {"derivativetransformer__degree": [3, 5],
            "hamiltonianregressor__degree": [cfg["fit"]["degree"], cfg["fit"]["degree"] + 2]}
    rows = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.process_time()
        grid_search = GridSearchCV(pipeline(cfg), grid, cv=cv).fit(X)
        rows["pipeline"] = dict(seconds=time.process_time() - start,
                                error=fresh_error(grid_search.best_estimator_[-1], name),
                                params=grid_search.best_params_)
        start = time.process_time()
        search = HamiltonianSearchCV(dt=cfg["dt"], cv=cv).fit(X)
        rows["search"] = dict(seconds=time.process_time() - start,
                              error=fresh_error(search.best_estimator_[-1], name))
    return rows


def compute(output, key, make):
    path = output / f"{'_'.join(map(str, key))}.pkl"
    if path.exists():
        return pickle.loads(path.read_bytes())
    row = make()
    path.write_bytes(pickle.dumps(row))
    print(key, {k: v for k, v in row.items() if k != "intervals"}, flush=True)
    return row


def report(output, seeds):
    lines = ["coverage of the 90 % intervals (trajectory fit): scene, term | seeds | covered | "
             "mean bias | mean half-width | mean sd / Cramer-Rao sd"]
    bounds = {}
    path = output / "cramer_rao.pkl"
    if path.exists():
        bounds = pickle.loads(path.read_bytes())
    for name, cfg in SCENES.items():
        rows = [r for s in range(seeds)
                if (r := _load(output, ("coverage", name, s))) and r["status"] == "refined"]
        if not rows:
            continue
        for term, value in cfg["truth"].items():
            found = [r["intervals"][term] for r in rows if term in r["intervals"]]
            if not found:
                continue
            coef, low, high = np.array(found).T
            covered = np.sum((low <= value) & (value <= high))
            half = (high - low) / 2
            ratio = ""
            if term in bounds.get(name, {}):
                ratio = f"{np.mean(half) / 1.6449 / bounds[name][term]:.3g}"
            lines.append(f"{name}, {term} | {len(found)} | {covered}/{len(found)} "
                         f"({covered / len(found):.0%}) | {np.mean(coef) - value:+.3g} | "
                         f"{np.mean(half):.3g} | {ratio}")
    cost = _load(output, ("cost",))
    if cost:
        lines.append(f"\ncost (pendulum seed 0, CPU s, best of repeats): derivatives "
                     f"{cost['derivatives']:.3g}, trajectories {cost['trajectories']:.3g}, the "
                     f"unchecked trajectory fit on a derivative fit {cost['unchecked']:.3g}")
    lines.append("\npipeline against the search: scene | seeds | GridSearchCV (trajectories) | "
                 "HamiltonianSearchCV | ratio | CPU s (grid, search)")
    for name in ("pendulum", "henon_heiles"):
        rows = [r for s in range(seeds) if (r := _load(output, ("pipeline", name, s)))]
        if rows:
            a = np.array([r["pipeline"]["error"] for r in rows])
            b = np.array([r["search"]["error"] for r in rows])
            gm = lambda v: float(np.exp(np.mean(np.log(v))))  # noqa: E731
            lines.append(f"{name} | {len(rows)} | {gm(a):.3g} | {gm(b):.3g} | {gm(a) / gm(b):.3g}"
                         f" | {np.median([r['pipeline']['seconds'] for r in rows]):.3g}, "
                         f"{np.median([r['search']['seconds'] for r in rows]):.3g}")
    text = "\n".join(lines)
    print(text)
    (output / "trajectory_fit_study.txt").write_text(text + "\n")


def _load(output, key):
    path = output / f"{'_'.join(map(str, key))}.pkl"
    return pickle.loads(path.read_bytes()) if path.exists() else None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--table", nargs="+", default=[],
                        choices=["coverage", "cost", "pipeline"])
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--output", type=Path,
                        default=HERE / "results" / "trajectory_fit_study")
    parser.add_argument("--report", action="store_true")
    args = parser.parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    if "coverage" in args.table:
        path = args.output / "cramer_rao.pkl"
        if not path.exists():
            path.write_bytes(pickle.dumps({"pendulum": cramer_rao("pendulum")}))
        for name in args.scenes:
            for seed in range(args.seeds):
                compute(args.output, ("coverage", name, seed),
                        lambda: run_coverage(name, seed))
    if "cost" in args.table:
        compute(args.output, ("cost",), lambda: run_cost(args.repeats))
    if "pipeline" in args.table:
        for name in ("pendulum", "henon_heiles"):
            for seed in range(min(args.seeds, 10)):
                compute(args.output, ("pipeline", name, seed), lambda: run_pipeline(name, seed))
    report(args.output, args.seeds)


if __name__ == "__main__":
    main()
