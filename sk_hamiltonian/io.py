"""Safe model files: save and load fitted models without pickle.

A model file is a zip archive holding a JSON manifest (format version,
package version, class names, parameters, fitted attributes and a
provenance record) and the model's arrays as ``.npy`` members. Loading reads
the arrays with ``allow_pickle=False``, constructs only the classes of this
package named in an allow-list, and checks every value before the model is
returned, so that a file from an untrusted source cannot run code; a file
that is malformed, truncated, oversized or from an incompatible version is
refused with a :class:`ModelFileError` that says what to do.

Pickle-based formats (``pickle``, ``joblib``) execute code while loading:
load such files only from sources you trust.
"""

import datetime
import math
import platform

import numpy as np
import sklearn
from sklearn.pipeline import Pipeline
from sklearn.utils._param_validation import InvalidParameterError

from ._derivatives import DerivativeTransformer
from ._hamiltonian import HamiltonianRegressor
from ._io_schema import (
    ATTRIBUTE_NAME,
    MODELS,
    check_dynamics,
    check_regressor,
    check_transformer,
    fitted_values,
)
from ._io_text import printable
from ._io_values import Encoder, decode
from ._io_zip import Container, ModelFileError, write_container
from ._vector_field import VectorFieldRegressor

__all__ = ["ModelFileError", "load", "read_manifest", "save", "SKOPS_TRUSTED"]

#: The ``format`` entry of every manifest.
FORMAT = "sk_hamiltonian.model"
#: The format version this module writes, and the oldest it reads. Format 2
#: writes lists, tuples and numpy scalars exactly (see :mod:`._io_values`).
FORMAT_VERSION = 2
OLDEST_FORMAT_VERSION = 1
#: The only classes a model file may name.
ESTIMATORS = {
    cls.__name__: cls
    for cls in (HamiltonianRegressor, VectorFieldRegressor, DerivativeTransformer)
}
#: Names of this package's types for ``skops.io.load(..., trusted=SKOPS_TRUSTED)``:
#: the estimators, and the data classes and basis functions of their model
#: space, which skops stores with them (it saves the private state too).
SKOPS_TRUSTED = [
    "sk_hamiltonian._derivatives.DerivativeTransformer",
    "sk_hamiltonian._hamiltonian.HamiltonianRegressor",
    "sk_hamiltonian._vector_field.VectorFieldRegressor",
    "sk_hamiltonian._space.contraction.ContractionPlan",
    "sk_hamiltonian._space.space.ModelSpace",
    "sk_hamiltonian._space.tables.FactorTables",
    "sk_hamiltonian._space.tables._fourier",
    "sk_hamiltonian._space.tables._legendre",
    "sk_hamiltonian._space.tensor.SlotLayout",
    "sk_hamiltonian._space.trie.Level",
]
# Pipelines inside pipelines: a few levels are plenty.
MAX_NESTING = 4
# Estimators in one file, pipeline steps included.
MAX_ESTIMATORS = 64
# Elements of an array-valued parameter (domain, periodic, couplings):
# a model over 10 000 state variables needs 20 000.
MAX_PARAMETER_ELEMENTS = 2**16
MANIFEST_KEYS = {"format", "format_version", "package_version", "written", "provenance", "model"}


def save(obj, path, *, provenance=None):
    """Save a model to a safe file (no pickle): a zip of a JSON manifest and ``.npy`` arrays.

    The file records the class names, parameters and fitted attributes (those
    ending in ``_``) of every estimator, the format and package versions, the
    library versions and time of saving, and ``provenance``.

    Parameters
    ----------
    obj : HamiltonianRegressor, VectorFieldRegressor, DerivativeTransformer or Pipeline
        The model, fitted or not; a :class:`~sklearn.pipeline.Pipeline` of
        these estimators is saved step by step.
    path : str or path-like or file object
        Where to write (``.skh`` is the customary extension). An existing
        file is replaced atomically: the model is written to a new file in
        the same folder, synced to disk, then renamed over it, so that an
        error, an interrupt (Ctrl-C) or a full disk leaves the previous
        file as it was (and no new file behind).
    provenance : dict, default=None
        Where the model comes from, kept in the manifest and shown by
        ``sk-hamiltonian show``: any JSON-serializable values, e.g.
        ``{"data_shape": [500, 41, 2], "fit_time": 3.2, "cv": "..."}``.

    Raises
    ------
    TypeError
        If ``obj`` (or a pipeline step) is not one of the supported
        estimators, a value cannot be stored without pickle, a fitted
        attribute is not one the estimator has, or ``provenance`` is not a
        JSON-serializable dict.
    OSError
        If the file cannot be written (an existing one is kept).

    See Also
    --------
    sk_hamiltonian.load : Read the file back, checking everything.
    sk_hamiltonian.io.read_manifest : The manifest alone (versions, classes, provenance).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from sk_hamiltonian import HamiltonianRegressor, save, load
    >>> X = np.random.default_rng(0).uniform(-1, 1, size=(100, 2))
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])
    >>> model = HamiltonianRegressor(degree=2).fit(X, y)
    >>> path = os.path.join(tempfile.mkdtemp(), "model.skh")
    >>> save(model, path, provenance={"data_shape": list(X.shape)})
    >>> bool(np.array_equal(load(path).predict(X), model.predict(X)))
    True
    """
    import json

    if provenance is None:
        provenance = {}
    if not isinstance(provenance, dict):
        raise TypeError(f"provenance must be a dict or None; got {type(provenance).__name__}.")
    try:
        json.dumps(provenance, allow_nan=False)
    except (TypeError, ValueError) as error:
        raise TypeError(
            f"provenance must hold JSON-serializable values (numbers, strings, lists, dicts; "
            f"no NaN): {error}."
        ) from None
    from . import __version__

    encoder = Encoder()
    manifest = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "written": {
            "time": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            "numpy": np.__version__,
            "scikit-learn": sklearn.__version__,
            "python": platform.python_version(),
        },
        "provenance": provenance,
        "model": _spec(obj, encoder, "obj"),
    }
    write_container(path, manifest, encoder.arrays)


def _spec(obj, encoder, what):
    if type(obj) is Pipeline:
        params = obj.get_params(deep=False)
        steps = params.pop("steps")
        if params.get("memory") is not None:
            raise TypeError(
                f"cannot save {what}: its memory={params['memory']!r} caches to disk; set "
                f"memory=None first."
            )
        return {
            "class": "Pipeline",
            "params": {k: encoder.encode(v, f"{what}.{k}") for k, v in params.items()},
            "steps": [
                {"name": name, "model": _spec(step, encoder, f"step {name!r}")}
                for name, step in steps
            ],
        }
    if type(obj).__name__ not in ESTIMATORS or ESTIMATORS[type(obj).__name__] is not type(obj):
        hint = ""
        if hasattr(obj, "best_estimator_") or type(obj).__name__.endswith("SearchCV"):
            hint = (
                " For a search, save its best_estimator_ and put what was chosen in "
                "provenance, e.g. provenance={'cv': str(search.best_params_)}."
            )
        raise TypeError(
            f"cannot save {what} of type {type(obj).__name__}: model files hold "
            f"{', '.join(ESTIMATORS)} and Pipelines of them.{hint}"
        )
    params = obj.get_params(deep=False)
    model = MODELS[type(obj).__name__]
    fitted = {
        k: v for k, v in vars(obj).items()
        if k.endswith("_") and not k.startswith("_") and not k.endswith("__")
    }
    unknown = sorted(set(fitted) - set(model.fields))
    if unknown:
        # load() reads only the fitted values of its table: refuse now what
        # could not be read back.
        raise TypeError(
            f"cannot save {what}: its attribute(s) {', '.join(unknown)} are not fitted values "
            f"a {type(obj).__name__} has ({', '.join(sorted(model.fields))}); delete them "
            f"first, and keep such notes in provenance."
        )
    private = {k: getattr(obj, k) for k in model.private if hasattr(obj, k) and fitted}
    return {
        "class": type(obj).__name__,
        "params": {k: encoder.encode(v, f"parameter {what}.{k}") for k, v in params.items()},
        "fitted": {
            k: encoder.encode(v, f"fitted attribute {what}.{k}") for k, v in fitted.items()
        },
        "private": {k: encoder.encode(v, f"state {what}.{k}") for k, v in private.items()},
    }


def load(path):
    """Load a model saved by :func:`sk_hamiltonian.save`, checking every part of the file first.

    Nothing in the file is executed: arrays are read with
    ``allow_pickle=False``, only the estimator classes of this package (and
    scikit-learn's ``Pipeline``) can be named, parameters pass the
    estimators' own validation, only the fitted values an estimator has are
    read, each array once, and every size is checked against the model
    (``powers_`` against ``degree`` and the state dimension, ``coef_``
    against the terms) before anything large is read or built. The values
    must agree with each other and with the parameters, and the time scales
    with the learned dynamics. Memory stays within a small multiple of the
    model's arrays; the table in :ref:`sharing` lists what is refused.

    Parameters
    ----------
    path : str or path-like or file object
        A file written by :func:`sk_hamiltonian.save`.

    Returns
    -------
    model : HamiltonianRegressor, VectorFieldRegressor, DerivativeTransformer or Pipeline
        The model, predicting, simulating and scoring exactly as the saved
        one did (same arrays, bit for bit). Continuing a ``partial_fit``
        starts afresh: the accumulated normal equations are not saved.

    Raises
    ------
    ModelFileError
        If the file is missing, not a model file, corrupted or truncated,
        too large, names an unknown class or parameter, holds inconsistent
        values, or comes from an incompatible format version; the message
        says which and what to do.

    See Also
    --------
    sk_hamiltonian.save : Write a model file.
    sk_hamiltonian.io.read_manifest : The manifest alone (versions, classes, provenance).

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from sk_hamiltonian import VectorFieldRegressor, save, load
    >>> X = np.random.default_rng(0).uniform(-1, 1, size=(100, 2))
    >>> model = VectorFieldRegressor(degree=1).fit(X, X[:, ::-1])
    >>> path = os.path.join(tempfile.mkdtemp(), "model.skh")
    >>> save(model, path)
    >>> load(path)
    VectorFieldRegressor(degree=1)
    """
    where = _name(path)
    with Container(path, where) as container:
        manifest = _checked_manifest(container)
        _check_extent(manifest["model"], container)
        try:
            return _build(manifest["model"], container, "the model", 0)
        except ModelFileError:
            raise
        except Exception as error:
            # A safety net: every failure the checks foresee has its own
            # message; this one keeps an unforeseen one to a line as well.
            raise ModelFileError(
                f"{where}: unexpected {type(error).__name__} while building the model "
                f"({str(error)[:200]}); the file is corrupted or was not written by "
                f"sk_hamiltonian.save."
            ) from None


def read_manifest(path):
    """The manifest of a model file: versions, time of saving, provenance and the model's parts.

    The container and versions are checked as by :func:`sk_hamiltonian.load`; arrays are
    not read, and no estimator is constructed.

    Parameters
    ----------
    path : str or path-like or file object
        A file written by :func:`sk_hamiltonian.save`.

    Returns
    -------
    manifest : dict
        The parsed JSON manifest: ``format_version``, ``package_version``,
        ``written`` (time and library versions), ``provenance`` and
        ``model`` (classes, parameters, and fitted values, arrays given by
        reference).

    Raises
    ------
    ModelFileError
        As :func:`sk_hamiltonian.load`, for the container and the versions.

    See Also
    --------
    sk_hamiltonian.load : The model itself.

    Examples
    --------
    >>> import numpy as np, tempfile, os
    >>> from sk_hamiltonian import DerivativeTransformer, save
    >>> from sk_hamiltonian.io import read_manifest
    >>> path = os.path.join(tempfile.mkdtemp(), "transformer.skh")
    >>> save(DerivativeTransformer(dt=0.1), path, provenance={"note": "unfitted"})
    >>> manifest = read_manifest(path)
    >>> manifest["model"]["class"], manifest["provenance"]
    ('DerivativeTransformer', {'note': 'unfitted'})
    """
    with Container(path, _name(path)) as container:
        return _checked_manifest(container)


def _name(path):
    """How messages name the file: its path, or "the model file" for a file object."""
    if isinstance(path, (str, bytes)) or hasattr(path, "__fspath__"):
        return repr(str(path))
    return "the model file"


def _checked_manifest(container):
    from . import __version__

    manifest = container.read_manifest()
    if manifest.get("format") != FORMAT:
        container.fail(
            f"the manifest is not that of an sk_hamiltonian model (format "
            f"{str(manifest.get('format'))[:40]!r}); write model files with sk_hamiltonian.save."
        )
    version, written_by = manifest.get("format_version"), manifest.get("package_version")
    if not isinstance(written_by, str) or len(written_by) > 40:
        container.fail("the manifest's package_version is not a version string.")
    written_by = printable(written_by)  # quoted in messages below
    if not isinstance(version, int) or isinstance(version, bool):
        container.fail(f"the manifest's format_version {str(version)[:20]!r} is not an integer.")
    if version > FORMAT_VERSION:
        container.fail(
            f"written by sk_hamiltonian {written_by} in model-file format {version}; this "
            f"sk_hamiltonian ({__version__}) reads formats {OLDEST_FORMAT_VERSION} to "
            f"{FORMAT_VERSION}. Upgrade sk_hamiltonian (pip install --upgrade sk_hamiltonian) "
            f"to load it."
        )
    if version < OLDEST_FORMAT_VERSION:
        container.fail(
            f"written by sk_hamiltonian {written_by} in model-file format {version}, which this "
            f"sk_hamiltonian ({__version__}) no longer reads (formats {OLDEST_FORMAT_VERSION} to "
            f"{FORMAT_VERSION}). Load it with sk_hamiltonian {written_by} and save it again, or "
            f"refit the model."
        )
    unknown = set(manifest) - MANIFEST_KEYS
    missing = {"model"} - set(manifest)
    if unknown or missing:
        container.fail(
            f"the manifest has unexpected entries {sorted(unknown)} or lacks {sorted(missing)}; "
            f"the file is corrupted."
        )
    for key in ("written", "provenance"):
        if not isinstance(manifest.get(key, {}), dict):
            container.fail(f"the manifest's {key!r} is not a JSON object.")
    return manifest


def _check_extent(model, container):
    """Before anything is read: few enough estimators, each array member referenced once."""
    count, stack = 0, [model]
    while stack:
        item = stack.pop()
        if isinstance(item, dict):
            count += "class" in item
            stack.extend(item.values())
        elif isinstance(item, list):
            stack.extend(item)
    if count > MAX_ESTIMATORS:
        container.fail(f"the model names {count} estimators, more than a model file holds "
                       f"({MAX_ESTIMATORS}); the file is refused.")
    container.check_references(model)


def _build(spec, container, what, depth):
    where = container.where
    if not isinstance(spec, dict) or not isinstance(spec.get("class"), str):
        container.fail(f"{what} is not described by an object with a 'class'.")
    name = spec["class"]
    if name == "Pipeline":
        return _build_pipeline(spec, container, what, depth)
    if name not in ESTIMATORS:
        container.fail(
            f"{what} is of class {name[:60]!r}, which a model file may not name: only "
            f"{', '.join(ESTIMATORS)} and Pipeline are allowed. The file is refused."
        )
    if set(spec) != {"class", "params", "fitted", "private"}:
        container.fail(f"{what} ({name}) has entries {sorted(spec)[:8]}; the file is corrupted.")
    cls = ESTIMATORS[name]
    what = f"{what} ({name})"
    est = cls()
    est.set_params(**_params(spec["params"], est, container, what))
    fitted, private = spec["fitted"], spec["private"]
    if not fitted:
        if private:
            container.fail(f"{what} is unfitted but carries fitted state.")
        return est
    attributes = fitted_values(container, est, fitted, private, what)
    if cls is DerivativeTransformer:
        check_transformer(where, est, attributes, what)
    else:
        check_regressor(where, est, attributes, what)
    if cls is not DerivativeTransformer and "support_" not in attributes:
        # Written before thresholds existed: every term was kept.
        attributes["support_"] = np.ones(attributes["coef_"].shape, bool)
    for key, value in attributes.items():
        setattr(est, key, value)
    if cls is not DerivativeTransformer:
        _rebuild(est, container, what)
    return est


def _params(encoded, est, container, what):
    if not isinstance(encoded, dict):
        container.fail(f"the parameters of {what} are not a JSON object.")
    known = est.get_params(deep=False)
    unknown = sorted(set(encoded) - set(known))
    if unknown:
        from . import __version__

        container.fail(
            f"{what} has parameter(s) {[str(u)[:40] for u in unknown[:5]]} unknown to this "
            f"sk_hamiltonian ({__version__}); the file comes from another version: upgrade "
            f"sk_hamiltonian to load it."
        )
    # Parameters missing from an older file keep their defaults (today's behaviour).
    params = _decoded(encoded, container, what)
    candidate = type(est)(**{**known, **params})
    try:
        candidate._validate_params()
        if hasattr(candidate, "_check_integer_params"):
            candidate._check_integer_params()
    except (InvalidParameterError, ValueError, TypeError) as error:
        container.fail(f"{what}: invalid parameter: {error}")
    return params


def _decoded(encoded, container, what):
    """Parameters from their manifest entries; their arrays small (MAX_PARAMETER_ELEMENTS)."""

    def read_array(member, shape, dtype, name):
        if math.prod(shape) > MAX_PARAMETER_ELEMENTS:
            container.fail(
                f"{name} declares an array of shape {tuple(shape)}, more than the "
                f"{MAX_PARAMETER_ELEMENTS} elements a parameter holds; the file is refused."
            )
        return container.read_array(member, shape, dtype, name)

    return {
        k: decode(v, container.where, f"parameter {k} of {what}", read_array)
        for k, v in encoded.items()
    }


def _rebuild(est, container, what):
    """Recompute the private state (model space, separable parts) from the public; probe it."""
    try:
        est._rebuild_fitted()
        est._partial = None
        check_dynamics(container.where, est, what)
    except ModelFileError:
        raise
    except (ValueError, TypeError, IndexError, KeyError, ArithmeticError,
            np.linalg.LinAlgError) as error:
        container.fail(f"{what}: the fitted values do not form a model ({error}).")


def _build_pipeline(spec, container, what, depth):
    if depth >= MAX_NESTING:
        container.fail(f"pipelines are nested deeper than {MAX_NESTING} levels.")
    if set(spec) != {"class", "params", "steps"} or not isinstance(spec["steps"], list):
        container.fail(f"{what} (Pipeline) has entries {sorted(spec)[:8]}; the file is corrupted.")
    if not spec["steps"]:
        container.fail(f"{what} (Pipeline) has no steps.")
    steps, names = [], set()
    for k, step in enumerate(spec["steps"]):
        name = step.get("name") if isinstance(step, dict) else None
        if (
            not isinstance(name, str) or not ATTRIBUTE_NAME.match(name) or "__" in name
            or name in names or set(step) != {"name", "model"}
        ):
            container.fail(f"step {k} of {what} has no valid, unique name.")
        names.add(name)
        steps.append((name, _build(step["model"], container, f"step {name!r}", depth + 1)))
    if not isinstance(spec["params"], dict):
        container.fail(f"the parameters of {what} (Pipeline) are not a JSON object.")
    params = _decoded(spec["params"], container, f"{what} (Pipeline)")
    known = set(Pipeline([("x", None)]).get_params(deep=False)) - {"steps"}
    if set(params) - known or params.get("memory") is not None:
        container.fail(
            f"{what} (Pipeline) has parameters {sorted(params)[:8]}; only {sorted(known)} are "
            f"known, and memory must be None."
        )
    pipeline = Pipeline(steps, **params)
    try:
        pipeline._validate_params()
    except (InvalidParameterError, ValueError, TypeError) as error:
        container.fail(f"{what} (Pipeline): invalid parameter: {error}")
    return pipeline
