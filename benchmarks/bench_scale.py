"""Speed at scale: evaluation, simulation and fitting of the paper's Example 5, in one run.

Every target of issues 9 and 19 is measured side by side in the same process
and reported against its target: evaluation and simulation on both kernel
paths (numpy, and numba when it is installed: ``pip install
sk_hamiltonian[fast]``), with the compiled path's first-call latency (cold
compile into an empty cache, then loading from the disk cache); the fit targets are ratios to one ``A.T @ A`` of
a design of the same shape, timed in the same run. Absolute times depend on
the machine and its load (the reported run is from a shared 2-core VM); the
ratios are what to compare.

Measured (the double pendulum on the paper's domain, finite-difference data,
J = 2 intervals per trajectory):

- evaluation of a degree-15 model (3 875 terms): ``predict`` of one state, of
  a batch of 1 000 (per state), and the explicit products (gradients of every
  basis function, then a matrix product) as the old reference; and
  ``predict`` of one state counted in evaluations of the field inside the
  RK4 loop, the two timed in alternation (a ratio that the VM's drifting
  speed leaves alone);
- simulation from u0*: 10 000 RK4 steps, and the cost of one AVF step in RK4
  steps; and a sweep of 256 initial states near u0* (100 RK4 steps, per
  state and step);
- fits (M = 8 000): time of ``fit`` against one ``A.T @ A`` at n = 10 and
  n = 14, for the default solver ("normal" at these sizes), at n = 14 the
  sketch-preconditioned solver and, at n = 10, the conjugate-gradient
  solver with its closed-form preconditioner; the cost of one CG iteration against the
  normal equations per state, as ``"normal"`` accumulates them (factored),
  at n = 14 and n = 18 (how many iterations CG may take to break even), and
  its iteration count at n = 10;
- scaling: fit time against the number of samples and against the number of
  terms, on log-log axes with fitted slopes.

``--groups`` runs some groups only (evaluation, compile, fits, scaling);
``--all-cores`` leaves the BLAS and numba every core instead of one (the fit
targets of issue 19 are ratios to ``A.T @ A`` on both cores of a 2-core
machine; batches and sweeps are then reported in wall time);
``--quick`` skips the compile group and the agreement rows.
``--paper-n18`` instead runs the paper's largest case alone (n = 18,
M = 60 000) with all cores and reports its time and peak memory, for each
solver of ``--n18-solvers`` (default ``auto``; e.g. ``auto sketch`` side by
side, with the agreement of their coefficients).

Outputs, in ``--output`` (default ``benchmarks/results/``): ``scale.csv``
(one row per measurement, with its target), ``scale_fit.csv`` (the scaling
runs), ``scale.png`` (the log-log charts) and ``machine.txt``.

Run ``python benchmarks/bench_scale.py`` (about 10 minutes on 2 shared cores),
``--quick`` (a smoke run, < 60 s) or ``--paper-n18``.
"""

import os
import sys

# Pin BLAS before numpy is imported (one thread: ratios between methods must
# not depend on what other users leave free); the paper's n = 18 case uses
# every core instead, as a user would.
_ALL_CORES = "--paper-n18" in sys.argv or "--all-cores" in sys.argv
_THREADS = str(os.cpu_count() or 1) if _ALL_CORES else "1"
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = _THREADS

import argparse  # noqa: E402
import csv  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402
from threadpoolctl import threadpool_info, threadpool_limits  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, config_context  # noqa: E402
from sk_hamiltonian import _fit_steps as steps  # noqa: E402
from sk_hamiltonian._design import quadrature_nodes  # noqa: E402
from sk_hamiltonian._design_operator import DesignOperator  # noqa: E402
from sk_hamiltonian._numba import numba_available  # noqa: E402
from sk_hamiltonian.datasets import load_system, make_trajectories  # noqa: E402

SYSTEM = load_system("double_pendulum")
DT = 0.01
U0 = np.array([0.0, 0.0, np.pi / 6, np.pi / 4])

FULL = dict(
    eval_degree=15, eval_M=3000, batch=1000, rk4_steps=10_000, avf_steps=500,
    many_states=256, many_steps=100,
    fit_cases=[(10, 8000), (14, 8000)], cg_degree=10, cg_M=8000, iteration_cases=[14, 18],
    iteration_M=1000, samples_degree=8, samples=[1000, 2000, 4000, 8000, 16000],
    terms_M=4000, terms=[4, 6, 8, 10, 12, 14], repeats=3, quick=False,
)
QUICK = dict(
    eval_degree=8, eval_M=400, batch=200, rk4_steps=300, avf_steps=50,
    many_states=32, many_steps=10,
    fit_cases=[(6, 400)], cg_degree=5, cg_M=400, iteration_cases=[8], iteration_M=100,
    samples_degree=4, samples=[200, 400, 800], terms_M=300, terms=[3, 4, 5], repeats=1,
    quick=True,
)
COLUMNS = ["group", "measure", "value", "unit", "target", "met", "note"]


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small smoke run (< 60 s)")
    parser.add_argument("--all-cores", action="store_true",
                        help="leave the BLAS every core (issue 19's fit targets: against a "
                             "two-thread A.T @ A on 2 cores); default one thread")
    parser.add_argument("--paper-n18", action="store_true",
                        help="only the paper's n = 18, M = 60 000 fit, with all cores")
    parser.add_argument("--n18-solvers", nargs="+", default=["auto"],
                        choices=["auto", "normal", "sketch", "iterative"],
                        help="solvers of the n = 18 fit, one after the other in this run "
                             "(default: auto)")
    parser.add_argument("--groups", nargs="+", default=["evaluation", "compile", "fits", "scaling"],
                        choices=["evaluation", "compile", "fits", "scaling"],
                        help="which groups to run (default: all)")
    parser.add_argument("--output", type=Path,
                        default=Path(__file__).resolve().parent / "results",
                        help="directory for CSV and PNG outputs")
    return parser.parse_args(argv)


def machine():
    """nproc, CPU model, Python, numpy and the BLAS threadpoolctl sees."""
    model = platform.processor() or "?"
    try:
        lscpu = subprocess.run(["lscpu"], capture_output=True, text=True, check=False).stdout
        model = next(line.split(":", 1)[1].strip() for line in lscpu.splitlines()
                     if line.startswith("Model name")) or model
    except (OSError, StopIteration):
        pass
    blas = [f"{i.get('internal_api')} {i.get('version')} ({i.get('num_threads')} threads)"
            for i in threadpool_info() if i.get("user_api") == "blas"]
    try:
        load = " ".join(open("/proc/loadavg").read().split()[:3])
    except OSError:
        load = "?"
    return (f"{datetime.date.today()}: {os.cpu_count()} cores ({model}), load average {load}, "
            f"python {platform.python_version()}, numpy {np.__version__}, BLAS "
            f"{', '.join(blas) or '?'}")


def layout(M, seed=0):
    X = make_trajectories(SYSTEM, M, 2, DT, random_state=seed)
    return DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)


def best(f, repeats, number=1, clock=time.perf_counter):
    """Best over ``repeats`` of the mean time of ``number`` calls (wall clock by default)."""
    times = []
    for _ in range(repeats):
        start = clock()
        for _ in range(number):
            f()
        times.append((clock() - start) / number)
    return min(times)


def both(f, repeats, number=1):
    """(CPU seconds of this thread, wall seconds), each the best of ``repeats``.

    On a shared machine the wall clock also counts the time spent waiting
    for a core; the thread's CPU time is the work done, which is what an
    idle machine would take.
    """
    return best(f, repeats, number, time.thread_time), best(f, repeats, number)


def fit(Xt, degree, **params):
    with warnings.catch_warnings():
        # Finite differences push ~4 % of the states just outside the paper's box.
        warnings.simplefilter("ignore")
        return HamiltonianRegressor(degree=degree, domain=SYSTEM.domain, **params).fit(Xt)


def gram_time(n_rows, n_terms, repeats):
    """One ``A.T @ A`` (numpy's BLAS rank-k update) of a random design of this shape."""
    A = np.random.default_rng(0).random((n_rows, n_terms))
    seconds = best(lambda: A.T @ A, repeats)
    del A
    return seconds


def row(rows, group, measure, value, unit, target=None, note=""):
    met = "" if target is None else ("yes" if value <= target else "no")
    rows.append(dict(group=group, measure=measure, value=value, unit=unit,
                     target="" if target is None else target, met=met, note=note))
    print(f"  {measure:<52} {value:>12.4g} {unit:<10} "
          f"{'' if target is None else f'target <= {target:g}':<18} {met}", flush=True)


# ------------------------------------------------------------------ groups
def kernel_paths():
    """The kernel paths to measure: numpy always, numba when it is installed."""
    return ["numpy"] + (["numba"] if numba_available() else [])


# Targets of each path: issue 9's for numpy (which must not get slower), issue 19's for numba.
EVAL_TARGETS = {
    "numpy": dict(one=50, batch=5, rk4=2.0, avf=3.0),
    "numba": dict(one=15, batch=2, rk4=0.5, avf=3.0),
}


def one_state_gauge(model, u, t, rounds=7):
    """``predict`` of one state in evaluations of the field inside the compiled or numpy RK4 loop.

    This VM's speed drifts by up to 1.7 times over minutes, so the two are
    timed in alternation, close together, and the median ratio is kept.
    """
    ratios = []
    for _ in range(rounds):
        one = best(lambda: model.predict(u), 3, 200, time.thread_time)
        start = time.thread_time()
        model.simulate(u[0], t, method="rk4", max_step=np.inf)
        ratios.append(one / ((time.thread_time() - start) / (4 * (t.size - 1))))
    return float(np.median(ratios))


def evaluation(cfg, rows):
    print(f"# evaluation and simulation, degree {cfg['eval_degree']} model, both kernel paths")
    model = fit(layout(cfg["eval_M"]), cfg["eval_degree"])
    space = model._space
    u = U0[None]
    batch = np.random.default_rng(1).uniform(*SYSTEM.domain.T, size=(cfg["batch"], 4))
    n = cfg["rk4_steps"]
    t = np.linspace(0, n * DT, n + 1)
    n_avf = cfg["avf_steps"]
    t_avf = np.linspace(0, n_avf * DT, n_avf + 1)
    # A sweep of initial conditions: many states simulated in one call.
    n_many, steps_many = cfg["many_states"], cfg["many_steps"]
    x0_many = U0 + np.random.default_rng(2).uniform(-0.05, 0.05, size=(n_many, 4))
    t_many = np.linspace(0, steps_many * DT, steps_many + 1)
    results = {}
    for kernels in kernel_paths():
        with config_context(kernels=kernels):
            # Warm up: the first call of a compiled kernel loads (or compiles) it.
            model.predict(u), model.predict(batch[:300])
            model.simulate(U0, t[:3], method="rk4", max_step=np.inf)
            model.simulate(U0, t_avf[:3], method="avf", max_step=np.inf)
            model.simulate(x0_many, t_many[:3], method="rk4", max_step=np.inf)
            results[kernels] = dict(
                one=both(lambda: model.predict(u), 5, 200),
                kernel=both(lambda: space.gradient_dot(u, model.coef_), 5, 200),
                # Best of 7 x 5 calls: a batch takes milliseconds, and this VM varies.
                batch=[x / cfg["batch"] for x in both(lambda: model.predict(batch), 7, 5)],
                rk4=both(lambda: model.simulate(U0, t, method="rk4", max_step=np.inf), 1),
                avf=both(lambda: model.simulate(U0, t_avf, method="avf", max_step=np.inf), 1),
                many=both(lambda: model.simulate(x0_many, t_many, method="rk4", max_step=np.inf), 1),
                gauge=one_state_gauge(model, u, t[:501]),
                values=(model.predict(batch), model.simulate(U0, t[:200], method="rk4",
                                                             max_step=np.inf)),
            )

    def explicit():
        grad = space.gradients(batch) @ model.coef_
        return np.concatenate([-grad[:, 2:], grad[:, :2]], axis=1)

    with config_context(kernels="numpy"):
        assert np.allclose(explicit(), model.predict(batch), rtol=1e-10, atol=1e-10)
        reference = [x / cfg["batch"] for x in both(explicit, cfg["repeats"])]
    note = f"{space.n_terms} terms; CPU time (wall {{:.4g}})"
    for kernels, r in results.items():
        target = EVAL_TARGETS[kernels]
        group = "evaluation"
        row(rows, group, f"predict, one state [{kernels}]", r["one"][0] * 1e6, "us",
            target["one"], note.format(r["one"][1] * 1e6))
        row(rows, group, f"gradient contraction, one state [{kernels}]", r["kernel"][0] * 1e6,
            "us", None, "ModelSpace.gradient_dot alone; " + note.format(r["kernel"][1] * 1e6))
        if _ALL_CORES:
            # The batch runs in threads: the calling thread's CPU time is not the work.
            cpu, wall = r["batch"]
            row(rows, group, f"predict, batch (per state, wall, {_THREADS} cores) [{kernels}]",
                wall * 1e6, "us", target["batch"],
                f"{space.n_terms} terms; wall time (CPU time of the calling thread {cpu * 1e6:.4g})")
        else:
            row(rows, group, f"predict, batch (per state) [{kernels}]", r["batch"][0] * 1e6, "us",
                target["batch"], note.format(r["batch"][1] * 1e6))
        rk4, avf = r["rk4"], r["avf"]
        row(rows, group, f"predict, one state, in field evaluations of RK4 [{kernels}]",
            r["gauge"], "evaluations", None,
            f"CPU time; median of 7 rounds, each predict (best of 3 x 200) then {min(n, 500)} "
            "RK4 steps")
        row(rows, "simulation", f"{n} RK4 steps from u0* [{kernels}]",
            rk4[0] * 10_000 / n, "s per 1e4", target["rk4"],
            f"CPU time (wall {rk4[1] * 10_000 / n:.3g}); measured over {n} steps")
        row(rows, "simulation", f"one AVF step, in RK4 steps [{kernels}]",
            (avf[0] / n_avf) / (rk4[0] / n), "RK4 steps", target["avf"],
            f"CPU time (wall {(avf[1] / n_avf) / (rk4[1] / n):.3g}); step {DT}, "
            f"{n_avf} AVF steps; one AVF step {avf[0] / n_avf * 1e3:.3g} ms")
    for kernels, r in results.items():
        per = n_many * steps_many
        cpu, wall = (x / per * 1e6 for x in r["many"])
        row(rows, "simulation", f"RK4 of {n_many} states, per state and step [{kernels}]",
            wall if _ALL_CORES else cpu, "us", None,
            f"{steps_many} steps; " + (f"wall time on {_THREADS} cores (CPU time of the calling "
                                       f"thread {cpu:.3g})" if _ALL_CORES else f"CPU time (wall {wall:.3g})"))
    row(rows, "evaluation", "explicit products, batch (per state; old path)",
        reference[0] * 1e6, "us", None,
        "gradients of every function, then a matrix product; " + note.format(reference[1] * 1e6))
    if "numba" in results and not cfg["quick"]:
        # Full runs only (a difference may be exactly zero; the tests check agreement).
        (p0, s0), (p1, s1) = results["numpy"]["values"], results["numba"]["values"]
        for what, a, b in (("predict, batch", p0, p1), ("200 RK4 steps", s0, s1)):
            row(rows, "paths agree", f"{what}: max |numba - numpy| / max |numpy|",
                float(np.abs(b - a).max() / np.abs(a).max()), "relative", 1e-12)
        row(rows, "paths agree", "RK4 run time, numpy / numba",
            results["numpy"]["rk4"][0] / results["numba"]["rk4"][0], "ratio", None)


COMPILE_SCRIPT = """
import time, numpy as np
start = time.perf_counter()
from sk_hamiltonian import HamiltonianRegressor, config_context
X = np.random.default_rng(0).uniform(-1, 1, size=(300, 4))
# Degree 6: large enough for the tree (and the lanes of batches) on every order.
model = HamiltonianRegressor(degree=6, domain=[[-1, 1]] * 4).fit(X, X[:, ::-1])
fitted, cpu = time.perf_counter(), time.process_time()
with config_context(kernels="numba"):
    # One state in one checked call; a Fortran-ordered pair by the general compiled field.
    model.predict(X[:1]); model.predict(np.asfortranarray(X[:2])); model.predict(X)
    model.hamiltonian(X[:2]); model.hamiltonian(X)
    model.simulate(X[0], np.linspace(0, 0.1, 3), method="rk4")
    model.simulate(X[0], np.linspace(0, 0.1, 3), method="avf")
    model.simulate(X[:80] * 0.1, np.linspace(0, 5.0, 500), method="rk4", max_step=0.1,
                   on_failure="nan")
print(time.perf_counter() - fitted, time.process_time() - cpu)
"""


def compile_times(rows):
    """First-call latency of the compiled path: cold (empty cache) and warm (cached on disk)."""
    import tempfile

    print("# first-call latency of the compiled kernels")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        env["PYTHONPATH"] = os.pathsep.join(
            [str(Path(__file__).resolve().parents[1])] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
        for label in ("empty cache: compile", "cached on disk: load"):
            out = subprocess.run([sys.executable, "-c", COMPILE_SCRIPT], env=env, check=True,
                                 capture_output=True, text=True).stdout
            wall, cpu = (float(x) for x in out.split()[-2:])
            row(rows, "compile", f"first calls of every compiled kernel, {label}", cpu, "s CPU",
                None, f"wall {wall:.3g} s; one process: predict of one state (checked call), "
                "of two (general field) and of a batch, H of two states and of a batch, RK4, "
                "AVF (Hessian), RK4 of many states")


def fits(cfg, rows):
    print("# fits against one A.T @ A of the same design")
    # Warm up: the first fit of a process loads the compiled kernels from
    # numba's cache (about 0.4 s, a fifth of the n = 10 fit), which the
    # A.T @ A it is compared with does not pay.
    fit(layout(200), 4)
    for degree, M in cfg["fit_cases"]:
        Xt = layout(M)
        start = time.perf_counter()
        model = fit(Xt, degree)
        seconds = time.perf_counter() - start
        n_rows = Xt.shape[0] * Xt.shape[1] * 4
        gram = gram_time(n_rows, model.n_terms_, 1)
        # Issue 19's targets (against A.T @ A on every core: --all-cores).
        target = 1.0 if degree <= 10 else 0.7
        row(rows, "fit", f"fit n={degree} M={M} ({model.solver_}) / one A.T@A", seconds / gram,
            "ratio", target if M >= 8000 else None,
            f"fit {seconds:.2f} s, A.T@A {gram:.2f} s, {model.n_terms_} terms, {n_rows} rows")
    # The sketch-preconditioned solver on the largest (the last) case, for the
    # choice of "auto" (which keeps the normal equations at this size).
    start = time.perf_counter()
    model = fit(Xt, degree, solver="sketch")
    seconds = time.perf_counter() - start
    gram = gram_time(n_rows, model.n_terms_, 1)
    row(rows, "fit", f"fit n={degree} M={M} (sketch) / one A.T@A", seconds / gram, "ratio", None,
        f"fit {seconds:.2f} s, A.T@A {gram:.2f} s")
    Xt = layout(cfg["cg_M"])
    n_rows = Xt.shape[0] * Xt.shape[1] * 4
    iterations = []
    start = time.perf_counter()
    model = HamiltonianRegressor(degree=cfg["cg_degree"], domain=SYSTEM.domain, solver="iterative")
    model._progress = lambda message: (lambda i, r: iterations.append(i))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.fit(Xt)
    seconds = time.perf_counter() - start
    gram = gram_time(n_rows, model.n_terms_, 1)
    row(rows, "fit", f"fit n={cfg['cg_degree']} M={cfg['cg_M']} (iterative) / one A.T@A",
        seconds / gram, "ratio", None,
        f"{max(iterations, default=0)} CG iterations; fit {seconds:.2f} s, A.T@A {gram:.2f} s")
    for degree in cfg["iteration_cases"]:
        per_iteration, per_gram, n_terms = iteration_against_gram(degree, cfg["iteration_M"])
        row(rows, "solver choice", f"n={degree}: Gram cost / one CG iteration",
            per_gram / per_iteration, "iterations", None,
            f"{n_terms} terms; CG pays off only below this many iterations")


def iteration_against_gram(degree, M):
    """Seconds per state of one CG iteration (A x and A^T r) and of the normal equations.

    The normal equations as ``solver="normal"`` accumulates them (factored
    where that pays, see ``sk_hamiltonian._factored``).
    """
    Xt = layout(M)
    model = HamiltonianRegressor(degree=degree, domain=SYSTEM.domain)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = model._training_data(Xt, None, None)
        space = steps.build_space(model, data)
    n_states = data.states.shape[0]
    operator = DesignOperator(space, data, "derivatives", quadrature_nodes(space), "gradient")
    x = np.random.default_rng(0).normal(size=(space.n_terms, 1))

    def iteration():
        operator.rmatvec(operator.matvec(x))

    def gram():
        steps.normal_equations(model, space, data)

    return best(iteration, 2) / n_states, best(gram, 1) / n_states, space.n_terms


def scaling(cfg, rows, output):
    print("# scaling of the fit time")
    records = []
    for M in cfg["samples"]:
        Xt = layout(M)
        # One solver for the whole sweep ("auto" switches from lstsq to
        # normal at 5e7 design entries, which would break the power law).
        seconds = best(lambda: fit(Xt, cfg["samples_degree"], solver="normal"), 1)
        records.append(dict(sweep="samples", degree=cfg["samples_degree"], M=M,
                            n_rows=Xt.shape[0] * Xt.shape[1] * 4, seconds=seconds))
    Xt = layout(cfg["terms_M"])
    for degree in cfg["terms"]:
        seconds = best(lambda: fit(Xt, degree, solver="normal"), 1)
        n_terms = HamiltonianRegressor(degree=degree)._n_terms(4)
        records.append(dict(sweep="terms", degree=degree, M=cfg["terms_M"],
                            n_rows=Xt.shape[0] * Xt.shape[1] * 4, n_terms=n_terms, seconds=seconds))
    with open(output / "scale_fit.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, ["sweep", "degree", "M", "n_rows", "n_terms", "seconds"])
        writer.writeheader()
        writer.writerows(records)
    for sweep, slope, n in plot_scaling(records, output):
        row(rows, "scaling", f"log-log slope of fit time against {sweep}", slope, "slope", None,
            f"{n} fits, slope over the larger half; expected about 1 in samples, "
            f"2 in terms (the Gram matrix)")


def plot_scaling(records, output):
    """Log-log charts of the scaling sweeps with their fitted slopes; returns the slopes."""
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    slopes = []
    for ax, sweep, key, label in (
        (axes[0], "samples", "n_rows", "equations (4 per state)"),
        (axes[1], "terms", "n_terms", "terms (unknowns)"),
    ):
        part = [r for r in records if r["sweep"] == sweep]
        x = np.array([float(r[key]) for r in part])
        y = np.array([float(r["seconds"]) for r in part])
        # Fit the slope on the larger half: small fits are dominated by overheads.
        tail = slice(len(x) // 2, None) if len(x) > 3 else slice(None)
        slope, intercept = np.polyfit(np.log(x[tail]), np.log(y[tail]), 1)
        ax.loglog(x, y, "o", label="fit time")
        ax.loglog(x[tail], np.exp(intercept) * x[tail] ** slope, "-",
                  label=f"slope {slope:.2f} (larger half)")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel(label)
        ax.set_ylabel("seconds")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fixed = (f"degree {part[0]['degree']}" if sweep == "samples" else f"M = {part[0]['M']}")
        ax.set_title(f"Fit time against {sweep} ({fixed}, solver normal)")
        slopes.append((sweep, float(slope), len(x)))
    fig.tight_layout()
    fig.savefig(output / "scale.png", dpi=110)
    plt.close(fig)
    return slopes


def paper_n18(output, solvers=("auto",)):
    print("# the paper's n = 18, M = 60 000 fit, all cores")
    Xt = layout(60_000)
    rows, coefs = [], {}
    for solver in solvers:
        iterations = []
        model = HamiltonianRegressor(degree=18, domain=SYSTEM.domain, solver=solver)
        # Count the conjugate-gradient iterations, not the normal equations' blocks.
        model._progress = lambda message: (
            (lambda i, r: iterations.append(i)) if message.startswith("iteration")
            else (lambda *args: None))
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        start = time.perf_counter()
        with warnings.catch_warnings():
            # Finite differences push ~4 % of the states just outside the paper's box.
            warnings.simplefilter("ignore")
            model.fit(Xt)
        seconds = time.perf_counter() - start
        # The process's peak so far: for a later solver, the largest of the runs.
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB -> GiB
        coefs[solver] = model.coef_
        agreement = ""
        if len(coefs) > 1:
            first = next(iter(coefs.values()))
            difference = np.linalg.norm(model.coef_ - first) / np.linalg.norm(first)
            agreement = f"; coefficients {difference:.1e} relative from {solvers[0]}'s"
        note = (f"{model.n_terms_} terms, solver {solver} -> {model.solver_}, "
                f"{len(iterations)} CG iterations, cond {model.cond_:.3g}; peak RSS before "
                f"the fit {before / 2**20:.2f} GiB{agreement}")
        label = f"fit n=18 M=60000 ({model.solver_})"
        row(rows, "paper n=18", f"{label}, time", seconds / 60, "minutes", 5.0, note)
        row(rows, "paper n=18", f"{label}, peak memory (process)", peak, "GiB", 4.0, note)
    return rows


def main(argv=None):
    args = parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    info = machine()
    print("#", info)
    (args.output / ("machine_n18.txt" if args.paper_n18 else "machine.txt")).write_text(info + "\n")
    if args.paper_n18:
        rows = paper_n18(args.output, args.n18_solvers)
        name = "scale_n18.csv"
    else:
        cfg = QUICK if args.quick else FULL
        rows = []
        # One BLAS thread unless --all-cores (threadpool_limits(None) limits nothing).
        with threadpool_limits(None if _ALL_CORES else 1):
            if "evaluation" in args.groups:
                evaluation(cfg, rows)
            if "compile" in args.groups and numba_available() and not args.quick:
                compile_times(rows)
            if "fits" in args.groups:
                fits(cfg, rows)
            if "scaling" in args.groups:
                scaling(cfg, rows, args.output)
        name = "scale.csv"
    with open(args.output / name, "w", newline="") as handle:
        writer = csv.DictWriter(handle, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    print(f"# wrote {args.output / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
