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
import platform

import numpy as np
import sklearn
from sklearn.pipeline import Pipeline
from sklearn.utils._param_validation import InvalidParameterError

from ._derivatives import DerivativeTransformer
from ._hamiltonian import HamiltonianRegressor
from ._io_schema import (
    ATTRIBUTE_NAME,
    PRIVATE_STATE,
    REGRESSOR_ATTRIBUTES,
    REGRESSOR_REQUIRED,
    TRANSFORMER_ATTRIBUTES,
    TRANSFORMER_REQUIRED,
    Encoder,
    check_attributes,
    check_regressor,
    check_transformer,
    decode,
)
from ._io_zip import Container, ModelFileError, write_container
from ._vector_field import VectorFieldRegressor

__all__ = ["ModelFileError", "load", "read_manifest", "save", "SKOPS_TRUSTED"]

#: The ``format`` entry of every manifest.
FORMAT = "sk_hamiltonian.model"
#: The format version this module writes, and the oldest it reads.
FORMAT_VERSION = 1
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
        file is overwritten.
    provenance : dict, default=None
        Where the model comes from, kept in the manifest and shown by
        ``sk-hamiltonian show``: any JSON-serializable values, e.g.
        ``{"data_shape": [500, 41, 2], "fit_time": 3.2, "cv": "..."}``.

    Raises
    ------
    TypeError
        If ``obj`` (or a pipeline step) is not one of the supported
        estimators, a value cannot be stored without pickle, or
        ``provenance`` is not a JSON-serializable dict.

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
    fitted = {
        k: v for k, v in vars(obj).items() if k.endswith("_") and ATTRIBUTE_NAME.match(k)
    }
    private = {k: getattr(obj, k) for k in PRIVATE_STATE if hasattr(obj, k) and fitted}
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
    estimators' own validation, fitted arrays must agree in shape, type and
    value, and every declared size is checked before the bytes are read.

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
    est = cls()
    est.set_params(**_params(spec["params"], est, container, f"{what} ({name})"))
    fitted = _values(spec["fitted"], container, f"{what} ({name})", fitted=True)
    private = _values(spec["private"], container, f"{what} ({name})", fitted=False)
    if not fitted:
        if private:
            container.fail(f"{what} ({name}) is unfitted but carries fitted state.")
        return est
    attributes = {**fitted, **private}
    if cls is DerivativeTransformer:
        check_attributes(where, name, attributes, TRANSFORMER_ATTRIBUTES, TRANSFORMER_REQUIRED)
        check_transformer(where, est, attributes)
    else:
        required = REGRESSOR_REQUIRED + (("damping_",) if cls is HamiltonianRegressor else ())
        check_attributes(where, name, attributes, REGRESSOR_ATTRIBUTES, required)
        check_regressor(where, est, attributes)
    if cls is not DerivativeTransformer and "support_" not in attributes:
        # Written before thresholds existed: every term was kept.
        coef = attributes["coef_"]
        attributes["support_"] = np.ones(coef.shape if coef.ndim == 2 else coef.shape[:1], bool)
    for key, value in attributes.items():
        setattr(est, key, value)
    if cls is not DerivativeTransformer:
        _rebuild(est, container, f"{what} ({name})")
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
    params = {k: decode(v, container, f"parameter {k} of {what}") for k, v in encoded.items()}
    candidate = type(est)(**{**known, **params})
    try:
        candidate._validate_params()
        if hasattr(candidate, "_check_integer_params"):
            candidate._check_integer_params()
    except (InvalidParameterError, ValueError, TypeError) as error:
        container.fail(f"{what}: invalid parameter: {error}")
    return params


def _values(encoded, container, what, fitted):
    if not isinstance(encoded, dict):
        container.fail(f"the fitted state of {what} is not a JSON object.")
    out = {}
    for key, value in encoded.items():
        if fitted and not (isinstance(key, str) and ATTRIBUTE_NAME.match(key)
                           and key.endswith("_")):
            container.fail(
                f"{what} has a fitted attribute named {str(key)[:40]!r}; fitted attributes are "
                f"lower-case names ending in '_'. The file is refused."
            )
        if not fitted and key not in PRIVATE_STATE:
            container.fail(f"{what} has private state {str(key)[:40]!r}, which is not allowed.")
        kind = "attribute" if fitted else "state"
        out[key] = decode(value, container, f"{kind} {key} of {what}")
    return out


def _rebuild(est, container, what):
    """Recompute the private state (model space, separable parts) from the public."""
    try:
        est._rebuild_fitted()
        est._partial = None
        # A last check that the parts fit together: the field at the box centre.
        value = est._vector_field(est.domain_.mean(axis=1)[None])
    except (ValueError, TypeError, IndexError, KeyError, ArithmeticError) as error:
        container.fail(f"{what}: the fitted values do not form a model ({error}).")
    if not np.isfinite(value).all():
        container.fail(f"{what}: the model evaluates to non-finite values; the file is corrupted.")


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
    params = {
        k: decode(v, container, f"parameter {k} of {what}") for k, v in spec["params"].items()
    }
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
