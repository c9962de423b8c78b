"""The fitting command: from the options to the report, the model file and the figure."""

import os
import tempfile
import warnings

import numpy as np
from sklearn.pipeline import make_pipeline

from .._derivatives import DerivativeTransformer
from .._integrate import integrate
from .._integrate.simulation import MAX_STEPS, check_outputs
from .._memory import SizeLimitError
from .._vector_field import VectorFieldRegressor
from ..exceptions import DomainWarning
from ..inspection import format_hamiltonian
from ..io import save
from .data import check_complete, load_data, prepare_for_search, segment_if_needed
from .errors import UsageError, check_positive
from .figure import draw_report
from .outputs import OUTPUTS
from .parser import MODEL_FILE, check_options, check_resamples
from .report import describe_energy_trend, print_choice, print_drift, print_errors
from .discovery import run_discovery
from .resampling import band_or_none, resample_chosen
from .search import run_search
from .words import counted, friction_line


def run(args):
    """Fit, report, and write the model file (and the figure); returns the exit status."""
    data = load_data(args)
    check_options(args)
    if args.paper_grid or args.segment_length is not None:
        check_complete(args, data)
        data = segment_if_needed(args, data)
    else:
        data = prepare_for_search(args, data)
    check_resamples(args.resamples, len(data.X))
    horizon = args.horizon if args.horizon is not None else data.horizon
    check_positive("--horizon", horizon)
    # Before the search: a horizon beyond the simulation limits fails at once.
    n_intervals = _horizon_steps(horizon, data.step, len(data.names))
    _prepare_output(args.output)
    print(f"data: {data.title}")
    X, names = data.X, data.names
    result = (run_search if args.paper_grid else run_discovery)(args, data)
    best = result.best
    model = best[-1]
    print_choice(result)
    try:
        resample_time = resample_chosen(args, data, best)
    except SizeLimitError:
        # The regressor refused the count for the chosen model's size: say
        # it with the command's option.
        check_resamples(args.resamples, len(data.X), model._n_terms(len(names)))
        raise
    refinement = _refine_chosen(result, model, resample_time is not None, names, data.ids)
    intervals = (resample_time is not None
                 or getattr(model, "coef_covariance_", None) is not None)
    print(f"learned: {format_hamiltonian(model, state_names=names, intervals=intervals)}")
    if model.damping:
        print(friction_line(model, names))
    print(
        f"fit time: {result.fit_time:.1f} s for {result.n_fits} "
        f"cross-validation fits and the refit"
        + (f" (warnings of the candidates: {', '.join(result.warned)})" if result.warned
           else "")
    )
    print(describe_energy_trend(model))
    baseline = _fit_baseline(best, X)

    system = data.system
    x0 = np.asarray(system.initial_state if system is not None else data.states[0][0])
    t = data.step * np.arange(n_intervals + 1)
    origin = (
        "u0* = (" + ", ".join(f"{v:g}" for v in x0) + ")" if system is not None
        else "the first observation of the first trajectory"
    )
    method = model._default_method()
    print(
        f"\nsimulated from {origin} up to T = {t[-1]:g} ("
        + (f"RK4 step {data.step:g}" if method == "rk4" else
           f"SP: {method.upper()}, the map a fit on steps learns, at the data step; "
           f"non-SP: RK4 step {data.step:g}")
        + "):"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # leaving the domain is reported as a failure
        rk4, avf = _rollout(model, x0, t, "rk4"), _rollout(model, x0, t, "avf")
        curves = {"SP": rk4 if method == "rk4" else avf}
        if baseline is not None:
            curves["non-SP"] = _rollout(baseline[-1], x0, t, "rk4")
    truth, errors = None, {}
    if system is not None:
        truth = system.solve(x0, t, max_step=data.step / 10)
        errors = print_errors(t, curves, truth)
        if "non-SP" in curves and refinement is not None and refinement["status"] == "refined":
            print("  (SP: the refined coefficients; non-SP: the same candidate's least-squares "
                  "fit, component by component)")
    band = band_or_none(model, x0, t)
    with warnings.catch_warnings():
        # Where the rollouts leave the training box was said above (or shows
        # as a failure); evaluating H~ along them need not repeat it.
        warnings.simplefilter("ignore", DomainWarning)
        print_drift(t, model, {"RK4": rk4, "AVF": avf})

    # The names the report used go with the model: show and load print them.
    model.set_params(state_names=list(names))
    model_path = os.path.join(args.output, MODEL_FILE)
    with OUTPUTS.writing(model_path, atomic=True):
        save(best, model_path,
             provenance=_provenance(args, data, result, resample_time, refinement))
    print(
        f"\nmodel: {model_path} (a fitted Pipeline; sk-hamiltonian show {model_path}, or "
        f"sk_hamiltonian.load in Python)"
    )
    if args.joblib:
        import joblib

        pickle_path = os.path.join(args.output, "model.joblib")
        with OUTPUTS.writing(pickle_path):
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
    with warnings.catch_warnings(), OUTPUTS.writing(figure_path):
        warnings.simplefilter("ignore", DomainWarning)
        draw_report(
            figure_path, t, curves, truth, errors, model, rk4, avf, observed, names, data.title,
            band=band,
        )
    print(f"figure: {figure_path}")
    return 0


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


def _refine_chosen(result, model, refitted, names, ids):
    """The search's refinement of ``model``'s coefficients, said (and applied again after a refit).

    The resampling refits the chosen regressor by least squares; the
    search's refinement on the raw trajectories is then applied to it once
    more (``refitted``). Returns the refinement's outcome (None when the
    search made none). ``ids`` name the trajectories.
    """
    if result.refine is None and result.refinement is None:
        return None
    info = result.refine(model) if refitted and result.refine is not None else result.refinement
    if info["status"] != "refined":
        print(f"refined: no, {info['status']}")
        return info
    # The held-out check is the search's (a refit's refinement is not checked again).
    check = info.get("check") or (result.refinement or {}).get("check") or {}
    checked = ""
    if check.get("misfit") is not None:
        least, refined = check["misfit"]
        checked = (f"; on held-out trajectories its misfit is {refined:.4g} against "
                   f"{least:.4g} for least squares")
        # The gain with its standard error; beyond two of them either way
        # (about 5 % by chance) the held-out data tell the two fits apart.
        spread = check.get("gain_se")
        if spread is not None and np.isfinite(spread):
            gain = check["gain"]
            checked += (f" (a gain of {gain:.3g} ± {spread:.2g}"
                        + ("; the held-out data tell the two apart)" if abs(gain) > 2 * spread
                           else "; within what the held-out data can tell)"))
    print(
        f"refined: the {counted(info['n_terms'], 'kept coefficient')}"
        + (" and the friction" if model.damping else "")
        + " fitted to the raw "
        f"trajectories (output error, {counted(info['n_iter'], 'iteration')}); largest "
        f"change {100 * info['change']:.2g}%{checked}"
    )
    left = info.get("outliers") or {}
    if left:
        named = [ids[k] for k in left]
        print(f"note: the trajectory fit left out "
              f"{counted(sum(len(v) for v in left.values()), 'sample')}, each alone far beyond "
              f"its residuals (a reading moved off, at a record's end where the spike screen "
              f"cannot tell it from noise): {', '.join(named[:10])}"
              + (f" and {len(named) - 10} more" if len(named) > 10 else ""))
    if info["noise"] is not None:
        parts = [f"{name} {np.sqrt(a):.2g} + {100 * np.sqrt(b):.2g}%"
                 for name, (a, b) in zip(names, info["noise"])]
        print(f"noise (sd, additive + relative, estimated): {', '.join(parts)}")
    misfit = info.get("misfit")
    if misfit is not None and len(misfit):
        worst = int(np.argmax(misfit))
        print(f"misfit of each trajectory in units of that noise: median "
              f"{np.median(misfit):.2g}, largest {misfit[worst]:.2g} (about 1 where the model "
              f"explains a trajectory)")
    return info


def _provenance(args, data, result, resample_time=None, refinement=None):
    """What the model file records about the data, the search and the resampling."""
    lengths = [len(T) for T in data.X]
    i = result.best_index
    return {
        "data": data.title,
        "data_shape": (
            f"{counted(len(lengths), 'trajectory', 'trajectories')} x {min(lengths)}"
            + (f"-{max(lengths)}" if max(lengths) > min(lengths) else "")
            + f" samples x {len(data.names)} states"
        ),
        "state_names": list(data.names),
        "fit_time_s": round(result.fit_time, 3),
        "cv": result.summary,
        "cv_choice": result.labels[i],
        "cv_score": (
            f"{result.cv_results['mean_test_score'][i]:.4f} +- "
            f"{result.cv_results['std_test_score'][i]:.4f} over the folds"
        ),
        "damping": bool(args.damping),
        "resampling": (
            "none" if resample_time is None else
            f"{args.resamples} bootstrap resamples of whole "
            f"{'segments' if data.groups is not None else 'trajectories'} (seed {args.seed}), "
            f"{resample_time:.1f} s"
        ),
        "refinement": (
            "none" if refinement is None else
            "coefficients fitted to the raw trajectories (output error)"
            if refinement["status"] == "refined" else refinement["status"]
        ),
    }


def _fit_baseline(best, X):
    """The component-wise (non-SP) baseline of the chosen model, or None if it cannot fit.

    The same derivative layout, model space, degree, threshold and fit target,
    one vector-field component at a time (with a threshold: SINDy's
    sequential thresholding in this library); for the paper's grid, the
    paper's dense baseline.
    """
    chosen = best[-1]
    baseline = make_pipeline(
        DerivativeTransformer(**best[0].get_params()),
        VectorFieldRegressor(
            degree=chosen.degree, domain=chosen.domain, periodic=chosen.periodic,
            mixed=chosen.mixed, momentum_degree=chosen.momentum_degree,
            separable=chosen.separable, threshold=chosen.threshold, fit_on=chosen.fit_on,
        ),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return baseline.fit(X)
        except ValueError as error:  # e.g. more unknowns than data at this degree
            print(f"note: non-SP baseline not fitted: {error}")
            return None


def _horizon_steps(horizon, step, n_states):
    """Sampling intervals up to ``horizon``, refused (one line) beyond the simulation limits.

    The reference solution of a known system takes ten steps per interval.
    """
    intervals = horizon / step
    if not (np.isfinite(intervals) and 10 * intervals <= MAX_STEPS):
        raise UsageError(
            f"--horizon {horizon:g} is {intervals:.3g} sampling intervals of {step:g} (and ten "
            f"times as many steps for the reference solution), beyond the limit of "
            f"{MAX_STEPS // 10:.0e} intervals; give a shorter --horizon"
        )
    try:
        check_outputs(intervals + 1, 1, n_states, what=f"--horizon {horizon:g}")
    except ValueError as error:
        raise UsageError(str(error)) from None
    return max(0, int(round(intervals)))


def _rollout(model, x0, t, method):
    """Simulate, keeping what precedes a failure; return (states, n_valid_times).

    The model wraps an angle into its period; the report draws and compares
    the rollout in the chart of ``x0``, the data's (a pendulum about
    ``q = pi`` would otherwise jump between ``pi`` and ``-pi``).
    """
    Y, failed_at = integrate(model._integrator(method), x0[None], t, None)
    return model._space.unwrap(Y[:, 0], x0), int(failed_at[0])
