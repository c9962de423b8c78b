"""The search of the ``sk-hamiltonian`` command: a GridSearchCV over (Q, n[, threshold]).

Its boundary is :func:`run_search`: the command's options and data in, a
:class:`SearchResult` out. The report reads only that result, so another
search can take this one's place by returning the same fields.
"""

import re
import sys
import time
import warnings
from collections import namedtuple

import numpy as np
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV, GroupKFold, KFold, ParameterGrid
from sklearn.pipeline import make_pipeline

from .._derivatives import DerivativeTransformer
from .._hamiltonian import HamiltonianRegressor
from ..model_selection import count_terms
from .errors import UsageError
from .parser import (
    DEFAULT_DEGREES,
    DEFAULT_DENOISE,
    QUICK_DEGREES,
    QUICK_DENOISE,
    parse_denoise,
    parse_domain,
    parse_threshold,
)
from .words import counted

Q_KEY, N_KEY = "derivativetransformer__degree", "hamiltonianregressor__degree"
METHOD_KEY = "derivativetransformer__method"
THRESHOLD_KEY = "hamiltonianregressor__threshold"

SearchResult = namedtuple(
    "SearchResult",
    ["best", "cv_results", "best_index", "labels", "n_fits", "fit_time", "warned", "summary",
     "refine", "refinement"],
    defaults=(None, None),
)
SearchResult.__doc__ = """What a search hands to the report and the model file.

``best``: the refitted Pipeline (DerivativeTransformer, HamiltonianRegressor);
``cv_results``: a ``cv_results_``-like dict (``params``, ``mean_test_score``,
``std_test_score``, ``split<k>_test_score``); ``best_index``: the chosen
candidate's row in it; ``labels``: a short description per candidate;
``n_fits``: the cross-validation fits run (the refit aside); ``fit_time``:
seconds for the whole search with the refit; ``warned``: the sorted names of
the warning categories the candidates raised; ``summary``: one line on how
the search ran, for the model file's provenance; ``refine``: None, or
``refine(regressor)``, the search's refinement of the chosen coefficients on
the raw trajectories, applied again after a refit (returns its outcome);
``refinement``: the search's own outcome of it (None without one).
"""


def run_search(args, data):
    """Cross-validate the candidates on ``data`` and refit the best mean score.

    Prints the plan on stdout and a line per finished candidate on stderr.

    Parameters
    ----------
    args : argparse.Namespace
        The command's options (``--degrees``, ``--denoise-degrees``,
        ``--threshold``, ``--domain``, ``--cv``, ``--seed``, ``--damping``, ``--quick``).
    data : Data
        What to fit (``X``, ``dt``, ``groups``, ``names``, ``ids``).

    Returns
    -------
    result : SearchResult

    Raises
    ------
    UsageError
        If every cross-validation fit failed: one line with the reason.
    """
    domain = parse_domain(args.domain, data.names)
    grid = _grid(args, data)
    n_candidates = sum(int(np.prod([len(v) for v in g.values()])) for g in grid)
    pipe = make_pipeline(
        DerivativeTransformer(dt=data.dt),
        HamiltonianRegressor(damping=args.damping, domain=domain),
    )
    folds, what = cv_folds(args, data)
    print(
        f"search: {counted(n_candidates, 'candidate')} x {args.cv} folds of {what}, "
        f"score = rollouts vs held-out observations, refit = best mean score",
        flush=True,
    )
    search = GridSearchCV(
        pipe, grid, cv=folds,
        scoring=_ProgressScorer(n_candidates, args.cv, sys.stderr),
        refit=True,
    )
    try:
        warned, fit_time = fit_recording_warnings(search, data)
    except ValueError as error:
        # GridSearchCV's words when no fit succeeded, with every traceback.
        failed = re.match(r"\s*All the (\d+) fits failed", str(error))
        if failed is None:
            raise
        reason = _first_failure(pipe, grid, folds, data)
        raise UsageError(_shared_failure(int(failed.group(1)), str(error), reason, data.names))\
            from None
    params = search.cv_results_["params"]
    return SearchResult(
        best=search.best_estimator_,
        cv_results=search.cv_results_,
        best_index=int(search.best_index_),
        labels=[_describe(p) for p in params],
        n_fits=len(params) * args.cv,
        fit_time=fit_time,
        warned=warned,
        summary=(
            f"GridSearchCV, {args.cv} folds of {what}, {counted(len(params), 'candidate')}, "
            f"rollout score, refit = best mean"
        ),
    )


def fit_recording_warnings(search, data):
    """Fit ``search`` on ``data``: the sorted names of the warnings' categories, and the seconds.

    Poor candidates warn by the hundred (rollouts leaving the domain); the
    report names the kinds once instead.
    """
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        search.fit(data.X, groups=data.groups)
    return sorted({w.category.__name__ for w in caught}), time.perf_counter() - start


def search_degrees(args):
    """The polynomial degrees of the options (``--degrees``, or the defaults), checked."""
    degrees = sorted(set(args.degrees or (QUICK_DEGREES if args.quick else DEFAULT_DEGREES)))
    if degrees[0] < 1:
        raise UsageError(f"--degrees: n must be at least 1; got {degrees[0]}")
    return degrees


def _first_failure(pipe, grid, folds, data):
    """Why the first candidate failed on the first fold, from the exception itself.

    GridSearchCV keeps only the formatted tracebacks; fitting that one
    candidate again (deterministic, like every fit here) gives the message as
    raised. None if it fits this time.
    """
    params = next(iter(ParameterGrid(grid)))
    train, _ = next(folds.split(data.X, groups=data.groups))
    X = data.X[train] if isinstance(data.X, np.ndarray) else [data.X[k] for k in train]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            clone(pipe).set_params(**params).fit(X)
        except Exception as error:  # noqa: BLE001 -- whatever it was, it is the reason
            return str(error)
    return None


def _shared_failure(n_fits, message, reason, names):
    """One line for a search in which every fit failed: how many, and why."""
    n_reasons = message.count("fits failed with the following error:")
    if reason is None:  # not reproduced: the last line of GridSearchCV's report
        reason = message.strip().splitlines()[-1]
    reason = " ".join(reason.split())
    why = (
        "with the same error" if n_reasons == 1
        else f"{n_reasons} different errors; the first candidate's"
    )
    line = f"every candidate failed to fit ({n_fits} cross-validation fits, {why}): {reason}"
    if "`domain`" in reason:
        line += (
            f" On the command line: one --domain LOW HIGH per state variable, in the order "
            f"{', '.join(names)}."
        )
    return line


def cv_folds(args, data):
    """The folds of the search and their words: whole trajectories, or blocked segments.

    Data prepared for the default search carry its folds (those of
    ``HamiltonianSearchCV(cv=--cv)``); the paper's grid shuffles whole
    trajectories with ``--seed``.
    """
    n = len(data.X)
    if data.folds is not None:
        folds = [(np.setdiff1d(np.arange(n), test), test) for test in data.folds]
        return folds, "contiguous segments" if data.segmented else "whole trajectories"
    if data.groups is None:
        return KFold(args.cv, shuffle=True, random_state=args.seed), "whole trajectories"
    return GroupKFold(args.cv), "contiguous segments"


def usable_denoise(args, data):
    """The de-noising degrees of the options the data allow, with a note on those dropped."""
    denoise = parse_denoise(
        args.denoise_degrees or (QUICK_DENOISE if args.quick else DEFAULT_DENOISE)
    )
    lengths = [len(T) for T in data.X]
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
    if not denoise:
        raise UsageError(
            f"no de-noising degree left: give --denoise-degrees at most {shortest - 2}, or 'fd'"
        )
    return denoise


def _grid(args, data):
    """Candidate parameters, keeping only those the data can support."""
    X, n_states = data.X, len(data.names)
    denoise = usable_denoise(args, data)
    degrees = search_degrees(args)
    # At least twice as many equations as unknowns in every training fold.
    equations = (args.cv - 1) / args.cv * sum(len(T) for T in X) * n_states
    too_big = [
        n for n in degrees if 2 * count_terms(HamiltonianRegressor(n), n_states) > equations
    ]
    if too_big:
        print(f"note: dropped degrees {too_big}: too many unknowns for the data")
    degrees = [n for n in degrees if n not in too_big]
    if not degrees:
        raise UsageError("no degree left: give lower --degrees, or more data")
    grid = []
    if "fd" in denoise:
        grid.append({METHOD_KEY: ["finite_difference"], N_KEY: degrees})
    Qs = [Q for Q in denoise if Q != "fd"]
    if Qs:
        grid.append({METHOD_KEY: ["polynomial"], Q_KEY: Qs, N_KEY: degrees})
    thresholds = parse_threshold(args.threshold or "0")
    if thresholds != [0.0]:  # the default grid stays today's
        for entry in grid:
            entry[THRESHOLD_KEY] = thresholds
    return grid


def _describe(params):
    """A candidate in a few words, from its grid parameters or its pipeline."""
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
