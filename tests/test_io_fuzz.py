"""Hostile and broken model files: each gives a clear ModelFileError, nothing executes."""

import io
import json
import os
import pickle
import warnings
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    ModelFileError,
    VectorFieldRegressor,
    load,
    save,
)
from sk_hamiltonian.datasets import make_trajectories
from sk_hamiltonian.io import ESTIMATORS

# SK_HAMILTONIAN_FUZZ_EXAMPLES raises the count for a longer hunt.
FUZZ = settings(max_examples=int(os.environ.get("SK_HAMILTONIAN_FUZZ_EXAMPLES", 150)),
                deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])

#: Set by the planted payload if it ever runs.
EXECUTED = []


def _record(value):
    EXECUTED.append(value)
    return value


class Payload:
    """Unpickling this calls ``_record``: the stand-in for arbitrary code."""

    def __reduce__(self):
        return (_record, ("the payload ran",))


@pytest.fixture(scope="module")
def valid():
    X = make_trajectories("single_pendulum", 20, 20, 0.02, noise=0.01, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pipe = make_pipeline(
            DerivativeTransformer(dt=0.02), HamiltonianRegressor(degree=3, damping=True)
        ).fit(X)
    buffer = io.BytesIO()
    save(pipe, buffer, provenance={"data_shape": list(X.shape)})
    return buffer.getvalue()


def members(data):
    with zipfile.ZipFile(io.BytesIO(data)) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def rebuild(parts, compression=zipfile.ZIP_DEFLATED):
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=compression) as archive:
        for name, content in parts.items():
            archive.writestr(name, content)
    return buffer.getvalue()


def with_manifest(data, change):
    """The file with ``change(manifest)`` applied to its parsed manifest."""
    parts = members(data)
    manifest = json.loads(parts["manifest.json"])
    change(manifest)
    parts["manifest.json"] = json.dumps(manifest)
    return rebuild(parts)


def regressor_spec(manifest):
    return manifest["model"]["steps"][1]["model"]


def refused(data, match=None):
    """Load ``data``: it must raise ModelFileError (matching ``match``) and run nothing."""
    with pytest.raises(ModelFileError, match=match) as info:
        load(io.BytesIO(data))
    assert not EXECUTED
    message = str(info.value)
    assert message.startswith("the model file") and "\n" not in message
    return message


def loads_or_is_refused(data):
    """Either a valid model of an allowed class, or a ModelFileError: nothing else."""
    try:
        model = load(io.BytesIO(data))
    except ModelFileError as error:
        # Foreseen: the checks name the problem, not the safety net of load.
        assert "while building the model" not in str(error), error
    else:
        steps = model.steps if hasattr(model, "steps") else [("model", model)]
        assert all(type(step).__name__ in ESTIMATORS for _, step in steps)
    assert not EXECUTED


def test_the_valid_file_loads(valid):
    model = load(io.BytesIO(valid))
    assert isinstance(model[-1], HamiltonianRegressor) and model[-1].damping


@FUZZ
@given(fraction=st.floats(0, 1, exclude_max=True))
def test_truncated_files_are_refused(valid, fraction):
    refused(valid[: int(fraction * len(valid))])


@FUZZ
@given(flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(1, 255)),
                      min_size=1, max_size=4))
def test_flipped_bytes_never_crash(valid, flips):
    data = bytearray(valid)
    for where, mask in flips:
        data[int(where * len(data))] ^= mask
    loads_or_is_refused(bytes(data))


@FUZZ
@given(flips=st.lists(st.tuples(st.floats(0, 1, exclude_max=True), st.integers(1, 255)),
                      min_size=1, max_size=3))
def test_flipped_bytes_in_stored_members_never_crash(valid, flips):
    # Uncompressed members: the flips reach the JSON and the .npy bytes
    # themselves (the CRC is recomputed, as a forger would).
    parts = members(valid)
    name = sorted(parts)[len(flips) % len(parts)]
    content = bytearray(parts[name])
    for where, mask in flips:
        content[int(where * len(content))] ^= mask
    parts[name] = bytes(content)
    loads_or_is_refused(rebuild(parts, zipfile.ZIP_STORED))


JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers(-10**20, 10**20) | st.floats(allow_nan=False)
    | st.text(max_size=10),
    lambda children: st.lists(children, max_size=3)
    | st.dictionaries(st.text(max_size=8), children, max_size=3),
    max_leaves=8,
)


def paths(value, prefix=()):
    """Every path into a parsed JSON value."""
    yield prefix
    if isinstance(value, dict):
        for key, item in value.items():
            yield from paths(item, prefix + (key,))
    elif isinstance(value, list):
        for index, item in enumerate(value):
            yield from paths(item, prefix + (index,))


@FUZZ
@given(choice=st.floats(0, 1, exclude_max=True), replacement=JSON_VALUES)
def test_wrong_types_anywhere_in_the_manifest(valid, choice, replacement):
    manifest = json.loads(members(valid)["manifest.json"])
    all_paths = [p for p in paths(manifest) if p]
    path = all_paths[int(choice * len(all_paths))]

    def change(manifest):
        node = manifest
        for key in path[:-1]:
            node = node[key]
        node[path[-1]] = replacement

    loads_or_is_refused(with_manifest(valid, change))


@pytest.mark.parametrize(
    "key,value,match",
    [
        ("degree", "3", "invalid parameter"),
        ("degree", True, "must be an int, not a boolean"),
        ("solver", "pickle", "invalid parameter"),
        ("fit_on", None, "invalid parameter"),
        ("__class__", "x", "unknown to this sk_hamiltonian"),
        ("memory", "cache_dir", "unknown to this sk_hamiltonian"),
    ],
)
def test_parameters_go_through_the_estimators_constraints(valid, key, value, match):
    def change(manifest):
        regressor_spec(manifest)["params"][key] = value

    refused(with_manifest(valid, change), match)


@pytest.mark.parametrize(
    "attribute,value,match",
    [
        ("coef_", {"float": "nan"}, "coef_ must be a finite float array"),
        ("n_features_in_", 3, "is odd|powers_ has shape"),
        ("solver_", "os.system", "solver_ must be one of"),
        ("__class__", "x", "fitted attribute named '__class__'"),
        ("dict_", {"a": 1}, "no value a model file can hold"),
    ],
)
def test_fitted_values_are_checked(valid, attribute, value, match):
    def change(manifest):
        regressor_spec(manifest)["fitted"][attribute] = value

    refused(with_manifest(valid, change), match)


def test_missing_fitted_attribute_and_private_state(valid):
    def drop_coef(manifest):
        del regressor_spec(manifest)["fitted"]["coef_"]

    refused(with_manifest(valid, drop_coef), "lacks coef_")

    def plant_private(manifest):
        regressor_spec(manifest)["private"]["_space"] = 1

    refused(with_manifest(valid, plant_private), "private state '_space'")


def swap_array(valid, attribute, array):
    """Replace the member of ``attribute`` by ``array``, declared as such in the manifest."""
    parts = members(valid)
    manifest = json.loads(parts["manifest.json"])
    ref = regressor_spec(manifest)["fitted"][attribute]
    buffer = io.BytesIO()
    np.save(buffer, array)
    parts[ref["array"]] = buffer.getvalue()
    ref["shape"], ref["dtype"] = list(array.shape), array.dtype.str
    parts["manifest.json"] = json.dumps(manifest)
    return rebuild(parts)


@pytest.mark.parametrize(
    "attribute,array,match",
    [
        ("coef_", np.zeros(3), r"coef_ has shape \(3,\), expected \(9,\)"),
        ("coef_", np.array([np.inf] * 9), "finite"),
        ("powers_", np.zeros((9, 3), dtype=np.int64), r"powers_ has shape \(9, 3\)"),
        ("powers_", np.full((9, 2), 7, dtype=np.int64), "total degree above degree=3"),
        ("powers_", np.full((9, 2), -1, dtype=np.int64), "negative degree"),
        ("domain_", np.array([[1.0, -1.0], [0.0, 1.0]]), "low >= high"),
        ("domain_", np.zeros((2, 2), dtype=np.int64), "finite 2-D float array"),
        ("damping_", np.array([-0.5]), "non-negative"),
        ("damping_", np.zeros(2), r"damping_ has shape \(2,\)"),
        ("periodic_", np.array([True, False]), "periodic_ differs from the periodic parameter"),
        ("state_scale_", np.array([1.0, 0.0]), "positive floats"),
        ("support_", np.ones(3, dtype=bool), r"support_ has shape \(3,\), expected \(9,\)"),
        ("support_", np.ones(9), "support_ must be a boolean array"),
    ],
)
def test_inconsistent_arrays_are_refused(valid, attribute, array, match):
    refused(swap_array(valid, attribute, array), match)


def test_manifest_and_member_must_agree(valid):
    def lie(manifest):
        regressor_spec(manifest)["fitted"]["coef_"]["shape"] = [10]

    refused(with_manifest(valid, lie), r"has shape \(9,\) and dtype float64, but the manifest")


@pytest.mark.parametrize("shape", [[10**12], [2**40, 2**40], [10**6] * 8])
def test_huge_declared_shapes_are_refused_before_reading(valid, shape):
    def huge(manifest):
        regressor_spec(manifest)["fitted"]["coef_"]["shape"] = shape

    refused(with_manifest(valid, huge), "but the manifest declares")


def test_huge_npy_header_is_refused_before_reading(valid):
    parts = members(valid)
    manifest = json.loads(parts["manifest.json"])
    ref = regressor_spec(manifest)["fitted"]["coef_"]
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (10**11,)}
    )
    parts[ref["array"]] = header.getvalue() + b"\0" * 16
    ref["shape"] = [10**11]
    parts["manifest.json"] = json.dumps(manifest)
    refused(rebuild(parts), "holds .* bytes; its header declares")


def test_huge_declared_member_size_is_refused_before_reading(valid):
    # A zip bomb: a member that inflates far beyond its compressed size.
    parts = members(valid)
    parts["arrays/9999.npy"] = b"\0" * (300 * 2**20)
    refused(rebuild(parts), "declares 314572800 bytes, more than the limit")


@pytest.mark.parametrize(
    "name",
    ["../evil.npy", "/etc/evil.npy", "arrays/../../evil.npy", "arrays\\..\\evil.npy",
     "model.pkl", "arrays/", "arrays/0.npy/"],
)
def test_unexpected_and_traversal_member_names_are_refused(valid, name):
    parts = members(valid)
    parts[name] = b"x"
    assert refused(rebuild(parts), "unexpected member")


@pytest.mark.parametrize(
    "name", ["os.system", "builtins.eval", "LinearRegression", "sklearn.pipeline.Pipeline",
             "GridSearchCV"],
)
def test_unknown_classes_are_refused(valid, name):
    def change(manifest):
        regressor_spec(manifest)["class"] = name

    message = refused(with_manifest(valid, change), "may not name")
    assert "HamiltonianRegressor, VectorFieldRegressor, DerivativeTransformer" in message


@pytest.mark.parametrize(
    "version,match",
    [(2, r"format 2; this sk_hamiltonian \(0\.1\.0\) reads formats 1 to 1\. Upgrade"),
     (0, r"format 0, which this sk_hamiltonian \(0\.1\.0\) no longer reads .* save it again"),
     ("1", "not an integer")],
)
def test_old_and_future_versions_say_what_to_do(valid, version, match):
    def change(manifest):
        manifest["format_version"] = version
        manifest["package_version"] = "9.9.9"

    refused(with_manifest(valid, change), match)


def test_a_future_parameter_asks_for_an_upgrade(valid):
    def change(manifest):
        regressor_spec(manifest)["params"]["new_option"] = 1

    refused(with_manifest(valid, change), "unknown to this sk_hamiltonian .* upgrade")


def test_other_formats_are_refused(valid):
    refused(b"not a zip at all", "not a readable zip archive")
    refused(rebuild({"arrays/0000.npy": b""}), "no 'manifest.json'")
    refused(rebuild({"manifest.json": "[1, 2]"}), "not that of an sk_hamiltonian model|JSON obj")
    refused(rebuild({"manifest.json": '{"format": NaN}'}), "NaN, which is not JSON")
    refused(rebuild({"manifest.json": "[" * 100_000 + "]" * 100_000}), "not valid JSON|deeper")


def test_a_planted_pickle_payload_is_refused_and_never_runs(valid, tmp_path):
    payload = np.array([Payload()], dtype=object)
    # Sanity: unpickling the payload would run it.
    assert pickle.loads(pickle.dumps(Payload())) == "the payload ran"
    EXECUTED.clear()
    # 1. as the array of coef_, declared honestly as an object array ...
    parts = members(valid)
    manifest = json.loads(parts["manifest.json"])
    ref = regressor_spec(manifest)["fitted"]["coef_"]
    buffer = io.BytesIO()
    np.save(buffer, payload, allow_pickle=True)
    parts[ref["array"]] = buffer.getvalue()
    honest = dict(parts, **{"manifest.json": json.dumps(
        {**manifest, "model": {**manifest["model"]}})})
    ref["dtype"], ref["shape"] = "|O", [1]
    honest["manifest.json"] = json.dumps(manifest)
    refused(rebuild(honest), "declares dtype '|O'")
    # ... or as float64, so that only the .npy header tells;
    ref["dtype"] = "<f8"
    parts["manifest.json"] = json.dumps(manifest)
    refused(rebuild(parts), "object arrays could carry a pickle")
    # 2. as a whole pickled model beside the manifest, or instead of the file.
    refused(rebuild({**members(valid), "model.pkl": pickle.dumps(Payload())}), "unexpected")
    refused(pickle.dumps(Payload()), "not a readable zip archive")
    assert not EXECUTED


def test_vector_field_and_transformer_checks(tmp_path):
    X = np.random.default_rng(0).uniform(-1, 1, size=(60, 2))
    model = VectorFieldRegressor(degree=2).fit(X, X[:, ::-1])
    buffer = io.BytesIO()
    save(model, buffer)
    data = buffer.getvalue()

    def rows(manifest):
        manifest["model"]["fitted"]["n_features_in_"] = 1

    refused(with_manifest(data, rows), r"powers_ has shape \(6, 2\), expected \(n_basis >= 1, 1\)")

    transformer = DerivativeTransformer(dt=0.1, degree=3).fit(np.zeros((2, 10, 2)))
    buffer = io.BytesIO()
    save(transformer, buffer)

    def window(manifest):
        manifest["model"]["fitted"]["window_"] = 7

    refused(with_manifest(buffer.getvalue(), window), "window_=7 disagrees")


def test_a_file_without_support_keeps_every_term(valid):
    # Files written before thresholds existed have no support_: all terms kept.
    def drop(manifest):
        del regressor_spec(manifest)["fitted"]["support_"]

    model = load(io.BytesIO(with_manifest(valid, drop)))
    reference = load(io.BytesIO(valid))
    assert model[-1].support_.all() and model[-1].support_.shape == (9,)
    X = reference[-1].domain_.mean(axis=1)[None]
    assert np.array_equal(model[-1].predict(X), reference[-1].predict(X))
