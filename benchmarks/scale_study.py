"""The default search on chains of many degrees of freedom, against PySINDy.

For each chain length ``d`` and data seed, the FPU-beta chain with fixed ends
(:func:`~sk_hamiltonian.datasets.fput_chain`, ``beta = 1``) is sampled as in
the project issue "Many degrees of freedom": 200 trajectories of 41 samples,
``dt = 0.05``, 1 % noise, initial states uniform in ``[-1, 1]**(2d)``; 5
folds of whole trajectories, shuffled by the seed. Two methods see the same
data and folds:

``search``
    :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` with its
    defaults (``spaces="auto"``: pairwise couplings beyond two degrees of
    freedom).
``sindy``
    PySINDy 2 cross-validated (``benchmarks/sindy_anchor.py``,
    :func:`fit_sindy_cv`, strong form) with a polynomial library of degree 3,
    the library an expert would pick for a quartic potential. Skipped with a
    note when PySINDy is not importable, or when the training folds have
    fewer than two samples per function of the library (the search's own
    rule; from ``d = 16`` on).

``--chain toda`` runs the same protocol on the Toda lattice with fixed ends
(:func:`~sk_hamiltonian.datasets.toda_lattice`, ``V(r) = exp(-r) + r - 1``
per bond): not polynomial, so no model of either method is exact, and only
the errors and costs compare. ``--chain network`` runs it on anharmonic
oscillators coupled by springs on a random graph (:func:`oscillator_network`:
a random tree plus ``d // 4`` extra bonds, constants drawn once per size),
whose law is exact in monomials like the chain's but whose bonds are not
between neighbours.

Each row runs in a process of its own, BLAS on one thread, so that its CPU
time and peak memory are its own:

``cpu_s``
    CPU seconds of the fit (``time.process_time``), the search's refinement
    and PySINDy's bagged final fit included.
``peak_mb``, ``base_mb``
    Peak resident memory of the process (``ru_maxrss``) after the fit, and
    before it (the data, the imports).
``exact``
    The model keeps the law's terms and nothing else: for the search, the
    chain's monomials (``p_i^2``, ``q_i^2``, ``q_i^4``, and ``q_i q_{i+1}``,
    ``q_i^3 q_{i+1}``, ``q_i^2 q_{i+1}^2``, ``q_i q_{i+1}^3`` for each bond
    between particles; the network's ``p_i^2``, ``q_i^2``, ``q_i^4`` and
    ``q_i q_j`` for each bond); for PySINDy, the nonzero coefficients of the true
    vector field in its library (found by exact least squares on
    noise-free states).
``error``
    The fresh-state error of ``benchmarks/search_study.py``: the median over
    10 initial states drawn uniformly from the box of the relative state
    error at ``T = 20``, the truth by RK4 with steps of 1e-3.

Run::

    python benchmarks/scale_study.py                     # d = 2, 4, 8, 16; seeds 0-2
    python benchmarks/scale_study.py --sizes 2 4 --seeds 0
    python benchmarks/scale_study.py --methods search
    python benchmarks/scale_study.py --report            # the table from the saved rows
    python benchmarks/scale_study.py --quick             # d = 2, 3 on 60 trajectories
    python benchmarks/scale_study.py --chain toda --sizes 4 8 --seeds 0
    python benchmarks/scale_study.py --chain network --sizes 4 8 16 --seeds 0
    python benchmarks/scale_study.py --chart scale_study.png   # every saved row, drawn

Each (d, seed, method) is saved in ``--output`` (default
``benchmarks/results/scale_study``; ``--quick`` writes to its ``quick``
folder) as it finishes, and reused by later runs; ``--report`` prints the
table, the search's CPU time over PySINDy's measured on the same data, and
writes ``scale_study.csv``.
"""

import argparse
import contextlib
import math
import os
import pickle
import subprocess
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
N_TRAJECTORIES = 200
N_INTERVALS = 40
DT = 0.05
NOISE = 0.01
FOLDS = 5
SIZES = (2, 4, 8, 16)
SEEDS = (0, 1, 2)
METHODS = ("search", "sindy")
SINDY_LIBRARY = dict(poly_degree=3)
QUICK = dict(sizes=(2, 3), seeds=(0,), n_trajectories=60)
CHAINS = ("fput", "toda", "network")
# The network's graph and constants are drawn once per size from this seed,
# so that the data seeds vary the data only.
NETWORK_SEED = 2026


def network_constants(d):
    """On-site stiffness and quartic constants, and the bonds with their springs.

    A random tree joins the ``d`` oscillators (each new one to an earlier one
    drawn at random, so not a chain), plus ``d // 4`` extra bonds between
    random pairs: hubs, loops and long-range links the chain lacks.
    """
    rng = np.random.default_rng(NETWORK_SEED + d)
    stiffness = rng.uniform(0.5, 1.5, d)
    quartic = rng.uniform(0.5, 1.5, d)
    bonds = {(int(rng.integers(i)), i) for i in range(1, d)}
    while len(bonds) < d - 1 + d // 4:
        i, j = sorted(int(k) for k in rng.choice(d, 2, replace=False))
        bonds.add((i, j))
    bonds = sorted(bonds)
    springs = rng.uniform(0.2, 0.6, len(bonds))
    return stiffness, quartic, bonds, springs


def oscillator_network(d):
    """Anharmonic oscillators coupled pairwise by springs on a random graph.

    ``H = sum_i p_i^2 / 2 + k_i q_i^2 / 2 + b_i q_i^4 / 4 + sum_bonds c_ij (q_i - q_j)^2 / 2``
    with the constants of :func:`network_constants`; domain ``[-1, 1]**(2d)``.
    """
    from sk_hamiltonian.datasets import HamiltonianSystem

    stiffness, quartic, bonds, springs = network_constants(d)
    i, j = np.array(bonds).T

    def hamiltonian(X):
        p, q = X[..., :d], X[..., d:]
        stretch = q[..., i] - q[..., j]
        return (0.5 * np.sum(p**2, axis=-1)
                + np.sum(stiffness * q**2 / 2 + quartic * q**4 / 4, axis=-1)
                + np.sum(springs * stretch**2 / 2, axis=-1))

    def gradient(X):
        p, q = X[..., :d], X[..., d:]
        force = springs * (q[..., i] - q[..., j])
        dq = stiffness * q + quartic * q**3
        np.add.at(dq, (..., i), force)
        np.add.at(dq, (..., j), -force)
        return np.concatenate([p, dq], axis=-1)

    return HamiltonianSystem(
        f"oscillator network of {d}", hamiltonian, gradient,
        domain=[[-1.0, 1.0]] * (2 * d),
        initial_state=np.concatenate([np.zeros(d), np.full(d, 0.4)]),
        params=dict(n_oscillators=d, bonds=len(bonds)),
    )


def onsite_terms(d):
    """``p_i^2``, ``q_i^2`` and ``q_i^4`` of ``d`` degrees of freedom: the chain's and the network's."""
    return {f"p{i}^2" for i in range(1, d + 1)} | {f"q{i}^{k}" for i in range(1, d + 1)
                                                   for k in (2, 4)}


def chain_law(d):
    """The monomials of ``H`` of an FPU-beta chain of ``d`` particles with fixed ends."""
    terms = onsite_terms(d)
    for i in range(1, d):
        a, b = f"q{i}", f"q{i + 1}"
        terms |= {f"{a}*{b}", f"{a}^3*{b}", f"{a}^2*{b}^2", f"{a}*{b}^3"}
    return terms


def network_law(d):
    """The monomials of ``H`` of :func:`oscillator_network`."""
    return onsite_terms(d) | {f"q{i + 1}*q{j + 1}" for i, j in network_constants(d)[2]}


LAWS = dict(fput=chain_law, toda=None, network=network_law)


def chain_data(chain, d, seed, n_trajectories):
    from sklearn.model_selection import KFold

    from sk_hamiltonian.datasets import fput_chain, make_trajectories, toda_lattice

    system = dict(fput=lambda: fput_chain(d, beta=1.0), toda=lambda: toda_lattice(d),
                  network=lambda: oscillator_network(d))[chain]()
    X = make_trajectories(system, n_trajectories, N_INTERVALS, DT, noise=NOISE,
                          random_state=seed)
    return system, X, KFold(FOLDS, shuffle=True, random_state=seed)


def peak_mb():
    import resource

    # ru_maxrss is in kilobytes on Linux.
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_search(chain, system, X, cv, d, x0, truth):
    from search_study import model_error

    from sk_hamiltonian.inspection import hamiltonian_terms
    from sk_hamiltonian.model_selection import HamiltonianSearchCV

    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = HamiltonianSearchCV(dt=DT, cv=cv).fit(X)
    seconds = time.process_time() - start
    model = search.best_estimator_[-1]
    kept = {term.text for term in hamiltonian_terms(model)}
    # The Toda lattice's potential is not polynomial: no set of monomials is its law.
    law = LAWS[chain](d) if LAWS[chain] is not None else None
    return dict(
        cpu_s=seconds, wall_s=search.search_time_,
        exact=kept == law if law is not None else None,
        missing=sorted(law - kept) if law is not None else [],
        extra=sorted(kept - law) if law is not None else [], n_terms=int(model.n_terms_),
        error=model_error(model, x0, truth, []), params=search.best_params_,
        kept_spaces=search.kept_spaces_, refinement=search.refinement_["status"],
        n_candidates=len(search.cv_results_["params"]),
    )


def sindy_exact(anchor, system):
    """Whether PySINDy's nonzero coefficients are those of the true vector field."""
    rng = np.random.default_rng(0)
    n_features = anchor.coef.shape[1]
    states = rng.uniform(system.domain[:, 0], system.domain[:, 1],
                         size=(3 * n_features, system.domain.shape[0]))
    theta = np.asarray(anchor.library.transform(states), dtype=float)
    coef, *_ = np.linalg.lstsq(theta, system.vector_field(states), rcond=None)
    truth = np.abs(coef.T) > 1e-8 * np.abs(coef).max()
    return bool(np.array_equal(anchor.coef != 0, truth))


class CPULimitReached(Exception):
    """The fit used the CPU seconds it was given (``--sindy-cpu-limit``)."""


@contextlib.contextmanager
def cpu_limit(seconds):
    """Raise :class:`CPULimitReached` once this process has spent ``seconds`` more CPU seconds.

    The kernel's CPU-time limit (``RLIMIT_CPU``) sends ``SIGXCPU``, turned
    into the exception; None: no limit.
    """
    if seconds is None:
        yield
        return
    import resource
    import signal

    def stop(signum, frame):
        raise CPULimitReached

    previous = signal.signal(signal.SIGXCPU, stop)
    soft, hard = resource.getrlimit(resource.RLIMIT_CPU)
    resource.setrlimit(resource.RLIMIT_CPU, (math.ceil(time.process_time() + seconds), hard))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_CPU, (soft, hard))
        signal.signal(signal.SIGXCPU, previous)


def run_sindy(chain, system, X, cv, seed, x0, truth, cpu_limit_s=None):
    from math import comb

    from search_study import T_END, fresh_error

    n_states = X.shape[-1]
    n_features = comb(n_states + SINDY_LIBRARY["poly_degree"], n_states)
    n_samples = X.shape[0] * X.shape[1] * (FOLDS - 1) // FOLDS
    # The search's own rule (two equations per unknown in every fold); each
    # of PySINDy's regressions has one equation per sample.
    beyond_rule = 2 * n_features > n_samples
    too_few = (f"the library has {n_features} functions, the training folds {n_samples} "
               f"samples: fewer than two per function")
    if beyond_rule and cpu_limit_s is None:
        return dict(skipped=too_few)
    try:
        from sindy_anchor import fit_sindy_cv
    except ImportError as error:
        return dict(skipped=f"PySINDy anchor not importable ({error})")
    folds = [test for _, test in cv.split(X)]
    start = time.process_time()
    try:
        with cpu_limit(cpu_limit_s):
            anchor = fit_sindy_cv(X, DT, library=SINDY_LIBRARY, folds=folds, seed=seed)
    except CPULimitReached:
        # Its time is known to exceed the limit: a lower bound, no model.
        row = dict(unfinished=True, cpu_s=time.process_time() - start)
        if beyond_rule:
            row["note"] = too_few + " (run for its time only)"
        return row
    seconds = time.process_time() - start
    t = np.linspace(0.0, T_END, int(round(T_END / DT)) + 1)
    exact = sindy_exact(anchor, system) if LAWS[chain] is not None else None
    return dict(cpu_s=seconds, wall_s=anchor.fit_time, exact=exact,
                n_terms=int(anchor.n_terms), params=anchor.params,
                error=fresh_error(lambda x: anchor.simulate(x, t)[:, -1], x0, truth, []))


def run_one(chain, d, seed, method, n_trajectories, path, sindy_cpu_limit=None):
    """One row, in this process: the data, the fit, its measures; saved to ``path``."""
    from threadpoolctl import threadpool_limits

    sys.path.insert(0, str(HERE))
    from search_study import fresh_states

    system, X, cv = chain_data(chain, d, seed, n_trajectories)
    x0, truth = fresh_states(system)
    base = peak_mb()
    with threadpool_limits(1):
        if method == "search":
            row = run_search(chain, system, X, cv, d, x0, truth)
        else:
            row = run_sindy(chain, system, X, cv, seed, x0, truth, sindy_cpu_limit)
    row.update(chain=chain, d=d, seed=seed, method=method, base_mb=base, peak_mb=peak_mb(),
               n_trajectories=n_trajectories)
    path.write_bytes(pickle.dumps(row))


def row_path(output, chain, d, seed, method):
    return output / f"{chain}{d}_{seed}_{method}.pkl"


def compute(chain, d, seed, method, n_trajectories, output, sindy_cpu_limit=None):
    path = row_path(output, chain, d, seed, method)
    if path.exists():
        return pickle.loads(path.read_bytes())
    started = time.perf_counter()
    limit = [] if sindy_cpu_limit is None else ["--sindy-cpu-limit", str(sindy_cpu_limit)]
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--one", str(d), str(seed),
                    method, "--chain", chain, "--n-trajectories", str(n_trajectories),
                    "--output", str(output), *limit], check=True)
    row = pickle.loads(path.read_bytes())
    shown = {k: row[k] for k in ("cpu_s", "peak_mb", "exact", "n_terms", "error", "skipped",
                                 "unfinished") if k in row}
    print(f"{chain} d={d} seed {seed} {method} ({time.perf_counter() - started:.0f} s wall): {shown}",
          flush=True)
    return row


def geometric_mean(values):
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return math.nan
    return float(np.exp(np.mean(np.log(values)))) if np.all(np.isfinite(values)) else math.inf


def report(chain, sizes, seeds, output):
    """Print one line per chain length and method; write the CSV of every row."""
    import csv

    rows = {(row["d"], row["seed"], row["method"]): row for row in load_rows(output, chain)
            if row["d"] in sizes and row["seed"] in seeds}
    keys = ["d", "method", "seeds", "exact", "n_terms", "error", "cpu_s", "peak_mb",
            "cpu ratio"]
    print("  ".join(f"{k:>10s}" for k in keys))
    for d in sizes:
        for method in METHODS:
            done = [rows[d, s, method] for s in seeds if (d, s, method) in rows]
            skipped = [r for r in done if "skipped" in r]
            unfinished = [r for r in done if r.get("unfinished")]
            done = [r for r in done if "skipped" not in r and not r.get("unfinished")]
            if skipped and not done:
                print(f"{d:>10d}  {method:>10s}  skipped: {skipped[0]['skipped']}")
            for r in unfinished:
                # Its time is a lower bound, so the search's ratio an upper one.
                search = rows.get((d, r["seed"], "search"), {})
                bound = (f"; the search's CPU ratio at most {search['cpu_s'] / r['cpu_s']:.3g}"
                         if "cpu_s" in search else "")
                print(f"{d:>10d}  {method:>10s}  seed {r['seed']}: stopped unfinished after "
                      f"{r['cpu_s']:.0f} CPU s, {r['peak_mb']:.0f} MB{bound}")
            if not done:
                continue
            # The search's CPU time over PySINDy's, on the same data and folds
            # (where PySINDy finished; a bound is printed on its own line).
            ratios = [rows[d, r["seed"], "search"]["cpu_s"] / rows[d, r["seed"], "sindy"]["cpu_s"]
                      for r in done if method == "search"
                      and "cpu_s" in rows.get((d, r["seed"], "sindy"), {})
                      and not rows[d, r["seed"], "sindy"].get("unfinished")]
            line = dict(d=d, method=method, seeds=len(done),
                        exact=(f"{sum(r['exact'] for r in done)}/{len(done)}"
                               if LAWS[chain] is not None else "-"),
                        n_terms="/".join(str(r["n_terms"]) for r in done),
                        error=geometric_mean([r["error"] for r in done]),
                        cpu_s=float(np.median([r["cpu_s"] for r in done])),
                        peak_mb=max(r["peak_mb"] for r in done))
            line["cpu ratio"] = float(np.median(ratios)) if ratios else math.nan
            print("  ".join(f"{line[k]:>10.4g}" if isinstance(line[k], float)
                            else f"{line[k]!s:>10s}" for k in keys))
    fields = ["d", "seed", "method", "n_trajectories", "exact", "n_terms", "error", "cpu_s",
              "wall_s", "base_mb", "peak_mb", "skipped", "unfinished"]
    name = "scale_study.csv" if chain == "fput" else f"scale_study_{chain}.csv"
    with open(output / name, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows[key] for key in sorted(rows))


def load_rows(output, chain=""):
    """The saved rows of ``chain`` (every chain when empty), in file-name order."""
    return [pickle.loads(path.read_bytes()) for path in sorted(output.glob(f"{chain}*_*_*.pkl"))]


def chart(output, path):
    """Draw CPU time, T = 20 error and peak memory against ``d`` for every chain and method.

    One marker per saved row (seed), a line through the medians (geometric
    means for the error, the largest for memory). Rows saved as skipped
    (PySINDy's library too large for the data) are left out; runs stopped
    unfinished (``--sindy-cpu-limit``) are drawn on the time panel only, as
    triangles pointing up: their time is a lower bound.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    saved = [r for r in load_rows(output) if "skipped" not in r]
    rows = [r for r in saved if not r.get("unfinished")]
    bounds = [r for r in saved if r.get("unfinished")]
    fig, axes = plt.subplots(1, 3, figsize=(13, 5.0), layout="constrained")
    colors = dict(fput="C0", toda="C1", network="C2")
    names = dict(fput="FPU-beta chain", toda="Toda lattice", network="oscillator network")
    styles = dict(search=("o", "-", "HamiltonianSearchCV"), sindy=("s", "--", "PySINDy CV"))
    for chain in CHAINS:
        for method, (marker, line, label) in styles.items():
            mine = [r for r in rows if r.get("chain", "fput") == chain and r["method"] == method]
            if not mine:
                continue
            sizes = sorted({r["d"] for r in mine})
            for ax, key, centre in ((axes[0], "cpu_s", np.median),
                                    (axes[1], "error", geometric_mean),
                                    (axes[2], "peak_mb", np.max)):
                ax.plot([r["d"] for r in mine], [r[key] for r in mine], marker, ms=4,
                        color=colors[chain], alpha=0.35, mfc="none" if method == "sindy" else None)
                ax.plot(sizes, [centre([r[key] for r in mine if r["d"] == d]) for d in sizes],
                        line, marker=marker, color=colors[chain],
                        mfc="none" if method == "sindy" else None,
                        label=f"{names[chain]}, {label}")
    for chain in CHAINS:
        mine = [r for r in bounds if r.get("chain", "fput") == chain]
        if mine:
            axes[0].plot([r["d"] for r in mine], [r["cpu_s"] for r in mine], "^", ms=11, zorder=5,
                         color=colors[chain], mfc="none",
                         label=f"{names[chain]}, PySINDy CV stopped unfinished (at least)")
    titles = ("CPU seconds of the fit (median)", "error at T = 20 (geometric mean)",
              "peak memory of the process, MB")
    for ax, title in zip(axes, titles):
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("degrees of freedom d")
        ax.set_title(title, fontsize=10)
        ax.set_xticks(SIZES, [str(d) for d in SIZES])
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[1].get_legend_handles_labels()
    extra = [(h, lab) for h, lab in zip(*axes[0].get_legend_handles_labels())
             if lab not in labels]
    handles, labels = handles + [h for h, _ in extra], labels + [lab for _, lab in extra]
    fig.legend(handles, labels, loc="outside lower center", ncol=3, fontsize=8)
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", nargs="+", type=int, default=list(SIZES),
                        help="chain lengths d")
    parser.add_argument("--seeds", nargs="+", type=int, default=list(SEEDS))
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--chain", default="fput", choices=CHAINS,
                        help="the FPU-beta chain (default) or the Toda lattice")
    parser.add_argument("--n-trajectories", type=int, default=N_TRAJECTORIES)
    parser.add_argument("--output", type=Path, default=None)
    parser.add_argument("--report", action="store_true", help="only print the saved rows")
    parser.add_argument("--chart", type=Path, default=None, metavar="PNG",
                        help="draw time, error and memory against d from every saved row")
    parser.add_argument("--quick", action="store_true",
                        help=f"d = {QUICK['sizes']}, seed 0, {QUICK['n_trajectories']} "
                             f"trajectories, in the output's quick folder")
    parser.add_argument("--sindy-cpu-limit", type=float, default=None, metavar="SECONDS",
                        help="stop PySINDy after this many CPU seconds and save the time as "
                             "a lower bound; with it, PySINDy also runs where its library "
                             "has fewer than two samples per function (for its time only)")
    parser.add_argument("--one", nargs=3, metavar=("D", "SEED", "METHOD"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    output = args.output or HERE / "results" / "scale_study"
    if args.quick:
        args.sizes, args.seeds = list(QUICK["sizes"]), list(QUICK["seeds"])
        args.n_trajectories = QUICK["n_trajectories"]
        output = output / "quick"
    output.mkdir(parents=True, exist_ok=True)
    if args.one:
        d, seed, method = int(args.one[0]), int(args.one[1]), args.one[2]
        run_one(args.chain, d, seed, method, args.n_trajectories,
                row_path(output, args.chain, d, seed, method), args.sindy_cpu_limit)
        return
    if args.chart is not None:
        chart(output, args.chart)
        return
    if not args.report:
        for d in args.sizes:
            for seed in args.seeds:
                for method in args.methods:
                    compute(args.chain, d, seed, method, args.n_trajectories, output,
                            args.sindy_cpu_limit)
    report(args.chain, args.sizes, args.seeds, output)


if __name__ == "__main__":
    main()
