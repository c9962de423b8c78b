"""The ``show`` and ``simulate`` sub-commands of ``sk-hamiltonian``: reuse a saved model."""

import argparse
import csv
import os
import warnings

import numpy as np

from .._integrate.simulation import FAST_EXTRA, check_outputs
from .._io_text import escaping_output, printable
from .._state_order import swap_halves
from ..exceptions import DomainWarning, SimulationError
from ..io import ModelFileError, load, read_manifest
from .datafiles import default_state_names
from .errors import UsageError, check_positive
from .outputs import OUTPUTS
from .words import friction_line

METHODS = ("rk4", "avf", "leapfrog", "yoshida4")
# Output samples of a simulation when neither --dt nor a training step is known.
DEFAULT_SAMPLES = 200

SHOW_DESCRIPTION = """\
Print what a model file holds: its classes and parameters, the learned H~
(leading terms), the domain, the fitted attributes, and where the model came
from (provenance: data, fit time, cross-validation choice). The file is
checked as by sk_hamiltonian.load; nothing in it is executed."""

SIMULATE_DESCRIPTION = """\
Integrate a saved model from one or several initial states and write the
trajectories as CSV ('trajectory,t,<state names>', the layout the fitting
command reads), plus a figure beside it when matplotlib is installed.
Initial states outside the model's domain are refused unless --allow-outside
is given: the model is not trusted there."""

SIMULATE_EPILOG = """\
examples:
  sk-hamiltonian simulate sk_hamiltonian_output/model.skh --x0 0.5 1.0 --t-end 20 -o run.csv
  sk-hamiltonian simulate model.skh --x0 0 1 --x0 0 2 --t-end 5 --dt 0.01 --method avf -o runs.csv
"""


def show_parser():
    parser = argparse.ArgumentParser(
        prog="sk-hamiltonian show", description=SHOW_DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "model", metavar="MODEL",
        help="a model file (.skh) written by the command or by sk_hamiltonian.save",
    )
    return parser


def simulate_parser():
    parser = argparse.ArgumentParser(
        prog="sk-hamiltonian simulate", description=SIMULATE_DESCRIPTION,
        epilog=SIMULATE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("model", metavar="MODEL", help="a model file (.skh)")
    parser.add_argument(
        "--x0", type=float, nargs="+", action="append", required=True, metavar="X",
        help="initial state, one value per state variable in the model's order (p_1..p_d, "
        "q_1..q_d); repeat --x0 for several trajectories",
    )
    parser.add_argument("--t-end", type=float, required=True, metavar="T",
                        help="simulate from t = 0 to T")
    parser.add_argument(
        "--dt", type=float, metavar="DT",
        help="output sampling step (default: the model's training step, else T / "
        f"{DEFAULT_SAMPLES})",
    )
    parser.add_argument(
        "--method", choices=METHODS,
        help="integrator (default: the model's own, RK4, or AVF for a model fitted on steps); "
        "'avf' conserves the learned H~ exactly (it is implicit: without numba, "
        "pip install \"sk_hamiltonian[fast]\", each step costs several RK4 steps); 'leapfrog' "
        "and 'yoshida4' need a separable model",
    )
    parser.add_argument(
        "--max-step", type=float, metavar="H",
        help="largest integration step (default: chosen from the model's time scale)",
    )
    parser.add_argument("-o", "--output", required=True, metavar="CSV",
                        help="where to write the trajectories (.csv)")
    parser.add_argument(
        "--figure", metavar="PNG",
        help="where to write the figure (default: the CSV's name with .png; needs matplotlib)",
    )
    parser.add_argument(
        "--allow-outside", action="store_true",
        help="simulate initial states outside the model's domain (the model is not trusted "
        "there)",
    )
    return parser


def _load(path):
    if os.path.isdir(path):
        raise UsageError(f"{path} is a directory; give the model file, e.g. {path}/model.skh")
    try:
        return load(path), read_manifest(path)
    except ModelFileError as error:
        raise UsageError(str(error)) from None


def _regressor(model):
    return model[-1] if hasattr(model, "steps") else model


def _columns_box(regressor):
    """``domain_`` and ``periodic_`` in the order of the model's columns.

    The fitted attributes are in the model's ``(p, q)`` order; a model
    fitted with ``state_order="qp"`` reads and names its columns ``(q, p)``.
    """
    domain, periodic = regressor.domain_, regressor.periodic_
    if getattr(regressor, "_swapped", lambda: False)():
        domain, periodic = swap_halves(domain, axis=0), swap_halves(periodic)
    return domain, periodic


def _names(regressor):
    names = getattr(regressor, "state_names", None)
    if names is None:
        names = getattr(regressor, "feature_names_in_", None)
    if names is not None:
        return [str(name) for name in names]
    n = regressor.n_features_in_
    # Odd dimensions: a VectorFieldRegressor of a system without (p, q) pairs.
    return default_state_names(n) if n % 2 == 0 else [f"x{i + 1}" for i in range(n)]


def _field(value):
    """A value from the model file on one line: every control character escaped, newlines too."""
    return printable(str(value), keep_newline=False)


def _non_default_params(estimator):
    defaults = type(estimator)().get_params(deep=False)
    shown = []
    for key, value in estimator.get_params(deep=False).items():
        default = defaults.get(key)
        same = (value is default) or (
            not isinstance(value, (list, tuple, np.ndarray)) and value == default
        )
        if not same:
            text = np.asarray(value).tolist() if hasattr(value, "shape") else repr(value)
            shown.append(f"{key}={text}")
    return f"{type(estimator).__name__}({', '.join(shown)})"


@escaping_output  # the file's strings are data: no terminal escapes
def show(argv):
    """``sk-hamiltonian show MODEL``: print the model file's contents."""
    args = show_parser().parse_args(argv)
    model, manifest = _load(args.model)
    written = manifest.get("written", {})
    print(f"model file: {_field(args.model)}")
    print(
        f"  format {_field(manifest['format_version'])}, written by sk_hamiltonian "
        f"{_field(manifest['package_version'])}"
        + (f" on {_field(written['time'])}" if isinstance(written.get("time"), str) else "")
        + "".join(f", {key} {_field(written[key])}" for key in ("scikit-learn", "numpy")
                  if isinstance(written.get(key), str))
    )
    steps = model.steps if hasattr(model, "steps") else [(None, model)]
    print("estimator: " + _field(" -> ".join(_non_default_params(step) for _, step in steps)))
    provenance = manifest.get("provenance") or {}
    if provenance:
        print("provenance:")
        for key, value in provenance.items():
            print(f"  {_field(key)}: {_field(value)}")
    regressor = _regressor(model)
    if not hasattr(regressor, "n_features_in_"):
        print("fitted: no (the file holds an unfitted estimator)")
        return 0
    if not hasattr(regressor, "coef_"):  # a DerivativeTransformer alone
        print(f"fitted: {regressor.n_features_in_} state variables, window_ = "
              f"{regressor.window_}")
        return 0
    names = [_field(name) for name in _names(regressor)]
    if hasattr(regressor, "hamiltonian"):
        from ..inspection import format_hamiltonian, hamiltonian_terms

        resampled = getattr(regressor, "resampled_coef_", None) is not None
        covariance = getattr(regressor, "coef_covariance_", None) is not None
        print(f"learned: {format_hamiltonian(regressor, state_names=names, intervals=resampled or covariance)}")
        friction = friction_line(regressor, names)
        if friction is not None:
            print(friction)
        if covariance:
            print("  (the intervals: the trajectory fit's own, from its covariance "
                  "stored in the file" + (f"; the inclusion counts: "
                                          f"{regressor.resampled_coef_.shape[0]} least-squares "
                                          f"refits on resamples)" if resampled else ")"))
        elif resampled:
            print(f"  (the intervals: {regressor.resampled_coef_.shape[0]} refits on "
                  f"{regressor.resample} resamples of whole trajectories, stored in the file)")
        terms = hamiltonian_terms(regressor, state_names=names)
        print(f"terms ({len(terms)} in the monomial view, {regressor.powers_.shape[0]} basis "
              f"functions; largest first):")
        for term in terms[:12]:
            print(f"  {term.coefficient:+.6g} {term.text}")
        if len(terms) > 12:
            print(f"  ... {len(terms) - 12} more")
    else:
        outputs = 1 if regressor.coef_.ndim == 1 else regressor.coef_.shape[1]
        print(f"learned: a vector field, {outputs} component(s) of "
              f"{regressor.powers_.shape[0]} basis functions each (no Hamiltonian)")
    print("domain:")
    for name, (low, high), periodic in zip(names, *_columns_box(regressor)):
        kind = "period" if periodic else "interval"
        print(f"  {name}: [{low:.6g}, {high:.6g}{')' if periodic else ']'} ({kind})")
    print("fitted attributes:")
    for key in sorted(vars(regressor)):
        if not key.endswith("_") or key.startswith("_") or key in ("coef_", "powers_",
                                                                   "domain_", "periodic_"):
            continue
        value = getattr(regressor, key)
        if isinstance(value, np.ndarray):
            value = np.array2string(value, precision=6, threshold=20) if value.dtype != object \
                else list(value)
        elif isinstance(value, float):
            value = f"{value:.6g}"
        elif isinstance(value, str):
            value = _field(value)
        # Numeric arrays keep their rows' line breaks: numbers carry no
        # control characters, and arrays of strings print their repr.
        print(f"  {key} = {value}")
    print(f"  coef_: shape {regressor.coef_.shape}, powers_: shape {regressor.powers_.shape}")
    return 0


def simulate(argv):
    """``sk-hamiltonian simulate MODEL ...``: integrate a saved model, write CSV (+ figure)."""
    args = simulate_parser().parse_args(argv)
    for option, value in (("--t-end", args.t_end), ("--dt", args.dt),
                          ("--max-step", args.max_step)):
        check_positive(option, value)
    model, _ = _load(args.model)
    regressor = _regressor(model)
    if not hasattr(regressor, "coef_"):
        raise UsageError(
            f"{args.model} holds no fitted regressor (an unfitted estimator or a "
            f"DerivativeTransformer alone): nothing to simulate"
        )
    names = _names(regressor)
    n = regressor.n_features_in_
    x0 = np.array(args.x0, dtype=float) if all(len(x) == n for x in args.x0) else None
    if x0 is None:
        bad = next(x for x in args.x0 if len(x) != n)
        raise UsageError(
            f"--x0 needs {n} values ({', '.join(names)}), one per state variable; got {len(bad)}"
        )
    if not np.isfinite(x0).all():
        raise UsageError("--x0 values must be finite numbers")
    domain, periodic = _columns_box(regressor)
    outside = ((x0 < domain[:, 0]) | (x0 > domain[:, 1])) & ~periodic
    if outside.any() and not args.allow_outside:
        k, i = np.argwhere(outside)[0]
        box = ", ".join(
            f"{name} in [{low:.6g}, {high:.6g}]"
            for name, (low, high), p in zip(names, domain, periodic) if not p
        )
        raise UsageError(
            f"--x0 {' '.join(f'{v:g}' for v in x0[k])}: {names[i]} = {x0[k, i]:g} lies outside "
            f"the model's domain ({box}), where it is not trusted; choose a state inside it, or "
            f"pass --allow-outside to simulate anyway"
        )
    dt = args.dt
    if dt is None:
        dt = regressor.dt_ if np.isfinite(regressor.dt_) else args.t_end / DEFAULT_SAMPLES
    # Refused before the output times are built: --t-end 1e9 would ask numpy for 745 GiB.
    intervals = max(1.0, round(args.t_end / dt)) if np.isfinite(args.t_end / dt) else np.inf
    try:
        check_outputs(intervals + 1, len(x0), n,
                      what=f"--t-end {args.t_end:g} at output step {dt:g} (--dt)")
    except ValueError as error:
        raise UsageError(f"cannot simulate: {error}") from None
    t = dt * np.arange(int(intervals) + 1)
    figure = args.figure or os.path.splitext(args.output)[0] + ".png"
    for path in (args.output, figure):
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            raise UsageError(f"cannot write {path}: the directory {folder} does not exist")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DomainWarning)
        # Every time, not once per process: the slow-AVF note below reads it.
        warnings.simplefilter("always", UserWarning)
        try:
            Y = regressor.simulate(x0, t, method=args.method, max_step=args.max_step,
                                   on_failure="nan")
        except (ValueError, SimulationError) as error:
            raise UsageError(f"cannot simulate: {error}") from None
    with OUTPUTS.writing(args.output):
        _write_csv(args.output, t, Y, names)
    method = args.method or regressor._default_method()
    print(f"simulated {len(x0)} trajector{'y' if len(x0) == 1 else 'ies'} up to T = {t[-1]:g} "
          f"(output step {dt:g}, method {method}): {args.output}")
    failed = ~np.isfinite(Y).all(axis=2)
    for k in np.flatnonzero(failed.any(axis=1)):
        print(f"note: trajectory {k} failed at t = {t[np.argmax(failed[k])]:g} (written as NaN "
              f"from there on)")
    if any(issubclass(w.category, DomainWarning) for w in caught):
        print("note: the simulated states leave the model's domain, where it is not trusted")
    # The warning of a long AVF run without numba, caught above with the rest.
    for w in caught:
        if FAST_EXTRA in str(w.message):
            print(f"note: {w.message}")
    if hasattr(regressor, "hamiltonian"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DomainWarning)
            for k, trajectory in enumerate(Y):
                ok = trajectory[np.isfinite(trajectory).all(axis=1)]
                H = regressor.hamiltonian(ok)
                print(f"  trajectory {k}: H~ drift max|H~(t) - H~(0)| = "
                      f"{np.max(np.abs(H - H[0])):.2g}")
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("figure: skipped, matplotlib is not installed (pip install matplotlib)")
        return 0
    with OUTPUTS.writing(figure):
        _draw(figure, t, Y, names, regressor)
    print(f"figure: {figure}")
    return 0


def _write_csv(path, t, Y, names):
    try:
        with open(path, "w", newline="", encoding="utf-8") as stream:
            writer = csv.writer(stream)
            writer.writerow(["trajectory", "t", *names])
            for k, trajectory in enumerate(Y):
                for time, state in zip(t, trajectory):
                    writer.writerow([k, repr(float(time)), *(repr(float(v)) for v in state)])
    except OSError as error:
        raise UsageError(f"cannot write {path}: {error.strerror or error}") from None


def _draw(path, t, Y, names, regressor):
    from matplotlib.figure import Figure

    from ..plotting import plot_phase, plot_trajectories

    fig = Figure(figsize=(11, 4), layout="constrained")
    left, right = fig.subplots(1, 2)
    curves = {f"trajectory {k}": trajectory for k, trajectory in enumerate(Y)}
    plot_trajectories(t, curves, state_names=names, ax=left)
    left.set_title("simulated trajectories")
    if regressor.n_features_in_ % 2 == 0:
        plot_phase(curves, state_names=names, ax=right)
        right.set_title("phase plot (first degree of freedom)")
    else:
        right.set_visible(False)
    fig.savefig(path, dpi=110)
