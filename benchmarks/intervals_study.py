"""How far the resampling intervals can be trusted: coverage, bias, inclusion, and their cost.

For each scene and data seed, the scene's fit with ``n_resamples=100``
(bootstrap of whole trajectories, seeded by the data seed) gives each true
term's 90 % interval (:func:`sk_hamiltonian.inspection.term_intervals`). Over
the seeds:

``coverage``
    the share of seeds whose interval holds the true coefficient (target
    80-97 % for a 90 % interval);
``bias``
    the mean over seeds of the fitted coefficient minus the truth, beside
    the mean half-width of the interval: where the bias is comparable to
    the half-width, no resampling of the same experiment can cover it;
``inclusion``
    per seed, the share of the 100 refits that keep each true term (target
    >= 95 %) and the largest share that keeps any other term (target <= 20 %).

Scenes (the truth is in the model space of each):

``pendulum``
    the paper's pendulum, 500 x 41 samples, dt 0.01, 8 % noise; de-noising
    Q = 3, periodic mechanical space of degree 4, threshold 0.03, fit on
    pairs of steps (Simpson): the command's pick on these data.
    ``H = p^2 / 2 - 9.8 cos q``.
``pendulum_q5``
    the same with Q = 5: the de-noising polynomial's bias differs, so the
    coefficients do, by more than the intervals' width.
``double_well``
    ``sk_hamiltonian.datasets.double_well()``, 300 x 41 samples, dt 0.05,
    5 % noise; Q = 5, mechanical space of degree 4, threshold 0.01,
    Simpson. ``H = p^2 / 2 - q^2 / 2 + q^4 / 4``.

The budget: on the pendulum (seed 0), the fit with ``n_resamples=0`` and with
``n_resamples=100``, alternately, best of ``--repeats`` each, in one process
with BLAS pinned to one thread (``threadpoolctl``); the ratio of the extra
time to one fit is the cost of 100 resamples in fits.

Run::

    python benchmarks/intervals_study.py                   # 40 seeds, every scene, the budget
    python benchmarks/intervals_study.py --seeds 5 --scenes pendulum
    python benchmarks/intervals_study.py --report          # the tables from the saved rows

Each (scene, seed) is saved in ``--output`` (default
``benchmarks/results/intervals_study``) as it finishes and reused by later
runs; the tables go to ``intervals_study.txt`` and ``intervals_study.csv``
there.
"""

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.datasets import double_well, make_trajectories, single_pendulum  # noqa: E402
from sk_hamiltonian.inspection import format_hamiltonian, term_intervals  # noqa: E402

HERE = Path(__file__).resolve().parent
N_RESAMPLES = 100
LEVEL = 0.9
PENDULUM_FIT = dict(degree=4, periodic=[False, True], momentum_degree=2, threshold=0.03,
                    fit_on="simpson")
SCENES = {
    "pendulum": dict(system=single_pendulum, n_trajectories=500, n_intervals=40, dt=0.01,
                     noise=0.08, Q=3, fit=PENDULUM_FIT,
                     truth={"p^2": 0.5, "cos(q)": -9.8}),
    "pendulum_q5": dict(system=single_pendulum, n_trajectories=500, n_intervals=40, dt=0.01,
                        noise=0.08, Q=5, fit=PENDULUM_FIT,
                        truth={"p^2": 0.5, "cos(q)": -9.8}),
    "double_well": dict(system=double_well, n_trajectories=300, n_intervals=40, dt=0.05,
                        noise=0.05, Q=5,
                        fit=dict(degree=4, momentum_degree=2, threshold=0.01, fit_on="simpson"),
                        truth={"p^2": 0.5, "q^2": -0.5, "q^4": 0.25}),
}


def scene_layout(name, seed):
    cfg = SCENES[name]
    X = make_trajectories(cfg["system"](), cfg["n_trajectories"], cfg["n_intervals"], cfg["dt"],
                          noise=cfg["noise"], random_state=seed)
    return cfg, DerivativeTransformer(dt=cfg["dt"], degree=cfg["Q"]).fit_transform(X)


def run(name, seed):
    """One seed of one scene: the intervals of the true terms and the inclusion of the others."""
    cfg, Xt = scene_layout(name, seed)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = HamiltonianRegressor(**cfg["fit"], n_resamples=N_RESAMPLES,
                                     random_state=seed).fit(Xt)
    seconds = time.perf_counter() - start
    intervals = {t.text: t for t in term_intervals(model, level=LEVEL)}
    true = {}
    for text, value in cfg["truth"].items():
        t = intervals.get(text)
        true[text] = dict(
            truth=value, coefficient=None if t is None else t.coefficient,
            low=None if t is None else t.low, high=None if t is None else t.high,
            kept=0 if t is None else t.n_kept,
            covered=t is not None and t.low <= value <= t.high,
        )
    spurious = {t.text: t.n_kept for t in intervals.values() if t.text not in cfg["truth"]}
    model_terms = sorted(t.text for t in intervals.values() if t.coefficient != 0)
    return dict(scene=name, seed=seed, seconds=seconds, n_resamples=N_RESAMPLES,
                formula=format_hamiltonian(model, intervals=LEVEL), true=true,
                spurious=spurious, exact_support=model_terms == sorted(cfg["truth"]))


def budget(repeats):
    """Seconds of one pendulum fit without and with 100 resamples, best of ``repeats`` each."""
    from threadpoolctl import threadpool_limits

    _, Xt = scene_layout("pendulum", 0)
    times = {0: [], N_RESAMPLES: []}
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for _ in range(repeats):
            for n in times:
                start = time.perf_counter()
                HamiltonianRegressor(**PENDULUM_FIT, n_resamples=n, random_state=0).fit(Xt)
                times[n].append(time.perf_counter() - start)
    one, with_resamples = min(times[0]), min(times[N_RESAMPLES])
    return dict(fit_s=one, fit_with_resamples_s=with_resamples,
                resamples_in_fits=(with_resamples - one) / one, repeats=repeats)


def summary(rows):
    """Per scene and true coefficient: coverage, bias, half-width; inclusion over seeds."""
    lines, table = [], []
    for name in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == name]
        n = len(mine)
        lines.append(f"{name}: {n} seeds, {N_RESAMPLES} bootstrap resamples each, "
                     f"{LEVEL:.0%} intervals; exact support of the fit on "
                     f"{sum(r['exact_support'] for r in mine)}/{n} seeds")
        lines.append(f"  {'term':8s} {'truth':>7s} {'coverage':>9s} {'mean coef':>10s} "
                     f"{'bias':>9s} {'half-width':>10s} {'bias/hw':>8s} {'kept>=95%':>10s}")
        for text, value in SCENES[name]["truth"].items():
            entries = [r["true"][text] for r in mine]
            coef = np.array([e["coefficient"] if e["coefficient"] is not None else np.nan
                             for e in entries])
            half = np.array([(e["high"] - e["low"]) / 2 if e["low"] is not None else np.nan
                             for e in entries])
            covered = sum(e["covered"] for e in entries)
            bias = float(np.nanmean(coef) - value)
            kept = sum(e["kept"] >= 0.95 * N_RESAMPLES for e in entries)
            row = dict(scene=name, term=text, truth=value, seeds=n, coverage=covered / n,
                       mean_coefficient=float(np.nanmean(coef)), bias=bias,
                       mean_half_width=float(np.nanmean(half)),
                       bias_over_half_width=bias / float(np.nanmean(half)),
                       seeds_kept_95=kept)
            table.append(row)
            lines.append(
                f"  {text:8s} {value:7.3g} {covered:4d}/{n:<4d} {row['mean_coefficient']:10.5f} "
                f"{bias:+9.5f} {row['mean_half_width']:10.5f} "
                f"{row['bias_over_half_width']:+8.2f} {kept:5d}/{n}"
            )
        worst = [max(r["spurious"].values(), default=0) / N_RESAMPLES for r in mine]
        lines.append(
            f"  spurious terms: the most-kept one in at most 20% of the refits on "
            f"{sum(w <= 0.2 for w in worst)}/{n} seeds (median over seeds of its share "
            f"{np.median(worst):.0%}, largest {max(worst):.0%})"
        )
        seconds = [r["seconds"] for r in mine]
        lines.append(f"  fit with {N_RESAMPLES} resamples: median {np.median(seconds):.2f} s "
                     f"(not pinned to one thread)")
        lines.append("")
    return lines, table


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--repeats", type=int, default=5, help="budget timings per setting")
    parser.add_argument("--no-budget", action="store_true")
    parser.add_argument("--report", action="store_true", help="tables from the saved rows only")
    parser.add_argument("--output", type=Path, default=HERE / "results" / "intervals_study")
    args = parser.parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    rows = []
    for name in args.scenes:
        for seed in range(args.seeds):
            path = args.output / f"{name}_{seed:03d}.json"
            if path.exists():
                rows.append(json.loads(path.read_text()))
                continue
            if args.report:
                continue
            row = run(name, seed)
            path.write_text(json.dumps(row, indent=1))
            rows.append(row)
            print(f"{name} seed {seed}: {row['formula']}", flush=True)
    lines, table = summary(rows)
    budget_path = args.output / "budget.json"
    if not args.report and not args.no_budget:
        budget_path.write_text(json.dumps(budget(args.repeats), indent=1))
    if budget_path.exists():
        b = json.loads(budget_path.read_text())
        lines.append(
            f"budget (pendulum seed 0, BLAS on 1 thread, best of {b['repeats']}): one fit "
            f"{b['fit_s']:.3f} s, with {N_RESAMPLES} resamples {b['fit_with_resamples_s']:.3f} "
            f"s: the resamples cost {b['resamples_in_fits']:.2f} fits (budget 5)"
        )
    text = "\n".join(lines)
    print(text)
    (args.output / "intervals_study.txt").write_text(text + "\n")
    if table:
        columns = list(table[0])
        with open(args.output / "intervals_study.csv", "w", encoding="utf-8") as stream:
            stream.write(",".join(columns) + "\n")
            for row in table:
                stream.write(",".join(str(row[c]) for c in columns) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
