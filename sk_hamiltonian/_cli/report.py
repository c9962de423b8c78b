"""The printed lines of the ``sk-hamiltonian`` report.

Nothing here knows how the search ran: the choice is read from a
:class:`~sk_hamiltonian._cli.search.SearchResult` (the refitted pipeline, a
``cv_results_``-like dict, the chosen index and the candidates' labels).
"""

import numpy as np

from .._conservation import TREND_SIZE, TREND_Z, trend_verdict
from ..model_selection import candidate_table
from .words import counted

# |z| above which a large trend the rule does not count is still reported as a hint.
HINT_Z = 3.0


def describe_energy_trend(model):
    """One line: the trend of the learned energy along the data, and what it suggests.

    The verdict is the estimator's own rule (:func:`~sk_hamiltonian._conservation.trend_verdict`):
    a trend counts when it is both significant and large.
    """
    rate, z = model.energy_trend_, model.energy_trend_z_
    if not (np.isfinite(rate) and np.isfinite(z)):
        return "energy trend of H~ along the data: not available (too few samples)"
    verdict, change, period = trend_verdict(rate, z, model.time_scale_)
    per_period = (f"{change:.2%} of its spread per period ({period:.3g})"
                  if np.isfinite(change) else "a significant change")
    if verdict is None and HINT_Z < abs(z) <= TREND_Z and change > TREND_SIZE:
        # Conservative data scatter within |z| <= 2.1 (the test suite's seeds);
        # a large trend at 3 < |z| <= 4 is a hint the report should not hide.
        direction = "falls" if rate < 0 else "rises"
        fix = ("--damping fits friction if it is there" if rate < 0
               else "a conservative model is the best this package offers")
        reading = (
            f"H~ {direction} along the data ({per_period}), but not clearly (a trend counts "
            f"from |z| > {TREND_Z:g}): the data cannot tell it from noise; {fix}"
        )
    elif verdict is None and abs(z) <= TREND_Z:
        reading = (
            f"within the noise (a trend counts from |z| > {TREND_Z:g} and "
            f"{TREND_SIZE:.0%} of the spread per period): the data look conservative"
        )
    elif verdict is None:
        reading = (
            f"significant but small ({per_period}, below {TREND_SIZE:.0%}): the data look "
            f"conservative"
        )
    elif verdict == "loses" and np.any(model.damping_):
        reading = f"H~ falls along the data ({per_period}), as the fitted friction has it"
    elif verdict == "loses":
        reading = (
            f"H~ falls along the data ({per_period}): they look dissipative (friction), which "
            f"a conservative model cannot follow; --damping (HamiltonianRegressor(damping=True)) "
            f"can, or the model fits poorly where the data go"
        )
    else:
        reading = (
            f"H~ rises along the data ({per_period}): they look driven (energy fed in from "
            f"outside, which no damping can follow), or the model misses part of the dynamics"
        )
    return (
        f"energy trend of H~ along the data: {_percent(rate)} of its spread per unit time "
        f"(z = {z:.1f}): {reading}"
    )


def _percent(rate):
    """``rate`` as a signed percentage with two significant digits (never "-0.00%")."""
    if rate == 0:
        return "0%"
    return f"{100 * rate:+.2g}%" if abs(rate) < 1e-3 else f"{rate:+.2%}"


def print_choice(result):
    """The chosen candidate, its score, and whether other candidates tie with it."""
    results, labels = result.cv_results, result.labels
    means, stds = results["mean_test_score"], results["std_test_score"]
    i, top = result.best_index, int(np.nanargmax(means))
    # The term count is the refitted model's (after any threshold); another
    # candidate's kept terms are unknown without fitting it, so none is given.
    if len(labels) == 1:
        rank = ", the only candidate"
    elif top == i:
        rank = ", the best mean score"
    else:
        rank = f"; best mean {means[top]:.4f} at {labels[top]}"
    model = result.best[-1]
    # n_terms_ counts the friction's unknowns too; the report's other lines
    # say "N kept coefficients and the friction", so this one does as well.
    n_friction = len(model.damping_) if getattr(model, "damping", False) else 0
    terms = counted(model.n_terms_ - n_friction, "term") + (" and the friction" if n_friction
                                                            else "")
    print(
        f"\nchosen: {labels[i]} -> {terms} "
        f"(score {means[i]:.4f} +- {stds[i]:.4f}{rank})"
    )
    if len(labels) == 1:
        return
    # A search that says which candidates tie (HamiltonianSearchCV: paired
    # standard errors among its finalists) is read as it is; a grid search
    # by the unpaired rule of candidate_table.
    paired = "tied" in results
    tied = results["tied"] if paired else candidate_table(results)["tied"]
    others = [k for k in np.flatnonzero(tied) if k != i]
    band = "one paired standard error" if paired else "one standard error"
    if others:
        names = "; ".join(labels[k] for k in others[:4])
        more = f" and {len(others) - 4} more" if len(others) > 4 else ""
        print(
            f"tied: {counted(len(others), 'other candidate')} within {band} of the best "
            f"({names}{more}): the cross-validation cannot tell them apart"
            + (", and the pick among them is the simplest (fewest terms, smoothest "
               "de-noising, least biased fit target)" if paired else
               ", so this pick among them is partly chance")
        )
    else:
        print(f"no tie: every other candidate scores more than {band} below")


def print_errors(t, curves, truth):
    """Each rollout's relative error against the true system; returns the error curves."""
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


def print_drift(t, model, runs):
    """The drift of the learned energy along each rollout; with friction, its loss.

    A conservative model keeps H~: any change is the integrator's drift. With
    friction H~ falls by design, so the change is reported as the energy lost
    (H~(0) - H~(T)): calling it a drift would flag the physics as a
    numerical error.
    """
    damped = bool(getattr(model, "damping", False))
    for label, (Y, ok) in runs.items():
        if ok < 2:
            print(f"  H~ {'loss' if damped else 'drift'}, {label}: the simulation failed at "
                  f"the first step")
            continue
        H = model.hamiltonian(Y[:ok])
        tail = "" if ok == t.shape[0] else f" (until it failed at t = {t[ok]:g})"
        if damped:
            print(f"  H~ lost to the friction H~(0) - H~(T), {label}: {H[0] - H[-1]:.2g} (not "
                  f"a drift: with --damping H~ falls by design){tail}")
        else:
            print(f"  H~ drift max|H~(t) - H~(0)|, {label}: {np.max(np.abs(H - H[0])):.2g}{tail}")
