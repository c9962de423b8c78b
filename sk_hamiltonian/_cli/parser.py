"""The options of the ``sk-hamiltonian`` fitting command: help, defaults and checks.

The sub-commands ``show`` and ``simulate`` have their own parsers
(:mod:`.model`).
"""

import argparse
import math

from .. import __version__
from .._memory import bytes_text, memory_limit
from .._resampling import largest_resamples, resample_bytes
from .._state_order import STATE_ORDERS
from .data import MIN_SAMPLES, SEGMENT_SAMPLES
from .errors import UsageError
from .resampling import DEFAULT_RESAMPLES

DEFAULT_DENOISE, DEFAULT_DEGREES = ["fd", "3", "5", "8"], [4, 6, 8, 10]
QUICK_DENOISE, QUICK_DEGREES = ["fd", "5"], [4, 6]
# Sparsity thresholds searched with --threshold auto (0: the dense fit).
AUTO_THRESHOLDS = [0.0, 1e-3, 1e-2, 3e-2, 0.1]
# The model file the command writes (sk_hamiltonian.save: no pickle).
MODEL_FILE = "model.skh"

DESCRIPTION = """\
Learn a Hamiltonian system from trajectory data (Wu, Qin & Xiu): a
cross-validated search over the model space (each position polynomial,
periodic or mixed; a general or a mechanical Hamiltonian), the fit target
(estimated derivatives, observed steps, pairs of steps by Simpson's rule),
the de-noising degree Q, the degree n and the sparsity threshold, which
prints the law it finds as a formula.

Without DATA, runs the paper's Example 1 in-process: the single pendulum,
500 trajectories of 41 samples, dt = 0.01, +-8 % multiplicative noise.

The search (sk_hamiltonian.model_selection.HamiltonianSearchCV) holds out
whole trajectories: within each derivative layout and fit target it keeps
the fewest terms among the candidates tied on the held-out least-squares
residual, then scores those finalists by rolling them out from an initial
state fitted to every held-out trajectory's observations and comparing with
them (the default score), and keeps, among the finalists the data cannot
tell apart, the fewest terms, the smoothest de-noising and the least biased
fit target; the chosen model's coefficients are then fitted to the raw
trajectories themselves (output error, weighted by a noise model estimated
from the residuals; docs/default_search.rst). With --paper-grid, the paper's
polynomial space only: a GridSearchCV over (Q, n), refit = the best mean
score, no refinement. With
fewer trajectories than folds (e.g. one long record), the trajectories are
cut into contiguous segments and each fold holds out one contiguous stretch
of them (blocked cross-validation). The chosen model is then refitted on 100
bootstrap resamples of whole trajectories (--resamples, --no-resample), which
give each term of H~ how often it is kept and a 90 % interval for its
coefficient, and the figure a prediction band (the least-squares refits'
spread; the search's refinement is applied to the point estimate again).
The report gives the choice,
the learned H~ with those intervals, the fit time, the trend of H~ along the
data (a conservation check), the H~ drift along a simulated trajectory (RK4
and the energy-conserving averaged vector field, which is implicit: without
numba, pip install "sk_hamiltonian[fast]", each of its steps costs several
RK4 steps) and, for the built-in
example, the relative error at T against the true system of the
structure-preserving model (SP) and of the component-wise baseline (non-SP,
same space and degree, every term).
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
  report.png    trajectories (the whole span and a zoomed window, with the
                resampled refits' 90 % band), phase plot,
                errors or energy, H~ drift (needs matplotlib; skipped with a
                note without it)
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

exit status: 0 on success, 2 on a usage or data error (one-line message),
  including a search in which every candidate failed to fit (the message
  names the reason; e.g. a constant state variable needs --domain); 130
  when interrupted (Ctrl-C), with one line naming the files written.

examples:
  sk-hamiltonian
  sk-hamiltonian runs.npz --dt 0.05 --degrees 3 4 5 --output results
  python -m sk_hamiltonian runs.csv --dt 0.1 --denoise-degrees fd 4 6
  sk-hamiltonian record_with_times.csv --segment-length 60
  sk-hamiltonian damped.npz --dt 0.02 --damping
  sk-hamiltonian fixed_momentum.npz --dt 0.02 --domain 0 1 --domain -3 3
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
        "--names", nargs="+", metavar="NAME",
        help="names of the state variables in the order of DATA's columns (e.g. --names L "
        "theta): used in the formulas, the figure and the model file, instead of a CSV "
        "header's or p, q (p1.., q1..); they do not reorder the columns (--order does)",
    )
    parser.add_argument(
        "--order", default="pq", metavar="pq|qp",
        help="order of DATA's state columns: pq, momenta first (p1..pd, q1..qd), or qp, "
        "positions first (q1..qd, p1..pd, as in PySINDy and most lab files); with qp the "
        "columns (and --names, given in file order) are exchanged into p, q order on "
        "loading, in which the report, figures and model file list them "
        "(default: %(default)s)",
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
        "--threshold", default=None, metavar="VALUE|auto",
        help="sparsity threshold of H~ (HamiltonianRegressor(threshold=...)): terms of the "
        "readable form below VALUE times the largest are dropped; 'auto' searches "
        + ", ".join(f"{v:g}" for v in AUTO_THRESHOLDS) + " (default: auto; 0, every term "
        "kept, with --paper-grid)",
    )
    parser.add_argument(
        "--fit-on", nargs="+", choices=("derivatives", "steps", "simpson", "weak"), metavar="TARGET",
        help="fit targets searched: derivatives, steps, simpson, weak (default: all four; "
        "derivatives with --paper-grid)",
    )
    parser.add_argument(
        "--paper-grid", action="store_true",
        help="the paper's setting: a GridSearchCV over (Q, n) in the polynomial space, "
        "derivative fits, every term kept unless --threshold says otherwise (the command's "
        "earlier default, before it searched model spaces, fit targets and thresholds)",
    )
    parser.add_argument(
        "--domain", type=float, nargs=2, action="append", metavar=("LOW", "HIGH"),
        help="the box on which H~ is fitted and trusted, one --domain per state variable in "
        "the data's order (p_1..p_d, q_1..q_d) (HamiltonianRegressor(domain=...)); needed "
        "when a variable is constant in the data (default: the data's bounding box)",
    )
    parser.add_argument(
        "--resamples", type=int, default=DEFAULT_RESAMPLES, metavar="N",
        help="refit the chosen model on N bootstrap resamples of whole trajectories, for "
        "each term's inclusion and 90%% interval in the report and the model file, and the "
        "prediction band in the figure (default: %(default)s; 0: off)",
    )
    parser.add_argument(
        "--no-resample", dest="resamples", action="store_const", const=0,
        help="no resampling (the same as --resamples 0)",
    )
    parser.add_argument(
        "--joblib", action="store_true",
        help="also write model.joblib (a pickle: loading it runs any code it carries; "
        f"share {MODEL_FILE} instead)",
    )
    parser.add_argument(
        "--version", action="version", version=f"%(prog)s {__version__}",
        help="print the version of sk_hamiltonian and exit",
    )
    # Small data and grid, for the test suite.
    parser.add_argument("--quick", action="store_true", help=argparse.SUPPRESS)
    return parser


def check_options(args):
    """Refuse options that are wrong whatever the data."""
    if args.order not in STATE_ORDERS:
        raise UsageError(
            f"--order must be pq (momenta first) or qp (positions first); got {args.order!r}"
        )
    if args.threshold is not None:
        parse_threshold(args.threshold)
    if args.paper_grid and args.fit_on and set(args.fit_on) != {"derivatives"}:
        raise UsageError("--paper-grid fits derivatives only: drop --fit-on, or --paper-grid")
    if args.resamples < 0:
        raise UsageError(f"--resamples must be 0 (off) or more; got {args.resamples}")
    if args.cv < 2:
        raise UsageError(f"--cv must be at least 2; got {args.cv}")
    if args.segment_length is not None and args.segment_length < MIN_SAMPLES:
        raise UsageError(
            f"--segment-length must be at least {MIN_SAMPLES} samples; got {args.segment_length}"
        )


def check_resamples(n_resamples, n_trajectories, n_coefficients=1):
    """Refuse a ``--resamples`` whose refits memory cannot hold.

    Before the search, with one coefficient per refit (the least any model
    has), so that an absurd count is refused at once; after it, with the
    chosen model's coefficients.
    """
    need = resample_bytes(n_resamples, n_trajectories, n_coefficients)
    if need > memory_limit():
        largest = largest_resamples(n_trajectories, n_coefficients)
        raise UsageError(
            f"--resamples {n_resamples:,}: the refits would hold about {bytes_text(need)} "
            f"(each resample's draw of {n_trajectories:,} trajectories and its "
            f"{n_coefficients:,} coefficient(s)), beyond the memory limit of "
            f"{bytes_text(memory_limit())}; give --resamples {largest:,} or fewer (default "
            f"{DEFAULT_RESAMPLES}), or --no-resample"
        )


def parse_domain(domain, names):
    """The ``--domain`` intervals as ``[[low, high], ...]``, one per state; None if not given."""
    if domain is None:
        return None
    if len(domain) != len(names):
        raise UsageError(
            f"--domain: give one --domain LOW HIGH per state variable ({', '.join(names)}), "
            f"{len(names)} in all; got {len(domain)}"
        )
    for name, (low, high) in zip(names, domain):
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise UsageError(
                f"--domain {low:g} {high:g} (for {name}): LOW and HIGH must be finite "
                f"numbers with LOW < HIGH"
            )
    return [[float(low), float(high)] for low, high in domain]


def parse_denoise(values):
    """The de-noising degrees of ``--denoise-degrees``: 'fd' or integers Q >= 1."""
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


def parse_threshold(value):
    """The thresholds of ``--threshold``: one number in [0, 1), or the grid of 'auto'."""
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
