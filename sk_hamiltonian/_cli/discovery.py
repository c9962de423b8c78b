"""The command's default search: model spaces, fit targets, de-noising, degree and sparsity.

:func:`run_discovery` runs :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV`
and returns the same :class:`~sk_hamiltonian._cli.search.SearchResult` as the
paper's grid (:func:`~sk_hamiltonian._cli.search.run_search`), so the report
reads either.
"""

import numpy as np

from .._trajectories import check_trajectories
from ..model_selection import HamiltonianSearchCV
from ..model_selection._refine import refine_on_trajectories
from .errors import UsageError
from .parser import parse_domain, parse_threshold
from .search import SearchResult, cv_folds, fit_recording_warnings, search_degrees, usable_denoise
from .words import counted

# Fit targets the command searches unless told (--fit-on).
DEFAULT_FIT_ON = ("derivatives", "steps", "simpson", "weak")
QUICK_FIT_ON = ("derivatives", "weak")


def run_discovery(args, data):
    """Search spaces, fit targets, de-noising, degree and threshold on ``data``.

    Parameters
    ----------
    args : argparse.Namespace
        The command's options.
    data : Data
        What to fit (``X``, ``dt``, ``groups``, ``names``).

    Returns
    -------
    result : SearchResult

    Raises
    ------
    UsageError
        If no candidate could be fitted: one line with the reason.
    """
    denoise = usable_denoise(args, data)
    degrees = search_degrees(args)
    thresholds = parse_threshold(args.threshold or "auto")
    fit_on = args.fit_on or (QUICK_FIT_ON if args.quick else DEFAULT_FIT_ON)
    folds, what = cv_folds(args, data)
    search = HamiltonianSearchCV(
        dt=data.dt,
        denoise_degrees=["finite_difference" if q == "fd" else q for q in denoise],
        degrees=degrees, fit_on=fit_on, thresholds=thresholds, damping=args.damping,
        domain=parse_domain(args.domain, data.names), cv=folds, verbose=1,
    )
    print(
        f"search: model spaces (polynomial, periodic or mixed positions; general or "
        f"mechanical), fit targets {', '.join(fit_on)}, de-noising {', '.join(map(str, denoise))}, "
        f"degrees {', '.join(map(str, degrees))}, thresholds "
        f"{', '.join(f'{v:g}' for v in thresholds)}; {args.cv} folds of {what}",
        flush=True,
    )
    try:
        warned, fit_time = fit_recording_warnings(search, data)
    except ValueError as error:
        # The search names its own parameters; the command's options differ.
        message = " ".join(str(error).split()).replace("(degrees)", "(--degrees)")
        if "`domain`" in message:
            message += (
                f" On the command line: one --domain LOW HIGH per state variable, in the order "
                f"{', '.join(data.names)}."
            )
        raise UsageError(f"the search failed: {message}") from None
    if search.preparation_.get("one_level"):
        print(f"note: {search.preparation_['one_level']['message']}")
    for note in judgement_notes(search.judgement_):
        print(f"note: {note}")
    results = search.cv_results_
    n_states = len(data.names)
    labels = [_describe(p, data.names[n_states // 2:]) for p in results["params"]]
    n_candidates = len(labels)
    refine = None
    if search.refinement_["status"] == "refined":
        trajectories, _ = check_trajectories(data.X)

        def refine(regressor):
            return refine_on_trajectories(regressor, trajectories, data.dt)

    return SearchResult(
        best=search.best_estimator_,
        cv_results=results,
        best_index=int(search.best_index_),
        labels=labels,
        n_fits=n_candidates * search.n_splits_,
        fit_time=fit_time,
        warned=warned,
        summary=(
            f"HamiltonianSearchCV, {args.cv} folds of {what}, "
            f"{counted(n_candidates, 'candidate')} "
            f"({counted(int(np.sum(results['stage'] == 'finalist')), 'finalist')} scored by "
            f"rollouts), selection = {search.selection}"
        ),
        refine=refine,
        refinement=search.refinement_,
    )


def _describe(params, positions):
    """A candidate in a few words: layout, fit target, space, degree, threshold."""
    get = params.get
    layout = ("finite differences" if get("derivativetransformer__method") == "finite_difference"
              else f"Q={get('derivativetransformer__degree')}")
    parts = [layout, get("hamiltonianregressor__fit_on", "derivatives")]
    for key, word in (("periodic", "periodic"), ("mixed", "mixed")):
        flags = get(f"hamiltonianregressor__{key}")
        if flags is not None:
            d = len(flags) // 2
            named = [positions[i] for i in range(d) if flags[d + i]]
            if named:
                parts.append(f"{word} {' '.join(named)}")
    if get("hamiltonianregressor__momentum_degree") == 2:
        parts.append("mechanical")
    if get("hamiltonianregressor__separable"):
        parts.append("separable")
    if get("hamiltonianregressor__terms") is not None:
        parts.append(f"{len(get('hamiltonianregressor__terms'))} named terms")
    parts.append(f"n={get('hamiltonianregressor__degree')}")
    threshold = get("hamiltonianregressor__threshold", 0.0)
    if threshold:
        parts.append(f"threshold={threshold:g}")
    return ", ".join(parts)


def judgement_notes(judgement):
    """What stage 3's verdict (``judgement_``) changed, one sentence each (none if nothing)."""
    if judgement is None:
        return []
    notes = []
    if judgement.get("untied"):
        notes.append(f"fitted to the trajectories, a candidate the held-out scores ranked lower "
                     f"({', '.join(judgement['untied'])}) does better than their choice "
                     f"(information criterion); it is taken")
    if judgement.get("pruned"):
        notes.append(f"fitted to the trajectories, the chosen candidate does better without "
                     f"{', '.join(judgement['pruned'])} (information criterion); those are "
                     f"dropped")
    if judgement["kind"] == "cosine law" and judgement["best"]:
        best = judgement["best"]
        if judgement["n_terms"][best] < judgement["n_terms"][0]:
            why = (f"with fewer terms, information criterion {judgement['bic'][best]:.6g} "
                   f"against {judgement['bic'][0]:.6g}")
        else:
            why = (f"weighted residual sum lower by {judgement['gain']:.3g}, standard error "
                   f"{judgement['gain_se']:.2g}")
        # The offer put cos q in place of a Taylor series or of an angle's harmonics.
        replaced = [term for term in judgement["terms"][0] if term not in judgement["terms"][best]]
        notes.append(f"the trajectories prefer cos q to {', '.join(replaced)}, which the "
                     f"candidates kept ({why}); the cosine law is chosen")
    return notes
