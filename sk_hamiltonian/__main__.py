"""The ``sk-hamiltonian`` command: cross-validated Hamiltonian learning in one call.

Run ``sk-hamiltonian --help`` (or ``python -m sk_hamiltonian --help``).
"""

import argparse
import os
import sys
import time
import warnings

import numpy as np
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.pipeline import make_pipeline

from . import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from ._integrate import integrate
from ._report import UsageError, draw_report, load_trajectories
from .datasets import PAPER_DT, make_trajectories, single_pendulum
from .inspection import format_hamiltonian
from .model_selection import count_terms, one_standard_error_rule

EXAMPLE = dict(n_trajectories=500, n_intervals=40, noise=0.08, horizon=20.0)
QUICK = dict(n_trajectories=60, n_intervals=40, noise=0.08, horizon=5.0)
DEFAULT_DENOISE, DEFAULT_DEGREES = ["fd", "3", "5", "8"], [4, 6, 8, 10]
QUICK_DENOISE, QUICK_DEGREES = ["fd", "5"], [4, 6]
Q_KEY, N_KEY = "derivativetransformer__degree", "hamiltonianregressor__degree"
METHOD_KEY = "derivativetransformer__method"

DESCRIPTION = """\
Learn a Hamiltonian system from trajectory data (Wu, Qin & Xiu), choosing the
de-noising degree Q and the polynomial degree n by cross-validation.

Without DATA, runs the paper's Example 1 in-process: the single pendulum,
500 trajectories of 41 samples, dt = 0.01, +-8 % multiplicative noise.

The search is a GridSearchCV over (Q, n) whose folds hold out whole
trajectories; each candidate is scored by rolling it out from every held-out
trajectory's first observation and comparing with the observations (the
default score). The refit picks the candidate with the fewest terms whose
mean score is within one standard error of the best. The report gives the
chosen degrees, the number of terms, the leading terms of the learned H~,
the fit time, the H~ drift along a simulated trajectory (RK4 and the
energy-conserving averaged vector field) and, for the built-in example, the
relative error at T against the true system of the structure-preserving
model (SP) and of the component-wise baseline (non-SP, same degrees).
"""

EPILOG = """\
data files:
  .npz  an array of shape (n_trajectories, n_times, 2d) under the key
        'trajectories' (or the only array in the file); state order
        p_1..p_d, q_1..q_d; sampled every --dt.
  .csv  a header line 'trajectory,<p_1>,..,<p_d>,<q_1>,..,<q_d>', then one row
        per sample: the trajectory id, then the states. The rows of each
        trajectory are contiguous and in time order, sampled every --dt;
        lengths may differ. The header names are used in the report.

outputs (in --output, default ./sk_hamiltonian_output):
  report.png    trajectories, phase plot, errors or energy, H~ drift
                (needs matplotlib; skipped with a note without it)
  model.joblib  the fitted Pipeline (DerivativeTransformer, HamiltonianRegressor);
                load it with joblib.load

exit status: 0 on success, 2 on a usage or data error (one-line message).

examples:
  sk-hamiltonian
  sk-hamiltonian runs.npz --dt 0.05 --degrees 3 4 5 --output results
  python -m sk_hamiltonian runs.csv --dt 0.1 --denoise-degrees fd 4 6
"""


def build_parser():
    """The command's argument parser."""
    parser = argparse.ArgumentParser(
        prog="sk-hamiltonian", description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "data", nargs="?", metavar="DATA",
        help="trajectories as .npz or .csv (see below); omit to run the built-in example",
    )
    parser.add_argument(
        "--dt", type=float, metavar="DT",
        help="sampling step of DATA (required with DATA; the built-in example uses "
        "0.01 unless given)",
    )
    parser.add_argument(
        "--output", default="sk_hamiltonian_output", metavar="DIR",
        help="directory for report.png and model.joblib (default: %(default)s)",
    )
    parser.add_argument(
        "--degrees", type=int, nargs="+", metavar="N",
        help="candidate polynomial degrees n of H~ (default: "
        + " ".join(map(str, DEFAULT_DEGREES)) + ")",
    )
    parser.add_argument(
        "--denoise-degrees", nargs="+", metavar="Q",
        help="candidate de-noising degrees Q (a least-squares polynomial in time per "
        "trajectory); 'fd' means second-order finite differences without de-noising "
        "(default: " + " ".join(DEFAULT_DENOISE) + ")",
    )
    parser.add_argument(
        "--cv", type=int, default=5, metavar="K",
        help="number of cross-validation folds of whole trajectories (default: %(default)s)",
    )
    parser.add_argument(
        "--horizon", type=float, metavar="T",
        help="simulated time span of the report (default: 20 for the example, "
        "10 trajectory lengths for DATA)",
    )
    parser.add_argument(
        "--seed", type=int, default=0,
        help="seed of the example's data and of the fold shuffling (default: %(default)s)",
    )
    # Small data and grid, for the test suite.
    parser.add_argument("--quick", action="store_true", help=argparse.SUPPRESS)
    return parser


def main(argv=None):
    """Run the command.

    Parameters
    ----------
    argv : list of str, default=None
        Arguments; None reads ``sys.argv``.

    Returns
    -------
    status : int
        0 on success. Usage and data errors raise ``SystemExit(2)`` after
        printing a one-line message to stderr.
    """
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return _run(args)
    except UsageError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")


def _run(args):
    X, dt, names, title, system, horizon = _load(args)
    horizon = args.horizon if args.horizon is not None else horizon
    if not horizon > 0:
        raise UsageError(f"--horizon must be positive; got {horizon}")
    if args.cv < 2:
        raise UsageError(f"--cv must be at least 2; got {args.cv}")
    if len(X) < args.cv:
        raise UsageError(
            f"{len(X)} trajectories cannot fill {args.cv} folds: give more trajectories "
            f"or a lower --cv"
        )
    try:
        os.makedirs(args.output, exist_ok=True)
    except OSError as error:
        raise UsageError(f"cannot create the output directory {args.output}: {error}") from None
    print(f"data: {title}")
    search, fit_time, warned = _search(args, X, dt, len(names))
    best = search.best_estimator_
    model = best[-1]
    _print_choice(search, len(names))
    print(f"learned: {format_hamiltonian(model, state_names=names)}")
    print(
        f"fit time: {fit_time:.1f} s for {len(search.cv_results_['params']) * args.cv} "
        f"cross-validation fits and the refit"
        + (f" (warnings of the candidates: {', '.join(warned)})" if warned else "")
    )
    baseline = _fit_baseline(best, X)

    x0 = np.asarray(system.initial_state if system is not None else X[0][0], dtype=float)
    t = dt * np.arange(int(round(horizon / dt)) + 1)
    origin = (
        "u0* = (" + ", ".join(f"{v:g}" for v in x0) + ")" if system is not None
        else "the first observation of the first trajectory"
    )
    print(f"\nsimulated from {origin} up to T = {t[-1]:g} (RK4 step {dt:g}):")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # leaving the domain is reported as a failure
        rk4, avf = _rollout(model, x0, t, "rk4"), _rollout(model, x0, t, "avf")
        curves = {"SP": rk4}
        if baseline is not None:
            curves["non-SP"] = _rollout(baseline[-1], x0, t, "rk4")
    truth, errors = None, {}
    if system is not None:
        truth = system.solve(x0, t, max_step=dt / 10)
        errors = _print_errors(t, curves, truth)
    _print_drift(t, model, {"RK4": rk4, "AVF": avf})

    import joblib

    model_path = os.path.join(args.output, "model.joblib")
    joblib.dump(best, model_path)
    print(f"\nmodel: {model_path} (a fitted Pipeline; load it with joblib.load)")
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("figure: skipped, matplotlib is not installed (pip install matplotlib)")
        return 0
    figure_path = os.path.join(args.output, "report.png")
    draw_report(figure_path, t, curves, truth, errors, model, rk4, avf, X, names, title)
    print(f"figure: {figure_path}")
    return 0


def _load(args):
    """The trajectories, dt, state names, a title, the true system (or None), T."""
    if args.data is None:
        setting = QUICK if args.quick else EXAMPLE
        dt = PAPER_DT if args.dt is None else args.dt
        if not dt > 0:
            raise UsageError(f"--dt must be positive; got {dt}")
        system = single_pendulum()
        X = make_trajectories(
            system, setting["n_trajectories"], setting["n_intervals"], dt,
            noise=setting["noise"], random_state=args.seed,
        )
        title = (
            f"single pendulum (Example 1 of Wu, Qin & Xiu): {X.shape[0]} trajectories x "
            f"{X.shape[1]} samples, dt={dt:g}, +-{setting['noise']:.0%} noise"
        )
        return X, dt, ["p", "q"], title, system, setting["horizon"]
    if args.dt is None:
        raise UsageError(
            "--dt is required with a data file: give the sampling step, e.g. --dt 0.01"
        )
    if not args.dt > 0:
        raise UsageError(f"--dt must be positive; got {args.dt}")
    X, names = load_trajectories(args.data)
    lengths = [len(T) for T in X]
    span = f"{min(lengths)}" + (f"-{max(lengths)}" if max(lengths) > min(lengths) else "")
    title = (
        f"{args.data}: {len(lengths)} trajectories x {span} samples, {len(names)} states, "
        f"dt={args.dt:g}"
    )
    return X, args.dt, names, title, None, 10.0 * (lengths[0] - 1) * args.dt


def _parse_denoise(values):
    out = []
    for value in values:
        if value.lower() in ("fd", "finite_difference"):
            out.append("fd")
            continue
        try:
            Q = int(value)
        except ValueError:
            raise UsageError(
                f"--denoise-degrees: {value!r} is neither an integer nor 'fd'"
            ) from None
        if Q < 1:
            raise UsageError(f"--denoise-degrees: Q must be at least 1; got {Q}")
        out.append(Q)
    return list(dict.fromkeys(out))


def _grid(args, X, n_states):
    """Candidate parameters, keeping only those the data can support."""
    denoise = _parse_denoise(
        args.denoise_degrees or (QUICK_DENOISE if args.quick else DEFAULT_DENOISE)
    )
    degrees = sorted(set(args.degrees or (QUICK_DEGREES if args.quick else DEFAULT_DEGREES)))
    if degrees[0] < 1:
        raise UsageError(f"--degrees: n must be at least 1; got {degrees[0]}")
    shortest = min(len(T) for T in X)
    # Q = n_times - 1 interpolates the noise; finite differences need 3 samples.
    dropped = [
        Q for Q in denoise if (shortest < 3 if Q == "fd" else Q > shortest - 2)
    ]
    if dropped:
        print(f"note: dropped de-noising degrees {dropped}: trajectories have {shortest} samples")
    denoise = [Q for Q in denoise if Q not in dropped]
    # At least twice as many equations as unknowns in every training fold.
    equations = (args.cv - 1) / args.cv * sum(len(T) for T in X) * n_states
    too_big = [
        n for n in degrees if 2 * count_terms(HamiltonianRegressor(n), n_states) > equations
    ]
    if too_big:
        print(f"note: dropped degrees {too_big}: too many unknowns for the data")
    degrees = [n for n in degrees if n not in too_big]
    if not denoise or not degrees:
        raise UsageError(
            "no candidate left: give lower --degrees or --denoise-degrees, or more data"
        )
    grid = []
    if "fd" in denoise:
        grid.append({METHOD_KEY: ["finite_difference"], N_KEY: degrees})
    Qs = [Q for Q in denoise if Q != "fd"]
    if Qs:
        grid.append({METHOD_KEY: ["polynomial"], Q_KEY: Qs, N_KEY: degrees})
    return grid


def _describe(params):
    if hasattr(params, "get_params"):
        params = params.get_params()
    if params[METHOD_KEY] == "finite_difference":
        return f"finite differences, n={params[N_KEY]}"
    return f"Q={params[Q_KEY]}, n={params[N_KEY]}"


class _ProgressScorer:
    """The default (rollout) score, printing a line per finished candidate.

    GridSearchCV (without n_jobs) runs the folds of a candidate one after the
    other, so every ``n_splits`` calls close a candidate.
    """

    def __init__(self, n_candidates, n_splits, stream):
        self.n_candidates, self.n_splits, self.stream = n_candidates, n_splits, stream
        self.scores, self.done = [], 0

    def __call__(self, estimator, X, y=None):
        score = estimator.score(X)
        self.scores.append(score)
        if len(self.scores) == self.n_splits:
            self.done += 1
            width = len(str(self.n_candidates))
            print(
                f"  [{self.done:{width}d}/{self.n_candidates}] {_describe(estimator):28s} "
                f"score {np.mean(self.scores):.4f} +- {np.std(self.scores):.4f}",
                file=self.stream, flush=True,
            )
            self.scores = []
        return score


def _search(args, X, dt, n_states):
    grid = _grid(args, X, n_states)
    n_candidates = sum(int(np.prod([len(v) for v in g.values()])) for g in grid)
    pipe = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())
    print(
        f"search: {n_candidates} candidates x {args.cv} folds of whole trajectories, "
        f"score = rollouts vs held-out observations, refit = one-standard-error rule",
        flush=True,
    )
    search = GridSearchCV(
        pipe, grid, cv=KFold(args.cv, shuffle=True, random_state=args.seed),
        scoring=_ProgressScorer(n_candidates, args.cv, sys.stderr),
        refit=one_standard_error_rule(pipe, n_states=n_states),
    )
    start = time.perf_counter()
    # Poor candidates warn by the hundred (rollouts leaving the domain); the
    # report names the kinds once instead.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        search.fit(X)
    return search, time.perf_counter() - start, sorted({w.category.__name__ for w in caught})


def _print_choice(search, n_states):
    results = search.cv_results_
    means, stds = results["mean_test_score"], results["std_test_score"]
    i, top = search.best_index_, int(np.nanargmax(means))
    print(
        f"\nchosen: {_describe(search.best_estimator_)} -> "
        f"{search.best_estimator_[-1].n_terms_} terms (score {means[i]:.4f} +- {stds[i]:.4f}; "
        f"best mean {means[top]:.4f} at {_describe(results['params'][top])}, "
        f"{count_terms(search.estimator, n_states, results['params'][top])} terms)"
    )


def _fit_baseline(best, X):
    baseline = make_pipeline(
        DerivativeTransformer(**best[0].get_params()),
        VectorFieldRegressor(degree=best[-1].degree),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return baseline.fit(X)
        except ValueError as error:  # e.g. more unknowns than data at this degree
            print(f"note: non-SP baseline not fitted: {error}")
            return None


def _rollout(model, x0, t, method):
    """Simulate, keeping what precedes a failure; return (states, n_valid_times)."""
    Y, failed_at = integrate(model._integrator(method), x0[None], t, None)
    return Y[:, 0], int(failed_at[0])


def _print_errors(t, curves, truth):
    norms = np.linalg.norm(truth, axis=1)
    errors = {}
    for label, (Y, ok) in curves.items():
        e = np.full(t.shape, np.nan)
        e[:ok] = np.linalg.norm(Y[:ok] - truth[:ok], axis=1) / norms[:ok]
        errors[label] = e
        if ok < t.shape[0]:
            print(f"  {label:7s} relative error at T: failed (blew up at t = {t[ok]:g})")
        else:
            print(
                f"  {label:7s} relative error at T: {e[-1]:.3g} "
                f"(mean over [0, T]: {np.mean(e):.3g})"
            )
    return errors


def _print_drift(t, model, runs):
    for label, (Y, ok) in runs.items():
        if ok < 2:
            print(f"  H~ drift, {label}: the simulation failed at the first step")
            continue
        H = model.hamiltonian(Y[:ok])
        tail = "" if ok == t.shape[0] else f" (until it failed at t = {t[ok]:g})"
        print(f"  H~ drift max|H~(t) - H~(0)|, {label}: {np.max(np.abs(H - H[0])):.2g}{tail}")


if __name__ == "__main__":
    sys.exit(main())
