"""Fit the observed steps or the estimated derivatives? The paper's examples, side by side.

For each of the paper's clean examples (2: exponential, 3: Henon-Heiles,
4: Cherry, 5: double pendulum) with the paper's data (M trajectories of J steps
of dt = 0.01 from the system's domain, seed 0) and for a range of degrees, four
fits see the same trajectories:

``SP-derivatives``
    ``HamiltonianRegressor()``, the paper's fit on second-order
    finite-difference derivatives; simulated with RK4 at step dt.
``SP-steps``
    ``HamiltonianRegressor(fit_on="steps")``: the AVF map at the data step
    reproduces the observed steps; simulated with AVF at the data step (its
    default).
``SP-simpson``
    ``HamiltonianRegressor(fit_on="simpson")``: Simpson's rule over each pair
    of consecutive steps reproduces ``x2 - x0`` (the paper's ``J = 2`` gives
    one pair per trajectory); simulated with RK4 at step dt, as the
    derivative fits.
``non-SP-derivatives``, ``non-SP-steps`` and ``non-SP-simpson``
    ``VectorFieldRegressor`` fitted the same three ways (the baseline; its
    steps fit runs its own averaged map at the data step).

Each model is rolled out from the paper's u0* up to T = 20 and compared with
the true solution (RK4 at dt / 10); the table gives each method's relative
error ``||u~(T) - u(T)|| / ||u(T)||`` at its best degree, and the mean over
[0, T]. A rollout that fails counts as infinite.

Example 1 (noisy pendulum, 8 %, J = 40) is run at the degrees the
cross-validated command picks (Q = 3 de-noising, n = 8 and 10) with the
de-noised states of the same transformer: the steps fit uses those states.

Run::

    python benchmarks/steps_study.py            # all examples (~30 min on 2 cores)
    python benchmarks/steps_study.py --quick    # two degrees each, n = 8 for Ex. 1, M = 5 000 for Ex. 5
    python benchmarks/steps_study.py --examples exponential noisy   # a subset
    python benchmarks/steps_study.py --methods SP-simpson non-SP-simpson  # some methods

Prints a table and writes ``benchmarks/results/steps_study.csv``.
"""

import argparse
import csv
import os
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "2")

import numpy as np  # noqa: E402

from sk_hamiltonian import (  # noqa: E402
    DerivativeTransformer,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian.datasets import PAPER_DT, load_system, make_trajectories  # noqa: E402

T_END = 20.0
METHODS = ("SP-derivatives", "SP-steps", "SP-simpson", "non-SP-derivatives", "non-SP-steps",
           "non-SP-simpson")
CLEAN = {
    "exponential": list(range(4, 15)),
    "henon_heiles": [3, 4, 5, 6],
    "cherry": [3, 4, 5, 6],
    "double_pendulum": [15, 16],
}


def make_model(method, degree, domain):
    Regressor = HamiltonianRegressor if method.startswith("SP") else VectorFieldRegressor
    return Regressor(degree=degree, domain=domain, fit_on=method.rsplit("-", 1)[1])


def rollout(model, method, x0, t):
    # The paper's set-up for derivative (and Simpson) fits, RK4 at dt; a steps
    # model runs the map it was fitted to (AVF at the data step, its default).
    max_step = None if method.endswith("steps") else PAPER_DT
    return model.simulate(x0, t, max_step=max_step, on_failure="nan")


def errors(Y, truth):
    e = np.linalg.norm(Y - truth, axis=1) / np.linalg.norm(truth, axis=1)
    e = np.where(np.isnan(e), np.inf, e)
    return float(e[-1]), float(np.mean(e))


def run_example(name, degrees, n_trajectories=None, Xt=None, methods=METHODS,
                use_domain=True):
    system = load_system(name)
    domain = system.domain if use_domain else None
    settings = system.paper_settings
    M = n_trajectories or settings["n_trajectories"]
    if Xt is None:
        X = make_trajectories(system, M, settings["n_intervals"], PAPER_DT, random_state=0)
        Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
    t = PAPER_DT * np.arange(int(round(T_END / PAPER_DT)) + 1)
    truth = system.solve(system.initial_state, t, max_step=PAPER_DT / 10)
    rows = []
    for degree in degrees:
        for method in methods:
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    model = make_model(method, degree, domain).fit(Xt)
                except ValueError as error:  # e.g. underdetermined
                    print(f"  {name} n={degree} {method}: not fitted ({error})")
                    continue
                fit_s = time.perf_counter() - start
                Y = rollout(model, method, system.initial_state, t)
            at_T, mean = errors(Y, truth)
            rows.append(dict(example=name, M=M, degree=degree, method=method, err_T20=at_T,
                             mean_err=mean, fit_s=fit_s, n_terms=model.n_terms_))
            print(f"  {name:16s} n={degree:2d} {method:19s} err(T=20) {at_T:9.2e}  "
                  f"mean {mean:9.2e}  fit {fit_s:6.1f} s", flush=True)
    return rows


def noisy_pendulum(degrees, methods):
    system = load_system("single_pendulum")
    s = system.paper_settings
    X = make_trajectories(system, s["n_trajectories"], s["n_intervals"], PAPER_DT,
                          noise=s["noise"], random_state=0)
    Xt = DerivativeTransformer(dt=PAPER_DT, degree=3).fit_transform(X)
    # The noisy data reach |q| ~ 6, beyond the paper's domain: the basis lives
    # on their bounding box, as in the sk-hamiltonian command.
    return run_example("single_pendulum", degrees, Xt=Xt,
                       methods=[m for m in methods if m.startswith("SP")], use_domain=False)


def best_table(rows):
    lines = [f"{'example':16s} {'method':19s} {'best n':>6s} {'err(T=20)':>10s} {'mean':>10s}"]
    for example in dict.fromkeys(r["example"] for r in rows):
        for method in METHODS:
            mine = [r for r in rows if r["example"] == example and r["method"] == method]
            if not mine:
                continue
            best = min(mine, key=lambda r: r["err_T20"])
            lines.append(f"{example:16s} {method:19s} {best['degree']:6d} "
                         f"{best['err_T20']:10.2e} {best['mean_err']:10.2e}")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer degrees, smaller Example 5")
    parser.add_argument("--output", default=str(Path(__file__).parent / "results"))
    parser.add_argument("--examples", nargs="+", default=[*CLEAN, "noisy"],
                        choices=[*CLEAN, "noisy"], help="which examples to run (default: all)")
    parser.add_argument("--dp-trajectories", type=int, default=None, metavar="M",
                        help="trajectories of the double pendulum (default: the paper's "
                        "20 000; 5 000 with --quick)")
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS,
                        help="which fits to run (default: all)")
    args = parser.parse_args(argv)
    rows = []
    for name, degrees in CLEAN.items():
        if name not in args.examples:
            continue
        if args.quick:
            degrees = degrees[:2]
        M = None
        if name == "double_pendulum":
            M = args.dp_trajectories or (5000 if args.quick else None)
        rows += run_example(name, degrees, n_trajectories=M, methods=args.methods)
    # The example's own function would refit with M=500 at the paper's domain;
    # here the domain is the bounding box of the data, as the command does.
    if "noisy" in args.examples:
        rows += [dict(r, example="single_pendulum (noisy)") for r in noisy_pendulum(
            [8] if args.quick else [8, 10], args.methods)]
    print("\nEach method at its best degree:")
    print(best_table(rows))
    Path(args.output).mkdir(parents=True, exist_ok=True)
    path = Path(args.output) / "steps_study.csv"
    with open(path, "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"\nwritten: {path}")


if __name__ == "__main__":
    main()
