"""What a model file may hold, class by class, and how values are encoded.

Values go into the JSON manifest as plain scalars, lists of strings, or a
reference ``{"array": member, "shape": ..., "dtype": ...}`` to an ``.npy``
member; a non-finite float is ``{"float": "nan"}`` (JSON has no NaN), and a
list of sequences of different lengths is ``{"items": [...]}``, each item
encoded in turn (at most two levels deep). Nothing
else can be written or read, so loading never constructs anything beyond
numbers, strings, numpy arrays and the allow-listed estimator classes.
"""

import math
import re
from numbers import Integral, Real

import numpy as np

from ._io_zip import ARRAY_KINDS, ModelFileError
from ._space.mixed import factor_degrees

#: Public fitted attributes and parameter names: lower case, ending in ``_``
#: for fitted ones, never starting with one (no dunders, no private state).
ATTRIBUTE_NAME = re.compile(r"\A[a-z][a-z0-9_]{0,63}\Z")
#: Private fitted state saved explicitly (the rest is rebuilt from the public).
PRIVATE_STATE = ("_state_magnitude",)
SPECIAL_FLOATS = {"nan": math.nan, "inf": math.inf, "-inf": -math.inf}
#: Deepest nesting of lists that are no array (groups of different sizes).
MAX_NESTING = 2
#: How an array-valued parameter was given, to give it back the same way.
CONTAINERS = {"ndarray": lambda a: a, "list": lambda a: a.tolist(),
              "tuple": lambda a: tuple(a.tolist())}


class Encoder:
    """Collects the arrays of a manifest while encoding values."""

    def __init__(self):
        self.arrays = {}

    def encode(self, value, what):
        """A JSON-able form of ``value`` (``what`` names it in errors)."""
        if value is None or isinstance(value, (bool, str)):
            return value
        if isinstance(value, np.bool_):
            return bool(value)
        if isinstance(value, Integral):
            return int(value)
        if isinstance(value, Real):
            value = float(value)
            if math.isfinite(value):
                return value
            return {"float": "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")}
        if isinstance(value, (np.ndarray, list, tuple)):
            kind = type(value).__name__ if isinstance(value, (list, tuple)) else "ndarray"
            if kind != "ndarray" and all(isinstance(v, str) for v in value) and value:
                return {"strings": list(value), "as": kind}
            try:
                array = np.asarray(value)
            except ValueError:
                # Groups of different sizes (``couplings``) have no array
                # form: item by item (an ndarray is always rectangular).
                return {"items": [self.encode(v, what) for v in value], "as": kind}
            if array.dtype.kind == "O" and all(isinstance(v, str) for v in array.ravel()):
                return {"strings": [str(v) for v in array.ravel()], "as": "ndarray"}
            if array.dtype.kind not in ARRAY_KINDS:
                raise TypeError(
                    f"cannot save {what}: an array of dtype {array.dtype}; model files hold "
                    f"booleans, integers, floats and strings only."
                )
            name = f"arrays/{len(self.arrays):04d}.npy"
            self.arrays[name] = array
            return {"array": name, "shape": list(array.shape), "dtype": array.dtype.str,
                    "as": kind}
        raise TypeError(
            f"cannot save {what}: a value of type {type(value).__name__}; model files hold "
            f"None, booleans, numbers, strings and numeric arrays only."
        )


def decode(value, container, what, depth=0):
    """The value an :meth:`Encoder.encode` result stands for, read from ``container``."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, dict):
        keys = set(value)
        if keys == {"float"} and isinstance(value["float"], str) and (
            value["float"] in SPECIAL_FLOATS
        ):
            return SPECIAL_FLOATS[value["float"]]
        kind = value.get("as") if isinstance(value.get("as"), str) else None
        if (
            keys == {"items", "as"} and kind in ("list", "tuple")
            and isinstance(value["items"], list) and depth < MAX_NESTING
        ):
            items = [decode(v, container, what, depth + 1) for v in value["items"]]
            return items if kind == "list" else tuple(items)
        if keys == {"strings", "as"} and _is_string_list(value["strings"]):
            if kind == "ndarray":
                return np.array(value["strings"], dtype=object)
            if kind in ("list", "tuple"):
                return CONTAINERS[kind](np.array(value["strings"], dtype=object))
        if keys == {"array", "shape", "dtype", "as"} and kind in CONTAINERS:
            shape, dtype = value["shape"], value["dtype"]
            if not (
                isinstance(shape, list) and len(shape) <= 8
                and all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n for n in shape)
            ):
                raise ModelFileError(f"{container.where}: {what} declares shape {shape!r}.")
            try:
                dtype = np.dtype(dtype) if isinstance(dtype, str) and len(dtype) < 8 else None
            except TypeError:
                dtype = None
            if dtype is None or dtype.kind not in ARRAY_KINDS:
                raise ModelFileError(
                    f"{container.where}: {what} declares dtype {value['dtype']!r}; model arrays "
                    f"are booleans, integers or floats."
                )
            if not isinstance(value["array"], str):
                raise ModelFileError(f"{container.where}: {what} names no array member.")
            array = container.read_array(value["array"], shape, dtype)
            return CONTAINERS[kind](array)
    raise ModelFileError(
        f"{container.where}: {what} holds {str(value)[:80]!r}, which is no value a model file "
        f"can hold; the file is corrupted or was not written by sk_hamiltonian.save."
    )


def _is_string_list(value):
    return isinstance(value, list) and all(isinstance(v, str) for v in value)


# ---------------------------------------------------------------- checks
def _int(value, low=0):
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= low


def _float(value):
    return isinstance(value, (float, int, np.floating)) and not isinstance(value, bool)


def _array(value, kinds, ndim, finite=False):
    return (
        isinstance(value, np.ndarray) and value.dtype.kind in kinds and value.ndim in ndim
        and (not finite or bool(np.isfinite(value).all()))
    )


# Checks of each known fitted attribute on its own: (test, what it must be).
REGRESSOR_ATTRIBUTES = {
    "n_features_in_": (lambda v: _int(v, 1), "a positive integer"),
    "feature_names_in_": (
        lambda v: isinstance(v, np.ndarray) and v.dtype == object and v.ndim == 1,
        "an array of strings",
    ),
    "coef_": (lambda v: _array(v, "f", (1, 2), finite=True), "a finite float array"),
    "powers_": (lambda v: _array(v, "iu", (2,)), "a 2-D integer array"),
    "periodic_": (lambda v: _array(v, "b", (1,)), "a 1-D boolean array"),
    "mixed_": (lambda v: _array(v, "b", (1,)), "a 1-D boolean array"),
    "domain_": (lambda v: _array(v, "f", (2,), finite=True), "a finite 2-D float array"),
    "damping_": (lambda v: _array(v, "f", (1,), finite=True) and (v >= 0).all(),
                 "a finite 1-D array of non-negative floats"),
    "state_scale_": (lambda v: _array(v, "f", (1,), finite=True) and (v > 0).all(),
                     "a finite 1-D array of positive floats"),
    "support_": (lambda v: _array(v, "b", (1, 2)), "a boolean array"),
    "resampled_coef_": (lambda v: _array(v, "f", (2, 3), finite=True),
                        "a finite float array of one row per resample"),
    "resampled_damping_": (lambda v: _array(v, "f", (2,), finite=True) and (v >= 0).all(),
                           "a finite 2-D array of non-negative floats"),
    "cond_": (_float, "a float"),
    "rank_": (_int, "a non-negative integer"),
    "n_terms_": (_int, "a non-negative integer"),
    "n_iter_": (lambda v: _int(v) or _array(v, "iu", (0, 1, 2)), "a non-negative integer"),
    "solver_": (lambda v: v in ("lstsq", "normal", "iterative", "sketch"),
                "one of 'lstsq', 'normal', 'iterative', 'sketch'"),
    "dt_": (_float, "a float"),
    "time_scale_": (_float, "a float"),
    "energy_trend_": (_float, "a float"),
    "energy_trend_z_": (_float, "a float"),
    "_state_magnitude": (lambda v: _array(v, "f", (1,), finite=True) and (v >= 0).all(),
                         "a finite 1-D array of non-negative floats"),
}
TRANSFORMER_ATTRIBUTES = {
    "n_features_in_": REGRESSOR_ATTRIBUTES["n_features_in_"],
    "window_": (lambda v: _int(v, 2), "an integer of at least 2"),
}
# What a fitted model cannot do without.
REGRESSOR_REQUIRED = (
    "n_features_in_", "coef_", "powers_", "periodic_", "domain_", "dt_", "time_scale_",
    "state_scale_", "_state_magnitude",
)
TRANSFORMER_REQUIRED = ("n_features_in_", "window_")


def check_attributes(where, name, attributes, known, required):
    """Each attribute against ``known``; every ``required`` one present if any is."""
    for key, value in attributes.items():
        if key in known:
            test, kind = known[key]
            if not test(value):
                raise ModelFileError(
                    f"{where}: fitted attribute {name}.{key} must be {kind}; got "
                    f"{_describe(value)}. The file is corrupted."
                )
        elif not (_float(value) or isinstance(value, str) or value is None
                  or _array(value, "biuf", range(9))):
            raise ModelFileError(
                f"{where}: fitted attribute {name}.{key} holds {_describe(value)}, which no "
                f"model of this version has; the file is corrupted."
            )
    if attributes:
        missing = [key for key in required if key not in attributes]
        if missing:
            raise ModelFileError(
                f"{where}: the fitted {name} lacks {', '.join(missing)}; the file is "
                f"incomplete. Save the model again with sk_hamiltonian.save."
            )


def _describe(value):
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} and dtype {value.dtype}"
    return f"{type(value).__name__} {str(value)[:40]}"


def check_regressor(where, est, attributes):
    """Shapes and values of a regressor's fitted attributes agree with each other."""
    name = type(est).__name__

    def need(condition, problem):
        if not condition:
            raise ModelFileError(f"{where}: {name}: {problem}; the file is corrupted.")

    n = attributes["n_features_in_"]
    powers, coef, domain = attributes["powers_"], attributes["coef_"], attributes["domain_"]
    periodic = attributes["periodic_"]
    # A model saved before mixed variables existed has none.
    mixed = attributes.get("mixed_", np.zeros(n, dtype=bool))
    need(powers.shape[1] == n and powers.shape[0] >= 1,
         f"powers_ has shape {powers.shape}, expected (n_basis >= 1, {n})")
    need(periodic.shape == (n,), f"periodic_ has shape {periodic.shape}, expected ({n},)")
    need(mixed.shape == (n,), f"mixed_ has shape {mixed.shape}, expected ({n},)")
    need(not np.any(mixed & periodic), "mixed_ and periodic_ mark the same variable")
    need(domain.shape == (n, 2), f"domain_ has shape {domain.shape}, expected ({n}, 2)")
    need(bool(np.all(domain[:, 1] > domain[:, 0])), "domain_ has a row with low >= high")
    need(bool(np.all(powers[:, ~(periodic | mixed)] >= 0)),
         "powers_ holds a negative degree of a variable neither periodic nor mixed")
    degrees = factor_degrees(powers.astype(np.int64), mixed)
    need(int(degrees.sum(axis=1).max()) <= est.degree,
         f"powers_ holds a basis function of total degree above degree={est.degree}")
    n_basis = powers.shape[0]
    if name == "HamiltonianRegressor":
        need(n % 2 == 0, f"n_features_in_={n} is odd")
        need(coef.shape == (n_basis,), f"coef_ has shape {coef.shape}, expected ({n_basis},)")
        need("damping_" in attributes, "damping_ is missing")
        damping = attributes["damping_"]
        need(damping.shape == (n // 2,),
             f"damping_ has shape {damping.shape}, expected ({n // 2},)")
        need(est.damping or not damping.any(), "damping_ is non-zero with damping=False")
        support_shape = (n_basis,)
    else:
        need(coef.shape[0] == n_basis,
             f"coef_ has {coef.shape[0]} rows for {n_basis} basis functions")
        support_shape = coef.shape
    if "resampled_coef_" in attributes:
        # One row per refit; n_resamples may have been set after the fit.
        resampled = attributes["resampled_coef_"]
        need(resampled.shape[0] >= 1 and resampled.shape[1:] == coef.shape,
             f"resampled_coef_ has shape {resampled.shape}, expected (n_resamples >= 1,) + "
             f"{coef.shape}")
    if "resampled_damping_" in attributes:
        need(name == "HamiltonianRegressor" and est.damping,
             "resampled_damping_ is present without damping=True")
        rows = attributes.get("resampled_coef_", np.zeros((0,))).shape[0]
        need(attributes["resampled_damping_"].shape == (rows, n // 2),
             f"resampled_damping_ has shape {attributes['resampled_damping_'].shape}, "
             f"expected ({rows}, {n // 2}), a row per refit of resampled_coef_")
    for key in ("state_scale_", "_state_magnitude"):
        if key in attributes:
            need(attributes[key].shape == (n,), f"{key} has shape {attributes[key].shape}, "
                 f"expected ({n},)")
    if "support_" in attributes:
        need(attributes["support_"].shape == support_shape,
             f"support_ has shape {attributes['support_'].shape}, expected {support_shape}")
    if "feature_names_in_" in attributes:
        names = attributes["feature_names_in_"]
        need(names.shape == (n,) and all(isinstance(v, str) for v in names),
             f"feature_names_in_ must hold {n} strings")
    if est.domain is not None:
        given = np.asarray(est.domain, dtype=float)
        need(given.shape == domain.shape and np.array_equal(given, domain),
             "domain_ differs from the domain parameter")
    given = (np.zeros(n, dtype=bool) if est.periodic is None
             else np.asarray(est.periodic).astype(bool))
    need(given.shape == periodic.shape and np.array_equal(given, periodic),
         "periodic_ differs from the periodic parameter")
    if "mixed_" in attributes:
        given = (np.zeros(n, dtype=bool) if est.mixed is None
                 else np.asarray(est.mixed).astype(bool))
        need(given.shape == mixed.shape and np.array_equal(given, mixed),
             "mixed_ differs from the mixed parameter")


def check_transformer(where, est, attributes):
    """A DerivativeTransformer's window agrees with its parameters."""
    n = attributes["n_features_in_"]
    if n % 2:
        raise ModelFileError(f"{where}: DerivativeTransformer: n_features_in_={n} is odd.")
    try:
        window = est._resolve_window()
    except ValueError as error:
        raise ModelFileError(f"{where}: DerivativeTransformer: {error}") from None
    if attributes["window_"] != window:
        raise ModelFileError(
            f"{where}: DerivativeTransformer: window_={attributes['window_']} disagrees with "
            f"its parameters (window={est.window!r}, degree={est.degree}: {window}); the file "
            f"is corrupted."
        )
