"""Stage 2 of the search: degrees and thresholds in the kept spaces, one finalist per layout and fit target.

For one derivative layout and fit target, each model space is assembled once
per degree (:class:`~._fold_problems.FoldProblems`), from the smallest: every
threshold is a solve on the same normal equations, and a degree whose best
candidate is no better than the best below it ends the space's search. The
candidate with the fewest terms among those the data cannot reject against
the lowest held-out equation error (:func:`~._selection.pick_within`) is the
pair's *finalist*, scored by rollouts against the held-out observations.
"""

import itertools
import time
import warnings

import numpy as np
from sklearn.utils.parallel import Parallel, delayed

from .._trajectories import unpack_derivatives
from ._fold_problems import FoldProblems, take
from ._selection import DEGREE_GAIN, EXACT_FLOOR, pick_within

# Training equations per unknown a candidate needs in every fold.
ROWS_PER_UNKNOWN = 2


def failure_reason(failures):
    """The first failure's message, as the end of an error message."""
    return f" The first candidate's error: {failures[0]}" if failures else ""


def search_finalists(layouts, fit_on, folds, spaces, kept, offset, *, degrees, thresholds,
                     damping, domain, scorer, error_score, n_jobs):
    """Stage 2: :func:`search_unit` for every layout and fit target, in parallel.

    Parameters
    ----------
    layouts : dict
        Each searched derivative layout's key to its transformed trajectories.
    fit_on : list of str
        The fit targets.
    folds : list of ndarray of int
    spaces : list of dict
        Every screened space; ``kept`` indexes the ones searched.
    kept : list of int
    offset : int
        Records before these (the screen's): finalists' rows count from it.
    degrees, thresholds, damping, domain, scorer, error_score
        As :func:`search_unit` takes them.
    n_jobs : int or None
        Pairs searched at once (joblib).

    Returns
    -------
    records : list of dict
        Every candidate's record, ``space`` an index into ``spaces`` and
        ``stage`` ``"search"`` or ``"finalist"``.
    finalists : list of int
        The finalists' rows, ``offset`` plus their position in ``records``.
    failures : list of str
        The messages of the spaces that could not be set up.
    """
    pairs = list(itertools.product(layouts, fit_on))
    results = Parallel(n_jobs=n_jobs)(
        delayed(search_unit)(layouts[key], folds, [spaces[k] for k in kept], target, degrees,
                             thresholds, damping, domain, key, rollout=True, scorer=scorer,
                             error_score=error_score)
        for key, target in pairs
    )
    records, finalists, failures = [], [], []
    for unit_records, finalist, unit_failures in results:
        failures.extend(unit_failures)
        for record in unit_records:
            record.update(space=kept[record["space"]], stage="search")
        if finalist is not None:
            unit_records[finalist]["stage"] = "finalist"
            finalists.append(offset + len(records) + finalist)
        records.extend(unit_records)
    return records, finalists, failures


def search_unit(Xt, folds, spaces, fit_on, degrees, thresholds, damping, domain, denoise,
                rollout, scorer=None, error_score=np.nan):
    """Every candidate of one layout and fit target in ``spaces``; with ``rollout``, its finalist scored.

    Returns the candidates' records (``space`` is the index into ``spaces``),
    the row of the finalist (None without ``rollout`` or without one), and
    the messages of the spaces that could not be set up. The finalist's
    record also holds its regressor fitted on all the data (``fitted``).
    The finalist is scored in each fold by :func:`score_fold` (``scorer``);
    a score that raises counts as ``error_score``, or is raised with
    ``error_score="raise"``.
    """
    records, problems, failures = [], [], []
    n_folds = len(folds)
    for k, space in enumerate(spaces):
        params = {**space, "fit_on": fit_on, "damping": damping}
        # Degrees from the smallest, each assembled on its own: a degree whose
        # best candidate is no better than the best below (by more than one
        # standard error and DEGREE_GAIN) ends the space's search, as the
        # larger ones, which cost the most, would add terms the data do not
        # need.
        best = None
        for degree in degrees:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    problem = FoldProblems(params, Xt, folds, degree, domain)
                except ValueError as error:  # e.g. a constant variable, or no Simpson pairs
                    failures.append(str(error))
                    break
            size = problem.n_unknowns(degree)
            n_train = problem.n_rows * (n_folds - 1) / n_folds
            if ROWS_PER_UNKNOWN * size > n_train:
                if best is None:
                    # The space got no candidate at all: say why, or an
                    # error downstream ("no model space could be set up")
                    # would carry no reason.
                    failures.append(
                        f"degree {degree} has {size} unknowns, which need "
                        f"{ROWS_PER_UNKNOWN * size} rows ({ROWS_PER_UNKNOWN} per unknown), "
                        f"but a training fold holds about {int(n_train)}: give more or "
                        f"longer trajectories, or lower degrees (degrees).")
                break
            problems.append(problem)
            found = [candidate(problem, degree, threshold, n_folds)
                     for threshold in thresholds]
            for record in found:
                record.update(denoise=denoise, fit_on=fit_on, space=k, size=size,
                              problem=len(problems) - 1)
            records.extend(found)
            errors = np.array([r["errors"] for r in found])
            here = int(np.nanargmin(errors.mean(axis=1))) if np.isfinite(errors).any() else None
            if here is None:
                break
            mean = errors[here].mean()
            if best is not None and (best[0] - mean <= max(best[1], DEGREE_GAIN * best[0])
                                     or best[0] <= EXACT_FLOOR):
                break
            best = (mean, errors[here].std() / np.sqrt(n_folds))
    finalist = None
    if rollout and records:
        finalist, _ = pick_within(
            np.array([r["errors"] for r in records]), np.array([r["n_terms"] for r in records]),
            np.array([r["size"] for r in records]),
        )
    if finalist is not None:
        record = records[finalist]
        problem = problems[record["problem"]]
        started = time.perf_counter()
        for fold, test in enumerate(folds):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, solution = problem.solve(record["degree"], record["threshold"], fold)
                model = problem.fitted(record["degree"], record["threshold"], solution, fold)
                try:
                    record["scores"][fold] = score_fold(model, take(Xt, test), scorer)
                except Exception:
                    if isinstance(error_score, str) and error_score == "raise":
                        raise
                    record["scores"][fold] = error_score
        record["score_time"] = (time.perf_counter() - started) / n_folds
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _, solution = problem.solve(record["degree"], record["threshold"])
            record["fitted"] = problem.fitted(record["degree"], record["threshold"], solution)
    for record in records:
        del record["problem"]
    return records, finalist, failures


def score_fold(model, Xt, scorer=None):
    """A fold-fitted regressor's score on the held-out layout ``Xt``.

    Without ``scorer``, its rollout score against the held-out observations
    (:meth:`~sk_hamiltonian.HamiltonianRegressor.score`). With one,
    ``scorer(model, X, y)`` on the held-out states ``X`` and their estimated
    time derivatives ``y`` (both of shape ``(n_samples, n_states)``), as for
    a regressor fitted on states and derivatives.
    """
    if scorer is None:
        return model.score(Xt)
    data = unpack_derivatives(Xt)
    states, derivatives = data.states, data.derivatives
    if isinstance(states, list):
        states, derivatives = np.concatenate(states), np.concatenate(derivatives)
    n_states = states.shape[-1]
    return float(scorer(model, states.reshape(-1, n_states), derivatives.reshape(-1, n_states)))


def candidate(problem, degree, threshold, n_folds):
    """One candidate's record: its equation error in every fold, its terms on all the data."""
    started = time.perf_counter()
    errors = np.full(n_folds, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fold in range(n_folds):
            columns, solution = problem.solve(degree, threshold, fold)
            errors[fold] = problem.equation_error(columns, solution.coef, fold)
        _, solution = problem.solve(degree, threshold)
    return dict(degree=degree, threshold=threshold, errors=errors,
                n_terms=int(solution.n_kept),
                fit_time=(time.perf_counter() - started) / (n_folds + 1),
                scores=np.full(n_folds, np.nan), score_time=np.nan, tied=False)
