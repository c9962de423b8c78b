"""The ``sk-hamiltonian`` command: cross-validated Hamiltonian learning in one call.

Run ``sk-hamiltonian --help`` (or ``python -m sk_hamiltonian --help``). The
sub-commands ``show`` and ``simulate`` reuse a saved model (``_cli_model``).
"""

import argparse
import math
import os
import sys
import tempfile
import time
import warnings

import numpy as np
from sklearn.model_selection import GridSearchCV, GroupKFold, KFold
from sklearn.pipeline import make_pipeline

from . import DerivativeTransformer, DomainWarning, HamiltonianRegressor, VectorFieldRegressor
from . import _cli_model
from ._datafiles import load_trajectories
from ._integrate import integrate
from ._report import UsageError, describe_energy_trend, draw_report
from .datasets import PAPER_DT, make_trajectories, single_pendulum
from .inspection import format_hamiltonian
from .io import save
from .model_selection import count_terms, segment_trajectories

EXAMPLE = dict(n_trajectories=500, n_intervals=40, noise=0.08, horizon=20.0)
QUICK = dict(n_trajectories=60, n_intervals=40, noise=0.08, horizon=5.0)
DEFAULT_DENOISE, DEFAULT_DEGREES = ["fd", "3", "5", "8"], [4, 6, 8, 10]
QUICK_DENOISE, QUICK_DEGREES = ["fd", "5"], [4, 6]
Q_KEY, N_KEY = "derivativetransformer__degree", "hamiltonianregressor__degree"
METHOD_KEY = "derivativetransformer__method"
THRESHOLD_KEY = "hamiltonianregressor__threshold"
# Sparsity thresholds searched with --threshold auto (0: the dense fit).
AUTO_THRESHOLDS = [0.0, 1e-3, 1e-2, 3e-2, 0.1]
# Fewest samples a trajectory needs for any derivative estimate.
MIN_SAMPLES = 3
# Segments of a record too long to cross-validate whole: the paper's
# trajectory length (one de-noising polynomial each with the default window),
# shortened so that every fold gets at least two segments.
SEGMENT_SAMPLES = 41
# The model file the command writes (sk_hamiltonian.save: no pickle).
MODEL_FILE = "model.skh"
SUBCOMMANDS = {"show": _cli_model.show, "simulate": _cli_model.simulate}

DESCRIPTION = """\
Learn a Hamiltonian system from trajectory data (Wu, Qin & Xiu), choosing the
de-noising degree Q and the polynomial degree n by cross-validation.

Without DATA, runs the paper's Example 1 in-process: the single pendulum,
500 trajectories of 41 samples, dt = 0.01, +-8 % multiplicative noise.

The search is a GridSearchCV over (Q, n) whose folds hold out whole
trajectories; each candidate is scored by rolling it out from an initial
state fitted to every held-out trajectory's observations and comparing with
them (the default score). With fewer trajectories than folds (e.g. one long record),
the trajectories are cut into contiguous segments and each fold holds out one
contiguous stretch of them (blocked cross-validation). The refit takes the
candidate with the best mean score: on noisy pendulum and Morse data it came
closer to the best choice than the one-standard-error rule, which prefers
fewer terms (docs/cross_validation.rst). The report gives the chosen
degrees, the number of terms, the leading terms of the learned H~, the fit
time, the trend of H~ along the data (a conservation check), the H~ drift
along a simulated trajectory (RK4 and the energy-conserving averaged vector
field) and, for the built-in example, the relative error at T against the
true system of the structure-preserving model (SP) and of the component-wise
baseline (non-SP, same degrees).
"""

EPILOG = """\
data files:
  .npz  an array of shape (n_trajectories, n_times, 2d) under the key
        'trajectories' (or the only array in the file besides 'times'); state
        order p_1..p_d, q_1..q_d; sampled every --dt. Time stamps instead of
        --dt: an array 'times' of shape (n_trajectories, n_times), or the
        time as the first column of the trajectories (then 1 + 2d columns).
  .csv  a header line 'trajectory,<p_1>,..,<p_d>,<q_1>,..,<q_d>', then one row
        per sample: the trajectory id, then the states. The rows of each
        trajectory are contiguous and in time order, sampled every --dt;
        lengths may differ. The header names are used in the report.
        Time stamps instead of --dt: a column named 't' or 'time' right
        after 'trajectory' ('trajectory,t,<p_1>,..').
  Time stamps may have any spacing (strictly increasing per trajectory);
  with them, --dt is not needed. Trajectories with fewer than 3 samples are
  dropped, with a note naming them.

outputs (in --output, default ./sk_hamiltonian_output):
  report.png    trajectories, phase plot, errors or energy, H~ drift
                (needs matplotlib; skipped with a note without it)
  model.skh     the fitted Pipeline (DerivativeTransformer, HamiltonianRegressor)
                in the safe model format (no pickle): load it with
                sk_hamiltonian.load, or reuse it with the commands below
  model.joblib  only with --joblib: the same Pipeline as a pickle. Loading a
                pickle runs any code it carries: load it only if you made it
                or trust whoever did; share model.skh instead.

reuse a saved model:
  sk-hamiltonian show MODEL       the learned H~, its terms, domain, fitted
                                  attributes and provenance
  sk-hamiltonian simulate MODEL --x0 P Q --t-end T -o out.csv
                                  trajectories from new initial states, as CSV
                                  (and a figure); see
                                  'sk-hamiltonian simulate --help'

exit status: 0 on success, 2 on a usage or data error (one-line message).

examples:
  sk-hamiltonian
  sk-hamiltonian runs.npz --dt 0.05 --degrees 3 4 5 --output results
  python -m sk_hamiltonian runs.csv --dt 0.1 --denoise-degrees fd 4 6
  sk-hamiltonian record_with_times.csv --segment-length 60
  sk-hamiltonian damped.npz --dt 0.02 --damping
  sk-hamiltonian show sk_hamiltonian_output/model.skh
  sk-hamiltonian simulate sk_hamiltonian_output/model.skh --x0 0.5 1 --t-end 20 -o run.csv

A DATA file named 'show' or 'simulate' needs a path: ./show.
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
        help="sampling step of DATA (required with DATA unless it carries time stamps; "
        "the built-in example uses 0.01 unless given)",
    )
    parser.add_argument(
        "--output", default="sk_hamiltonian_output", metavar="DIR",
        help=f"directory for report.png and {MODEL_FILE} (default: %(default)s)",
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
        help="number of cross-validation folds of whole trajectories (default: %(default)s; "
        "on noisy pendulum and Morse data 3 folds chose worse, and 10 folds no "
        "better at up to twice the time: docs/cross_validation.rst)",
    )
    parser.add_argument(
        "--segment-length", type=int, metavar="S",
        help="with fewer trajectories than folds, cut them into segments of S samples "
        f"(default: {SEGMENT_SAMPLES}, fewer if the folds need it)",
    )
    parser.add_argument(
        "--horizon", type=float, metavar="T",
        help="simulated time span of the report (default: 20 for the example, "
        "10 times the median trajectory duration for DATA)",
    )
    parser.add_argument(
        "--seed", type=int, default=0,
        help="seed of the example's data and of the fold shuffling (default: %(default)s)",
    )
    parser.add_argument(
        "--damping", action="store_true",
        help="fit linear friction with H~ (HamiltonianRegressor(damping=True)), for data "
        "that lose energy",
    )
    parser.add_argument(
        "--threshold", default="0", metavar="VALUE|auto",
        help="sparsity threshold of H~ (HamiltonianRegressor(threshold=...)): terms of the "
        "readable form below VALUE times the largest are dropped; 'auto' adds "
        + ", ".join(f"{v:g}" for v in AUTO_THRESHOLDS) + " to the search grid (default: "
        "%(default)s, every term kept)",
    )
    parser.add_argument(
        "--joblib", action="store_true",
        help="also write model.joblib (a pickle: loading it runs any code it carries; "
        f"share {MODEL_FILE} instead)",
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
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    if argv and argv[0] in SUBCOMMANDS:
        command = SUBCOMMANDS[argv[0]]
        run = lambda: command(argv[1:])  # noqa: E731
    else:
        args = parser.parse_args(argv)
        run = lambda: _run(args)  # noqa: E731
    try:
        return run()
    except UsageError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")


def _run(args):
    data = _load(args)
    _check_options(args)
    data = _segment_if_needed(args, data)
    horizon = args.horizon if args.horizon is not None else data.horizon
    _check_positive("--horizon", horizon)
    _prepare_output(args.output)
    print(f"data: {data.title}")
    X, names = data.X, data.names
    search, fit_time, warned = _search(args, data)
    best = search.best_estimator_
    model = best[-1]
    _print_choice(search, len(names))
    print(f"learned: {format_hamiltonian(model, state_names=names)}")
    print(
        f"fit time: {fit_time:.1f} s for {len(search.cv_results_['params']) * args.cv} "
        f"cross-validation fits and the refit"
        + (f" (warnings of the candidates: {', '.join(warned)})" if warned else "")
    )
    print(describe_energy_trend(model))
    baseline = _fit_baseline(best, X)

    system = data.system
    x0 = np.asarray(system.initial_state if system is not None else data.states[0][0])
    t = data.step * np.arange(int(round(horizon / data.step)) + 1)
    origin = (
        "u0* = (" + ", ".join(f"{v:g}" for v in x0) + ")" if system is not None
        else "the first observation of the first trajectory"
    )
    print(f"\nsimulated from {origin} up to T = {t[-1]:g} (RK4 step {data.step:g}):")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # leaving the domain is reported as a failure
        rk4, avf = _rollout(model, x0, t, "rk4"), _rollout(model, x0, t, "avf")
        curves = {"SP": rk4}
        if baseline is not None:
            curves["non-SP"] = _rollout(baseline[-1], x0, t, "rk4")
    truth, errors = None, {}
    if system is not None:
        truth = system.solve(x0, t, max_step=data.step / 10)
        errors = _print_errors(t, curves, truth)
    with warnings.catch_warnings():
        # Where the rollouts leave the training box was said above (or shows
        # as a failure); evaluating H~ along them need not repeat it.
        warnings.simplefilter("ignore", DomainWarning)
        _print_drift(t, model, {"RK4": rk4, "AVF": avf})

    model_path = os.path.join(args.output, MODEL_FILE)
    save(best, model_path, provenance=_provenance(args, data, search, fit_time))
    print(
        f"\nmodel: {model_path} (a fitted Pipeline; sk-hamiltonian show {model_path}, or "
        f"sk_hamiltonian.load in Python)"
    )
    if args.joblib:
        import joblib

        pickle_path = os.path.join(args.output, "model.joblib")
        joblib.dump(best, pickle_path)
        print(
            f"model: {pickle_path} (--joblib; a pickle: loading it runs any code it carries, "
            f"so load it only if you trust its source)"
        )
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("figure: skipped, matplotlib is not installed (pip install matplotlib)")
        return 0
    figure_path = os.path.join(args.output, "report.png")
    observed = (data.times[0] - data.times[0][0], data.states)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)
        draw_report(
            figure_path, t, curves, truth, errors, model, rk4, avf, observed, names, data.title
        )
    print(f"figure: {figure_path}")
    return 0


class _Data:
    """What the command fits and reports on.

    ``X`` is what the pipeline gets (time stamps as first column when
    ``stamped``); ``times`` and ``states`` are the same trajectories split;
    ``dt`` is the transformer's step (None with time stamps), ``step`` the
    (median) sampling step; ``groups`` the CV groups of segments (or None).
    """

    def __init__(self, X, names, ids, stamped, dt, title, system=None, horizon=None):
        self.X, self.names, self.ids, self.stamped = X, names, ids, stamped
        self.dt, self.title, self.system = dt, title, system
        self.groups = None
        self._split(horizon)

    def _split(self, horizon=None):
        if self.stamped:
            self.times = [np.asarray(T)[:, 0] for T in self.X]
            self.states = [np.asarray(T)[:, 1:] for T in self.X]
        else:
            self.times = [self.dt * np.arange(len(T)) for T in self.X]
            self.states = [np.asarray(T) for T in self.X]
        steps = np.concatenate([np.diff(t) for t in self.times])
        self.step = self.dt if self.dt is not None else float(np.median(steps))
        # By default, ten times the median duration over all trajectories.
        self.horizon = horizon or 10.0 * float(np.median([t[-1] - t[0] for t in self.times]))

    def use_segments(self, segments, ids, groups):
        self.X, self.ids, self.groups = segments, ids, groups
        self._split()


def _check_positive(option, value):
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f"{option} must be a positive finite number; got {value:g}")


def _check_options(args):
    _parse_threshold(args.threshold)
    if args.cv < 2:
        raise UsageError(f"--cv must be at least 2; got {args.cv}")
    if args.segment_length is not None and args.segment_length < MIN_SAMPLES:
        raise UsageError(
            f"--segment-length must be at least {MIN_SAMPLES} samples; got {args.segment_length}"
        )


def _prepare_output(directory):
    """Create the output directory and check, up front, that files can be written there."""
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as error:
        raise UsageError(f"cannot create the output directory {directory}: {error}") from None
    try:
        handle, probe = tempfile.mkstemp(dir=directory, prefix=".sk-hamiltonian-probe-")
        os.close(handle)
        os.remove(probe)
    except OSError as error:
        raise UsageError(
            f"cannot write to the output directory {directory} ({error.strerror or error}): "
            f"choose another one with --output"
        ) from None


def _segment_if_needed(args, data):
    """Cut the trajectories into segments when they cannot fill the folds."""
    if len(data.X) >= args.cv:
        return data
    total = sum(len(T) for T in data.X)
    length = args.segment_length or min(SEGMENT_SAMPLES, total // (2 * args.cv))
    if length < MIN_SAMPLES or total // length < args.cv:
        raise UsageError(
            f"{len(data.X)} trajectories of {total} samples in all cannot fill {args.cv} "
            f"folds, even cut into segments of {max(length, MIN_SAMPLES)} samples: give more "
            f"data, a lower --cv or a shorter --segment-length"
        )
    segments, groups = segment_trajectories(data.X, length, n_groups=args.cv)
    ids = []
    for label, T in zip(data.ids, data.X):
        count = len(segment_trajectories([np.asarray(T)], length)[0])
        ids.extend(f"{label}, segment {k}" for k in range(count))
    n_records = len(data.X)
    data.use_segments(segments, ids, groups)
    longest = max(len(S) for S in segments)
    print(
        f"note: {n_records} {'trajectory' if n_records == 1 else 'trajectories'} cannot fill "
        f"{args.cv} folds: cut into {len(segments)} segments of {length} samples"
        + (f" (the last of a record up to {longest})" if longest > length else "")
        + "; blocked cross-validation, each fold holds out a contiguous stretch of segments"
    )
    return data


def _load(args):
    """The data to fit, with their names, title, true system (or None) and horizon."""
    if args.data is None:
        setting = QUICK if args.quick else EXAMPLE
        dt = PAPER_DT if args.dt is None else args.dt
        _check_positive("--dt", dt)
        system = single_pendulum()
        X = make_trajectories(
            system, setting["n_trajectories"], setting["n_intervals"], dt,
            noise=setting["noise"], random_state=args.seed,
        )
        title = (
            f"single pendulum (Example 1 of Wu, Qin & Xiu): {X.shape[0]} trajectories x "
            f"{X.shape[1]} samples, dt={dt:g}, +-{setting['noise']:.0%} noise"
        )
        return _Data(
            X, ["p", "q"], [str(k) for k in range(len(X))], False, dt, title, system,
            setting["horizon"],
        )
    if args.dt is not None:
        _check_positive("--dt", args.dt)
    loaded = load_trajectories(args.data)
    if loaded.stamped and args.dt is not None:
        raise UsageError(
            f"{args.data} carries time stamps; --dt would contradict them: drop --dt"
        )
    if not loaded.stamped and args.dt is None:
        raise UsageError(
            "--dt is required with a data file without time stamps: give the sampling "
            "step, e.g. --dt 0.01, or add the times (see --help)"
        )
    X, ids = _drop_short(loaded.trajectories, loaded.ids, args.data)
    lengths = [len(T) for T in X]
    span = f"{min(lengths)}" + (f"-{max(lengths)}" if max(lengths) > min(lengths) else "")
    data = _Data(X, loaded.names, ids, loaded.stamped, args.dt, "")
    sampling = (
        f"dt={args.dt:g}" if not loaded.stamped
        else f"time stamps (median step {data.step:.4g})"
    )
    data.title = (
        f"{args.data}: {len(lengths)} trajectories x {span} samples, {len(loaded.names)} "
        f"states, {sampling}"
    )
    return data


def _drop_short(X, ids, path):
    """Drop trajectories too short for any derivative estimate, saying which."""
    short = [k for k, T in enumerate(X) if len(T) < MIN_SAMPLES]
    if not short:
        return X, ids
    if len(short) == len(X):
        raise UsageError(
            f"{path}: every trajectory has fewer than {MIN_SAMPLES} samples; time "
            f"derivatives need at least {MIN_SAMPLES} per trajectory"
        )
    named = ", ".join(f"{ids[k]} ({len(X[k])} samples)" for k in short[:5])
    more = f" and {len(short) - 5} more" if len(short) > 5 else ""
    print(
        f"note: dropped {len(short)} of {len(X)} trajectories with fewer than {MIN_SAMPLES} "
        f"samples, from which no time derivative can be estimated: {named}{more}"
    )
    kept = [k for k in range(len(X)) if k not in set(short)]
    X = [X[k] for k in kept]
    if len({len(T) for T in X}) == 1:
        X = np.stack(X)
    return X, [ids[k] for k in kept]


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


def _parse_threshold(value):
    if value.strip().lower() == "auto":
        return list(AUTO_THRESHOLDS)
    try:
        threshold = float(value)
    except ValueError:
        raise UsageError(f"--threshold: {value!r} is neither a number nor 'auto'") from None
    if not (math.isfinite(threshold) and 0 <= threshold < 1):
        raise UsageError(
            f"--threshold must be 'auto' or a number in [0, 1), a fraction of the largest "
            f"term; got {value}"
        )
    return [threshold]


def _grid(args, data):
    """Candidate parameters, keeping only those the data can support."""
    X, n_states = data.X, len(data.names)
    denoise = _parse_denoise(
        args.denoise_degrees or (QUICK_DENOISE if args.quick else DEFAULT_DENOISE)
    )
    degrees = sorted(set(args.degrees or (QUICK_DEGREES if args.quick else DEFAULT_DEGREES)))
    if degrees[0] < 1:
        raise UsageError(f"--degrees: n must be at least 1; got {degrees[0]}")
    lengths = [len(T) for T in X]
    shortest = min(lengths)
    # Q = n_times - 1 interpolates the noise (trajectories have at least 3 samples).
    dropped = [Q for Q in denoise if Q != "fd" and Q > shortest - 2]
    if dropped:
        which = (
            f"trajectories have {shortest} samples" if max(lengths) == shortest
            else f"the shortest trajectory ({data.ids[int(np.argmin(lengths))]}) has "
            f"{shortest} samples, and Q must be at most samples - 2"
        )
        print(f"note: dropped de-noising degrees {dropped}: {which}")
    denoise = [Q for Q in denoise if Q not in dropped]
    # At least twice as many equations as unknowns in every training fold.
    equations = (args.cv - 1) / args.cv * sum(len(T) for T in X) * n_states
    too_big = [
        n for n in degrees if 2 * count_terms(HamiltonianRegressor(n), n_states) > equations
    ]
    if too_big:
        print(f"note: dropped degrees {too_big}: too many unknowns for the data")
    degrees = [n for n in degrees if n not in too_big]
    if not denoise:
        raise UsageError(
            f"no de-noising degree left: give --denoise-degrees at most {shortest - 2}, or 'fd'"
        )
    if not degrees:
        raise UsageError("no degree left: give lower --degrees, or more data")
    grid = []
    if "fd" in denoise:
        grid.append({METHOD_KEY: ["finite_difference"], N_KEY: degrees})
    Qs = [Q for Q in denoise if Q != "fd"]
    if Qs:
        grid.append({METHOD_KEY: ["polynomial"], Q_KEY: Qs, N_KEY: degrees})
    thresholds = _parse_threshold(args.threshold)
    if thresholds != [0.0]:  # the default grid stays today's
        for entry in grid:
            entry[THRESHOLD_KEY] = thresholds
    return grid


def _describe(params):
    if hasattr(params, "get_params"):
        params = params.get_params()
    sparse = f", threshold={params[THRESHOLD_KEY]:g}" if params.get(THRESHOLD_KEY) else ""
    if params[METHOD_KEY] == "finite_difference":
        return f"finite differences, n={params[N_KEY]}{sparse}"
    return f"Q={params[Q_KEY]}, n={params[N_KEY]}{sparse}"


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


def _search(args, data):
    grid = _grid(args, data)
    n_candidates = sum(int(np.prod([len(v) for v in g.values()])) for g in grid)
    pipe = make_pipeline(
        DerivativeTransformer(dt=data.dt), HamiltonianRegressor(damping=args.damping)
    )
    if data.groups is None:
        folds, what = KFold(args.cv, shuffle=True, random_state=args.seed), "whole trajectories"
    else:
        folds, what = GroupKFold(args.cv), "contiguous segments"
    print(
        f"search: {n_candidates} candidates x {args.cv} folds of {what}, "
        f"score = rollouts vs held-out observations, refit = best mean score",
        flush=True,
    )
    search = GridSearchCV(
        pipe, grid, cv=folds,
        scoring=_ProgressScorer(n_candidates, args.cv, sys.stderr),
        refit=True,
    )
    start = time.perf_counter()
    # Poor candidates warn by the hundred (rollouts leaving the domain); the
    # report names the kinds once instead.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        search.fit(data.X, groups=data.groups)
    return search, time.perf_counter() - start, sorted({w.category.__name__ for w in caught})


def _provenance(args, data, search, fit_time):
    """What the model file records about the data and the search."""
    lengths = [len(T) for T in data.X]
    i = search.best_index_
    return {
        "data": data.title,
        "data_shape": (
            f"{len(lengths)} trajectories x {min(lengths)}"
            + (f"-{max(lengths)}" if max(lengths) > min(lengths) else "")
            + f" samples x {len(data.names)} states"
        ),
        "state_names": list(data.names),
        "fit_time_s": round(fit_time, 3),
        "cv": (
            f"GridSearchCV, {args.cv} folds of "
            f"{'whole trajectories' if data.groups is None else 'contiguous segments'}, "
            f"{len(search.cv_results_['params'])} candidates, rollout score, refit = best mean"
        ),
        "cv_choice": _describe(search.best_estimator_),
        "cv_score": (
            f"{search.cv_results_['mean_test_score'][i]:.4f} +- "
            f"{search.cv_results_['std_test_score'][i]:.4f} over the folds"
        ),
        "damping": bool(args.damping),
    }


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
    # Imported here to keep this note self-contained in the command's module.
    from .model_selection import candidate_table

    table = candidate_table(results)
    others = [k for k in np.flatnonzero(table["tied"]) if k != i]
    if others:
        names = "; ".join(_describe(results["params"][k]) for k in others[:4])
        more = f" and {len(others) - 4} more" if len(others) > 4 else ""
        print(
            f"tied: {len(others)} other candidate{'s' if len(others) > 1 else ''} within one "
            f"standard error of the best ({names}{more}): the cross-validation cannot tell "
            f"them apart, so this pick among them is partly chance"
        )
    else:
        print("no tie: every other candidate scores more than one standard error below")


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
