"""What a fitted estimator in a model file may hold: one table of known values.

Each estimator class has a table (:data:`MODELS`) of the fitted values it
may carry, each with its type, its canonical dtype and shape (in the
dimensions ``n`` state variables, ``d = n / 2`` degrees of freedom, ``b``
basis functions, ``o`` outputs), and a test of its values. Loading follows
the table in three steps, so that nothing large is read before its size is
known to fit the model:

1. the scalars, and the declared shapes and dtypes of the arrays, against
   the table (sizes of the members too, before any is read);
2. the arrays themselves (converted to the canonical dtype where an older
   file used another one that converts exactly), and their values;
3. the values against each other and the parameters (``powers_`` is the
   index set of the parameters; see :mod:`._io_powers`), and, once the model
   is built, its time scales against its dynamics (:func:`check_dynamics`).

A new fitted attribute is one more row of a table.
"""

import math
import re
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ._io_powers import index_set_problem
from ._space.builder import check_couplings
from ._state_order import swap_couplings
from ._io_values import decode, is_reference, reference
from ._io_zip import ModelFileError

#: Parameter and step names: lower case, never starting with ``_`` (no dunders).
ATTRIBUTE_NAME = re.compile(r"\A[a-z][a-z0-9_]{0,63}\Z")


@dataclass(frozen=True)
class Scalar:
    """A fitted scalar: Python type(s) and a test of the value."""

    types: tuple
    test: Callable
    text: str


@dataclass(frozen=True)
class Array:
    """A fitted array: canonical dtype, allowed shapes, a test of the values.

    ``shapes`` holds patterns of dimension names and integers; ``like``
    names another array whose declared shape this one must have. ``casts``
    lists further dtype kinds older files used that convert exactly.
    """

    dtype: str
    shapes: tuple = ()
    test: Callable = None
    text: str = ""
    like: str = None
    casts: str = ""


@dataclass(frozen=True)
class Names:
    """One string per state variable (``feature_names_in_``)."""

    text: str = "one string per state variable"


@dataclass(frozen=True)
class Model:
    """The fitted values an estimator class may hold, those it cannot lack, its state dimension.

    ``pairs``: the states are pairs (p_1..p_d, q_1..q_d), so their number is even.
    """

    fields: dict
    required: tuple
    private: dict
    pairs: bool = False


def _nonnegative_int(v):
    return v >= 0


def _any_float(v):
    return True


def _finite(a):
    return bool(np.isfinite(a).all())


def _finite_nonnegative(a):
    return _finite(a) and bool((a >= 0).all())


def _finite_positive(a):
    return _finite(a) and bool((a > 0).all())


INT, FLOAT = (int, np.integer), (float, np.floating)
SOLVERS = ("lstsq", "normal", "iterative", "sketch")
STATE = Array("float64", (("n",),), _finite_positive, "a finite 1-D array of positive floats")
REGRESSOR = {
    "n_features_in_": Scalar(INT, lambda v: v >= 1, "a positive integer"),
    "feature_names_in_": Names(),
    "powers_": Array("int64", (("b", "n"),), None, "a 2-D integer array"),
    "periodic_": Array("bool", (("n",),), None, "a 1-D boolean array"),
    # Absent from files of models fitted before mixed variables existed.
    "mixed_": Array("bool", (("n",),), None, "a 1-D boolean array"),
    "domain_": Array("float64", (("n", 2),), _finite, "a finite 2-D float array", casts="iu"),
    "coef_": Array("float64", (("b",), ("b", "o")), _finite, "a finite float array"),
    "support_": Array("bool", like="coef_", text="a boolean array"),
    # The refits of n_resamples > 0: one row per refit.
    "resampled_coef_": Array("float64", (("r", "b"), ("r", "b", "o")), _finite,
                             "a finite float array of one row per resample"),
    "state_scale_": STATE,
    "cond_": Scalar(FLOAT, _any_float, "a float"),
    "rank_": Scalar(INT, _nonnegative_int, "a non-negative integer"),
    "n_terms_": Scalar(INT, _nonnegative_int, "a non-negative integer"),
    "n_iter_": Scalar(INT, _nonnegative_int, "a non-negative integer"),
    "solver_": Scalar((str,), lambda v: v in SOLVERS, f"one of {', '.join(map(repr, SOLVERS))}"),
    # NaN: fitted without time stamps; checked against the dynamics by check_dynamics.
    "dt_": Scalar(FLOAT, lambda v: math.isnan(v) or 0 < v < math.inf,
                  "a positive finite float, or NaN"),
    "time_scale_": Scalar(FLOAT, lambda v: math.isnan(v) or v > 0,
                          "a positive float (NaN for a model that is no vector field)"),
}
HAMILTONIAN = {
    **REGRESSOR,
    "coef_": Array("float64", (("b",),), _finite, "a finite 1-D float array"),
    "resampled_damping_": Array("float64", (("r", "d"),), _finite_nonnegative,
                                "a finite 2-D array of non-negative floats, a row per resample"),
    "damping_": Array("float64", (("d",),), _finite_nonnegative,
                      "a finite 1-D array of non-negative floats"),
    "energy_trend_": Scalar(FLOAT, _any_float, "a float"),
    "energy_trend_z_": Scalar(FLOAT, _any_float, "a float"),
    # The fit on trajectories (fit_on="trajectories"): its outcome, and when
    # accepted the noise model, each trajectory's misfit and the covariance
    # of coef_ (then damping_, for a damped model).
    "trajectory_fit_status_": Scalar(
        (str,), lambda v: v == "refined" or (v.startswith("kept: ") and len(v) < 2000),
        "'refined' or 'kept: ' and a reason"),
    "noise_": Array("float64", (("n", 2),), _finite_nonnegative,
                    "a finite (n_states, 2) array of non-negative floats"),
    "trajectory_misfit_": Array("float64", (("t",),), _finite_nonnegative,
                                "a finite 1-D array of non-negative floats"),
    "coef_covariance_": Array("float64", (("b", "b"), ("bd", "bd")), _finite,
                              "a finite square float array over coef_ (then damping_)"),
}
#: Private fitted state saved explicitly (the rest is rebuilt from the public).
PRIVATE = {
    "_state_magnitude": Array("float64", (("n",),), _finite_nonnegative,
                              "a finite 1-D array of non-negative floats"),
}
REQUIRED = ("n_features_in_", "coef_", "powers_", "periodic_", "domain_", "dt_",
            "time_scale_", "state_scale_", "_state_magnitude")
MODELS = {
    "HamiltonianRegressor": Model(HAMILTONIAN, REQUIRED + ("damping_",), PRIVATE, pairs=True),
    "VectorFieldRegressor": Model(REGRESSOR, REQUIRED, PRIVATE),
    "DerivativeTransformer": Model(
        {"n_features_in_": REGRESSOR["n_features_in_"],
         "window_": Scalar(INT, lambda v: v >= 2, "an integer of at least 2")},
        ("n_features_in_", "window_"), {}, pairs=True,
    ),
}
PRIVATE_STATE = tuple(PRIVATE)

# Sane time scales, as products with the fastest rate of the learned
# dynamics at the probe points (the largest |eigenvalue| of the field's
# Jacobian there): the fit's time_scale_ is 1 / (a percentile of that rate
# over the training states), and dt_ the training step. Fitted models lie
# within [0.86, 2.2e3] and [3e-3, 1.6e3] (80 fits: five benchmark systems,
# both regressors, degrees 3-8, noise 0 and 5 %, steps 0.001-0.5,
# thresholds, fits on steps); far outside these ranges a value is no
# fitted one, and simulate's default step would be no sensible fraction of
# the dynamics.
TIME_SCALE_RANGE = (1e-4, 1e12)
DT_RANGE = (1e-9, 1e9)
# A model learned from nearly static data (a momentum held constant, say) has
# a fastest rate near zero (3.5e-8 for such a fit of the command's tests) and
# a legitimate training step, so dt_ * rate falls below any fixed bound: the
# lower end of DT_RANGE holds only for dynamics faster than this rate.
STATIC_RATE = 1e-6
# Points of the domain at which the dynamics are probed (the centre and a
# low-discrepancy sample), and the relative step of the forward differences
# that give the Jacobian there (relative errors of about 1e-6: the ranges
# above span orders of magnitude).
N_PROBES = 8
DIFFERENCE_STEP = 1e-6


def fitted_values(container, est, fitted, private, what):
    """The fitted attributes of ``est`` (parameters set) from its manifest entries, all checked.

    Parameters
    ----------
    container : Container
        The open model file.
    est : estimator
        The estimator, its parameters set and validated.
    fitted, private : dict
        The manifest's ``fitted`` and ``private`` entries (parsed JSON).
    what : str
        How messages name the estimator.

    Returns
    -------
    attributes : dict
        Name -> value, with canonical types and dtypes.
    """
    name = type(est).__name__
    model = MODELS[name]
    where = container.where

    def fail(problem):
        raise ModelFileError(f"{where}: {what}: {problem}")

    entries = _entries(model, name, fitted, private, fail)
    # 1. Scalars, the dimensions they and the declared shapes give, the
    #    declared arrays (and their members' sizes) against the table.
    values = {key: _scalar(field, value, where, f"{what}: fitted attribute {key}")
              for key, (field, value) in entries.items() if isinstance(field, Scalar)}
    declared = {key: reference(value, where, f"{what}: {key}")
                for key, (field, value) in entries.items() if isinstance(field, Array)}
    dims = _dimensions(model, name, values, declared, fail)
    for key, (member, shape, dtype, _) in declared.items():
        _check_declaration(entries[key][0], key, shape, dtype, dims, declared, fail)
        container.expect(member, shape, dtype, f"{what}: {key}")
    if "b" in dims and getattr(est, "degree", 0) > dims["b"]:
        # Every index set holds each degree 1..degree of some variable.
        fail(f"degree={est.degree} needs at least {est.degree} basis functions, but powers_ "
             f"declares {dims['b']}; the file is corrupted.")
    # 2. The arrays and their values.
    for key, (member, shape, dtype, _) in declared.items():
        field = entries[key][0]
        array = container.read_array(member, shape, dtype, f"{what}: {key}")
        array = _canonical(array, field, where, f"{what}: fitted attribute {key}")
        if field.test is not None and not field.test(array):
            fail(f"fitted attribute {key} must be {field.text}; the file is corrupted.")
        values[key] = array
    for key, (field, value) in entries.items():
        if isinstance(field, Names):
            values[key] = _names(value, dims["n"], where, f"{what}: {key}")
    return values


def _entries(model, name, fitted, private, fail):
    """Name -> (field of the table, manifest entry); only known names, none required missing."""
    entries = {}
    for source, table, kind in ((fitted, model.fields, "fitted attribute"),
                                (private, model.private, "private state")):
        if not isinstance(source, dict):
            fail(f"its {kind} entries are not a JSON object.")
        for key, value in source.items():
            if key not in table:
                known = ", ".join(sorted(table)) or "none"
                fail(
                    f"{kind} {str(key)[:40]!r} is not one a {name} has (known: {known}); "
                    f"the file is refused."
                )
            entries[key] = (table[key], value)
    missing = [key for key in model.required if key not in entries]
    if missing:
        fail(f"the fitted {name} lacks {', '.join(missing)}; the file is incomplete. Save the "
             f"model again with sk_hamiltonian.save.")
    return entries


def _dimensions(model, name, values, declared, fail):
    """``n``, ``d``, and ``b`` and ``o`` as ``powers_`` and ``coef_`` declare them."""
    dims = {"n": int(values["n_features_in_"])}
    if dims["n"] % 2 == 0:
        dims["d"] = dims["n"] // 2
    elif model.pairs:
        fail(f"n_features_in_={dims['n']} is odd, but a {name}'s states are pairs "
             f"(p_1..p_d, q_1..q_d); the file is corrupted.")
    if "powers_" in declared:
        dims["b"] = _first(declared["powers_"][1])
        dims["bd"] = dims["b"] + dims.get("d", 0)
    if "trajectory_misfit_" in declared:
        dims["t"] = _first(declared["trajectory_misfit_"][1])
    if "coef_" in declared and len(declared["coef_"][1]) == 2:
        dims["o"] = declared["coef_"][1][1]
    if "resampled_coef_" in declared:
        dims["r"] = _first(declared["resampled_coef_"][1])
    return dims


def _first(shape):
    return shape[0] if shape else -1


def _scalar(field, value, where, what):
    if is_reference(value):
        raise ModelFileError(f"{where}: {what} must be {field.text}, not an array.")
    value = decode(value, where, what, _no_arrays(where, what))
    if isinstance(value, bool) or not isinstance(value, field.types):
        raise ModelFileError(
            f"{where}: {what} must be {field.text}; got {_describe(value)}. The file is corrupted."
        )
    if not field.test(value):
        raise ModelFileError(
            f"{where}: {what} must be {field.text}; got {repr(value)[:40]}. The file is corrupted."
        )
    return value


def _no_arrays(where, what):
    def read_array(member, shape, dtype, _):
        raise ModelFileError(f"{where}: {what} refers to an array, where it holds none.")

    return read_array


def _names(value, n, where, what):
    names = decode(value, where, what, _no_arrays(where, what))
    if not (
        isinstance(names, np.ndarray) and names.dtype == object and names.shape == (n,)
        and all(isinstance(v, str) for v in names)
    ):
        raise ModelFileError(f"{where}: {what} must hold {n} strings; the file is corrupted.")
    return names


def _check_declaration(field, key, shape, dtype, dims, declared, fail):
    canonical = np.dtype(field.dtype)
    if not (dtype.kind == canonical.kind and dtype.itemsize <= canonical.itemsize
            or dtype.kind in field.casts):
        fail(
            f"fitted attribute {key} must be {field.text} of dtype {canonical}; the file "
            f"declares dtype {dtype}, and is refused."
        )
    if field.like is not None:
        expected = [declared[field.like][1]] if field.like in declared else []
    else:
        expected = [tuple(dims.get(d, -1) if isinstance(d, str) else d for d in pattern)
                    for pattern in field.shapes]
    if tuple(shape) not in expected:
        shown = " or ".join(str(tuple(e)) for e in expected) or "none"
        fail(f"fitted attribute {key} declares shape {tuple(shape)}, expected {shown}; the "
             f"file is corrupted.")


def _canonical(array, field, where, what):
    """``array`` in the canonical dtype of ``field``, if it converts exactly."""
    canonical = np.dtype(field.dtype)
    if array.dtype == canonical:
        return array
    converted = array.astype(canonical)
    if array.dtype.kind in "iu" and canonical.kind == "f" and not np.array_equal(
        converted.astype(array.dtype), array
    ):
        raise ModelFileError(f"{where}: {what} does not convert exactly to {canonical}.")
    return converted


def _describe(value):
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    return f"{type(value).__name__} {repr(value)[:40]}"


def check_regressor(where, est, attributes, what):
    """The fitted values of a regressor against each other and its parameters."""
    name = type(est).__name__

    def need(condition, problem):
        if not condition:
            raise ModelFileError(f"{where}: {what}: {problem}; the file is corrupted.")

    n = attributes["n_features_in_"]
    powers, coef, domain = attributes["powers_"], attributes["coef_"], attributes["domain_"]
    periodic = attributes["periodic_"]
    need(bool(np.all(domain[:, 1] > domain[:, 0])), "domain_ has a row with low >= high")
    # The per-state parameters are in the columns' order, the fitted
    # attributes in the model's (p, q) order: state_order="qp" exchanges them
    # (the estimator's own _state_parameter, as its fit reads them).
    given = (np.zeros(n, dtype=bool) if est.periodic is None
             else np.asarray(est._state_parameter("periodic")).astype(bool))
    need(given.shape == periodic.shape and np.array_equal(given, periodic),
         "periodic_ differs from the periodic parameter")
    mixed = attributes.get("mixed_", np.zeros(n, dtype=bool))
    given = (np.zeros(n, dtype=bool) if getattr(est, "mixed", None) is None
             else np.asarray(est._state_parameter("mixed")).astype(bool))
    need(given.shape == mixed.shape and np.array_equal(given, mixed),
         "mixed_ differs from the mixed parameter")
    need(not np.any(mixed & periodic), "a variable is both periodic_ and mixed_")
    if est.domain is not None:
        given = np.asarray(est._state_parameter("domain"), dtype=float)
        need(given.shape == domain.shape and np.array_equal(given, domain),
             "domain_ differs from the domain parameter")
    if name == "HamiltonianRegressor":
        need(est.damping or not attributes["damping_"].any(),
             "damping_ is non-zero with damping=False")
        need("resampled_damping_" not in attributes or est.damping,
             "resampled_damping_ is present without damping=True")
        need(("resampled_damping_" in attributes) == (est.damping and "resampled_coef_" in attributes),
             "resampled_damping_ and resampled_coef_ must come together with damping=True")
    if (est.momentum_degree is not None or est.separable) and n % 2:
        need(False, f"momentum_degree and separable need an even n_features_in_, not {n}")
    try:
        couplings = check_couplings(
            swap_couplings(est.couplings, n) if est._swapped() else est.couplings, n)
    except ValueError as error:
        need(False, str(error))
    problem = index_set_problem(
        powers, est.degree, periodic, momentum_degree=est.momentum_degree,
        separable=est.separable, max_interaction=est.max_interaction, couplings=couplings,
        include_constant=est._include_constant, mixed=mixed,
    )
    need(problem is None, f"{problem} (the index set of its parameters)")
    unknowns = coef.size + (n // 2 if name == "HamiltonianRegressor" else 0)
    for key in ("n_terms_", "rank_"):
        if key in attributes:
            need(attributes[key] <= unknowns,
                 f"{key}={attributes[key]} exceeds the {unknowns} unknowns of the model")


def check_transformer(where, est, attributes, what):
    """A DerivativeTransformer's fitted values against its parameters."""
    try:
        window = est._resolve_window()
    except ValueError as error:
        raise ModelFileError(f"{where}: {what}: {error}") from None
    if attributes["window_"] != window:
        raise ModelFileError(
            f"{where}: {what}: window_={attributes['window_']} disagrees with "
            f"its parameters (window={est.window!r}, degree={est.degree}: {window}); the file "
            f"is corrupted."
        )


def probe_points(domain):
    """``N_PROBES`` points of the box ``domain``: its centre and a Kronecker sequence."""
    n = domain.shape[0]
    # Fractional parts of square roots of primes: independent irrational steps.
    primes, candidate = [], 2
    while len(primes) < n:
        if all(candidate % p for p in primes):
            primes.append(candidate)
        candidate += 1
    steps = np.sqrt(np.array(primes, dtype=float)) % 1.0
    k = np.arange(N_PROBES - 1)[:, None] + 1
    unit = np.vstack([np.full((1, n), 0.5), (k * steps) % 1.0])
    return domain[:, 0] + unit * (domain[:, 1] - domain[:, 0])


def check_dynamics(where, est, what):
    """The model's field finite on its domain, its time scales sane against its fastest rate."""
    rate = _fastest_rate(est, where, what)
    time_scale, dt = est.time_scale_, est.dt_
    if rate is None:
        # No square Jacobian (a fit to other outputs): no time scale, no simulation.
        if not math.isnan(time_scale):
            raise ModelFileError(
                f"{where}: {what}: time_scale_={time_scale:g} for a model that is no vector "
                f"field (its fit gives NaN); the file is corrupted."
            )
        return
    if math.isnan(time_scale):
        raise ModelFileError(f"{where}: {what}: time_scale_ is NaN; the file is corrupted.")
    if time_scale == math.inf:
        # The fit's time scale is infinite only where the Jacobian's
        # eigenvalues vanish exactly (a field without any rate, e.g. H(p)).
        with np.errstate(all="ignore"):
            exact = max(float(np.abs(np.linalg.eigvals(est._jacobian(x[None]))).max())
                        for x in probe_points(est.domain_))
        if exact == 0:
            return
    dt_range = DT_RANGE if rate >= STATIC_RATE else (0.0, DT_RANGE[1])
    for key, value, (low, high) in (("time_scale_", time_scale, TIME_SCALE_RANGE),
                                    ("dt_", dt, dt_range)):
        if math.isnan(value) or rate == 0:
            continue
        product = value * rate
        if not low <= product <= high:
            raise ModelFileError(
                f"{where}: {what}: {key}={value:g} does not fit the learned dynamics, whose "
                f"fastest rate in the domain is {rate:.3g} ({key} times it is {product:.3g}, "
                f"outside [{low:g}, {high:g}]); the file is corrupted."
            )


def _fastest_rate(est, where, what):
    """Largest |eigenvalue| of the field's Jacobian at the probe points (None: no Jacobian).

    By forward differences of the field, one state at a time: the memory
    and the tables of a prediction of one state, which any use of the model
    builds anyway (and for one state the evaluation is the fastest).
    """
    if hasattr(est, "_is_vector_field") and not est._is_vector_field():
        return None
    n = est.n_features_in_
    steps = DIFFERENCE_STEP * (est.domain_[:, 1] - est.domain_[:, 0])
    rate = 0.0
    for x in probe_points(est.domain_):
        with np.errstate(all="ignore"):
            values = [est._vector_field(x[None])[0]]
            for i in range(n):
                moved = x.copy()
                moved[i] += steps[i]
                values.append(est._vector_field(moved[None])[0])
            values = np.array(values)
            jacobian = ((values[1:] - values[0]) / steps[:, None]).T  # [c, i] = d f_c / d x_i
        if not (np.isfinite(values).all() and np.isfinite(jacobian).all()):
            raise ModelFileError(
                f"{where}: {what}: the model evaluates to non-finite values in its domain; "
                f"the file is corrupted."
            )
        rate = max(rate, float(np.abs(np.linalg.eigvals(jacobian)).max()))
    return rate
