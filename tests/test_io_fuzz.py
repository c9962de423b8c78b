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
    """The file with ``change(manifest)`` applied to its parsed manifest.

    Members the changed manifest no longer refers to are dropped, as a forger
    would (a file with an unreferenced member is refused for that alone).
    """
    parts = members(data)
    manifest = json.loads(parts["manifest.json"])
    change(manifest)
    parts["manifest.json"] = json.dumps(manifest)
    text = parts["manifest.json"]
    return rebuild({k: v for k, v in parts.items() if k == "manifest.json" or f'"{k}"' in text})


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
        ("coef_", {"float": "nan"}, "coef_ is not an array reference"),
        ("n_features_in_", 3, "n_features_in_=3 is odd"),
        ("solver_", "os.system", "solver_ must be one of"),
        ("__class__", "x", "fitted attribute '__class__' is not one a HamiltonianRegressor has"),
        ("dict_", {"a": 1}, "fitted attribute 'dict_' is not one a HamiltonianRegressor has"),
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

    refused(with_manifest(valid, plant_private),
            "private state '_space' is not one a HamiltonianRegressor has")


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
        ("coef_", np.zeros(3), r"coef_ declares shape \(3,\), expected \(9,\)"),
        ("coef_", np.array([np.inf] * 9), "finite"),
        ("powers_", np.zeros((9, 3), dtype=np.int64),
         r"powers_ declares shape \(9, 3\), expected \(9, 2\)"),
        ("powers_", np.full((9, 2), 7, dtype=np.int64),
         r"powers_ holds \[7, 7\], which these parameters exclude"),
        ("powers_", np.full((9, 2), -1, dtype=np.int64),
         r"powers_ holds \[-1, -1\], which these parameters exclude"),
        ("domain_", np.array([[1.0, -1.0], [0.0, 1.0]]), "low >= high"),
        ("domain_", np.zeros((2, 2), dtype=bool), "finite 2-D float array of dtype float64"),
        ("damping_", np.array([-0.5]), "non-negative"),
        ("damping_", np.zeros(2), r"damping_ declares shape \(2,\), expected \(1,\)"),
        ("periodic_", np.array([True, False]), "periodic_ differs from the periodic parameter"),
        ("state_scale_", np.array([1.0, 0.0]), "positive floats"),
        ("support_", np.ones(3, dtype=bool), r"support_ declares shape \(3,\), expected \(9,\)"),
        ("support_", np.ones(9), "support_ must be a boolean array"),
    ],
)
def test_inconsistent_arrays_are_refused(valid, attribute, array, match):
    refused(swap_array(valid, attribute, array), match)


def test_manifest_and_member_must_agree(valid):
    def lie(manifest):
        regressor_spec(manifest)["fitted"]["coef_"]["dtype"] = "<f4"

    refused(with_manifest(valid, lie),
            r"has shape \(9,\) and dtype float64, but the manifest declares \(9,\) and float32")


@pytest.mark.parametrize("shape", [[10**12], [2**40, 2**40], [10**6] * 8])
def test_huge_declared_shapes_are_refused_before_reading(valid, shape):
    def huge(manifest):
        regressor_spec(manifest)["fitted"]["coef_"]["shape"] = shape

    refused(with_manifest(valid, huge), r"coef_ declares shape \(.*\), expected \(9,\)")


def test_huge_npy_header_is_refused_before_reading(valid):
    parts = members(valid)
    manifest = json.loads(parts["manifest.json"])
    ref = regressor_spec(manifest)["fitted"]["coef_"]
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": (10**11,)}
    )
    parts[ref["array"]] = header.getvalue() + b"\0" * 16
    refused(rebuild(parts), r"has shape \(100000000000,\) .* but the manifest declares \(9,\)")


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
    [(3, r"format 3; this sk_hamiltonian \(0\.1\.0\) reads formats 1 to 2\. Upgrade"),
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
    # ... or as the float64 array it replaces, so that only the .npy header tells;
    ref["dtype"], ref["shape"] = "<f8", [9]
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

    refused(with_manifest(data, rows), r"domain_ declares shape \(2, 2\), expected \(1, 2\)")

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


# --------------------------------------------------- bounded loading (issue 32)
def measured_refusal(data, monkeypatch, match=None):
    """Refuse ``data`` as :func:`refused`; return (peak traced bytes, member bytes read)."""
    import tracemalloc

    from sk_hamiltonian import _io_zip

    read = []
    original = _io_zip.Container.read_bytes

    def read_bytes(self, name):
        data = original(self, name)
        read.append(len(data))
        return data

    monkeypatch.setattr(_io_zip.Container, "read_bytes", read_bytes)
    tracemalloc.start()
    try:
        message = refused(data, match)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
        monkeypatch.setattr(_io_zip.Container, "read_bytes", original)
    # A foreseen refusal, not the safety net of load.
    assert "while building the model" not in message, message
    return peak, sum(read)


def with_parts(data, change):
    """The file with ``change(manifest, parts)`` applied (members as a name -> bytes dict)."""
    parts = members(data)
    manifest = json.loads(parts["manifest.json"])
    change(manifest, parts)
    parts["manifest.json"] = json.dumps(manifest)
    return rebuild(parts)


def npy(array):
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def big_member_file(valid, path, size, refer):
    """``valid`` plus a member of ``size`` zero bytes (deflated to ~size/1000), streamed to
    ``path``; ``refer(manifest, name, shape)`` makes the manifest refer to it (members it
    no longer refers to are dropped)."""
    parts = members(valid)
    manifest = json.loads(parts["manifest.json"])
    name, shape = "arrays/9000.npy", (size // 8,)
    refer(manifest, name, shape)
    text = parts["manifest.json"] = json.dumps(manifest)
    parts = {k: v for k, v in parts.items() if k == "manifest.json" or f'"{k}"' in text}
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        header, {"descr": "<f8", "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for member, content in parts.items():
            archive.writestr(member, content)
        with archive.open(name, "w", force_zip64=True) as stream:
            stream.write(header.getvalue())
            chunk = b"\0" * 2**20
            for _ in range(size // len(chunk)):
                stream.write(chunk)
    return path.read_bytes()


@pytest.mark.parametrize("value", [1.5, "x", {"float": "nan"}])
def test_unknown_fitted_attributes_are_refused(valid, value):
    def plant(manifest):
        regressor_spec(manifest)["fitted"]["evil_"] = value

    refused(with_manifest(valid, plant), "'evil_' is not one a HamiltonianRegressor has")


def test_the_reference_bomb_is_refused_before_reading(valid, tmp_path, monkeypatch):
    # Issue 32: unknown attributes all referring to one large member (250 MiB
    # there, 32 MiB here) loaded in 52 s at 3.4 GB.
    size = 32 * 2**20

    def refer(manifest, name, shape):
        for k in range(8):
            regressor_spec(manifest)["fitted"][f"evil{k}_"] = {
                "array": name, "shape": list(shape), "dtype": "<f8", "as": "ndarray"}

    data = big_member_file(valid, tmp_path / "bomb.skh", size, refer)
    peak, read = measured_refusal(data, monkeypatch, "referred to more than once|more than once")
    assert read < 64 * 2**10 and peak < 4 * 2**20, (read, peak)


@pytest.mark.parametrize("where", ["coef_", "domain_param", "unknown"])
def test_one_large_member_is_refused_before_reading(valid, tmp_path, monkeypatch, where):
    size = 32 * 2**20

    def refer(manifest, name, shape):
        ref = {"array": name, "shape": list(shape), "dtype": "<f8", "as": "ndarray"}
        spec = regressor_spec(manifest)
        if where == "coef_":  # the member of coef_ replaced by a large one
            spec["fitted"]["coef_"] = ref
        elif where == "domain_param":
            spec["params"]["domain"] = ref
        else:
            spec["fitted"]["evil_"] = ref

    data = big_member_file(valid, tmp_path / "big.skh", size, refer)
    match = {"coef_": r"coef_ declares shape \(4194304,\), expected \(9,\)",
             "domain_param": "more than the 65536 elements a parameter holds",
             "unknown": "'evil_' is not one a HamiltonianRegressor has"}[where]
    peak, read = measured_refusal(data, monkeypatch, match)
    assert read < 64 * 2**10 and peak < 4 * 2**20, (read, peak)


def test_a_member_referenced_twice_or_not_at_all_is_refused(valid):
    def twice(manifest):
        fitted = regressor_spec(manifest)["fitted"]
        fitted["state_scale_"]["array"] = fitted["_state_magnitude"]["array"] \
            if "_state_magnitude" in fitted else regressor_spec(manifest)["private"][
                "_state_magnitude"]["array"]

    refused(with_manifest(valid, twice), "refers to member .* more than once")
    parts = members(valid)
    parts["arrays/0999.npy"] = npy(np.zeros(3))
    refused(rebuild(parts), r"1 member\(s\) the manifest does not refer to \(arrays/0999.npy\)")


def set_powers_row(manifest, parts, degree, row):
    spec = regressor_spec(manifest)
    spec["params"]["degree"] = degree
    ref = spec["fitted"]["powers_"]
    powers = np.load(io.BytesIO(parts[ref["array"]]))
    powers[-1] = row
    parts[ref["array"]] = npy(powers)


@pytest.mark.parametrize("degree", [10**8, 3000])
def test_a_huge_degree_is_refused_before_anything_is_built(valid, monkeypatch, degree):
    # Issue 32: degree 10**8 (a 2 KB file) reached 2.4 GB; degree 3000 made
    # `show` run for minutes.
    data = with_parts(valid, lambda m, p: set_powers_row(m, p, degree, [0, degree]))
    peak, _ = measured_refusal(data, monkeypatch,
                               f"degree={degree} needs at least {degree} basis functions")
    assert peak < 2 * 2**20


def test_powers_must_be_the_index_set_of_the_parameters(valid):
    # One row of degree 4 replaced in a degree-3 model given degree=4 ...
    data = with_parts(valid, lambda m, p: set_powers_row(m, p, 4, [0, 4]))
    refused(data, r"powers_ lacks \[.*\], which these parameters include")
    # ... and the parameters of another space.
    refused(with_manifest(valid, lambda m: regressor_spec(m)["params"].update(separable=True)),
            r"powers_ holds \[.*\], which these parameters exclude")


def test_unsigned_powers_are_refused(valid):
    # Issue 32: uint64 powers with 2**63 bypassed the degree check.
    powers = load(io.BytesIO(valid))[-1].powers_.astype(np.uint64)
    powers[-1] = [2**63, 0]
    refused(swap_array(valid, "powers_", powers),
            "powers_ must be a 2-D integer array of dtype int64; the file declares dtype uint64")
    # Narrower signed integers (written on 32-bit systems) convert exactly.
    narrow = load(io.BytesIO(swap_array(
        valid, "powers_", load(io.BytesIO(valid))[-1].powers_.astype(np.int32))))
    assert narrow[-1].powers_.dtype == np.int64


@pytest.mark.parametrize("key,value,match", [
    ("time_scale_", -1.0, "time_scale_ must be a positive float"),
    ("time_scale_", {"float": "nan"}, "time_scale_ is NaN"),
    ("time_scale_", {"float": "inf"}, r"time_scale_=inf does not fit the learned dynamics"),
    ("time_scale_", 1e-9, r"time_scale_=1e-09 does not fit the learned dynamics"),
    ("dt_", 1e-300, r"dt_=1e-300 does not fit the learned dynamics"),
    ("dt_", 0.0, "dt_ must be a positive finite float, or NaN"),
    ("dt_", {"float": "inf"}, "dt_ must be a positive finite float, or NaN"),
    ("rank_", 10**6, "rank_=1000000 exceeds the 10 unknowns"),
    ("n_features_in_", 10**9, r"declares shape \(\d+,?\), expected \(500000000,\)"),
])
def test_loaded_scalars_are_checked(valid, key, value, match):
    def change(manifest):
        regressor_spec(manifest)["fitted"][key] = value

    refused(with_manifest(valid, change), match)


def test_json_1e999_time_scale_is_refused(valid):
    # What a hand-edited manifest holds: 1e999, which Python's json reads as inf.
    parts = members(valid)
    text = parts["manifest.json"].decode()
    manifest = json.loads(text)
    old = json.dumps(regressor_spec(manifest)["fitted"]["time_scale_"])
    assert text.count(f'"time_scale_": {old}') == 1
    parts["manifest.json"] = text.replace(f'"time_scale_": {old}', '"time_scale_": 1e999')
    refused(rebuild(parts), "time_scale_=inf does not fit the learned dynamics")


def test_a_model_without_dynamics_keeps_an_infinite_time_scale():
    # H = p**2 / 2 (dp/dt = 0, dq/dt = p): the Jacobian is nilpotent, its
    # eigenvalues vanish, and the fit's time_scale_ is inf: a valid file.
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(200, 2))
    model = HamiltonianRegressor(degree=2, threshold=0.5).fit(
        X, np.column_stack([np.zeros(200), X[:, 0]]))
    assert model.time_scale_ == np.inf
    buffer = io.BytesIO()
    save(model, buffer)
    assert load(io.BytesIO(buffer.getvalue())).time_scale_ == np.inf


def test_the_command_refuses_a_bad_step_in_one_line(valid, tmp_path, capsys):
    # Issue 32: dt_ = 1e-300 gave a traceback in `sk-hamiltonian simulate`.
    from sk_hamiltonian.__main__ import main

    path = tmp_path / "model.skh"
    path.write_bytes(with_manifest(
        valid, lambda m: regressor_spec(m)["fitted"].update(dt_=1e-300)))
    with pytest.raises(SystemExit) as info:
        main(["simulate", str(path), "--x0", "0", "0", "--t-end", "1",
              "-o", str(tmp_path / "run.csv")])
    err = capsys.readouterr().err
    assert info.value.code == 2 and err.count("\n") == 1
    assert "dt_=1e-300 does not fit the learned dynamics" in err


def test_show_escapes_control_characters(valid, tmp_path, capsys):
    # Issue 32: provenance strings with terminal escapes were printed raw.
    from sk_hamiltonian.__main__ import main

    hostile = "\x1b[2J\x1b]0;owned\x07\u202etxt.exe\r"
    model = load(io.BytesIO(valid))
    model[-1].feature_names_in_ = np.array([f"p{hostile}", "q"], dtype=object)
    path = tmp_path / "model.skh"
    save(model, path, provenance={f"note{hostile}": hostile, "list": [hostile]})
    assert main(["show", str(path)]) == 0
    out = capsys.readouterr().out
    assert not any(c in out for c in "\x1b\x07\u202e\r"), out
    assert r"\x1b[2J\x1b]0;owned\x07\u202etxt.exe\r" in out
    assert r"note\x1b[2J" in out and r"p\x1b[2J" in out


def test_a_hostile_version_string_is_escaped_in_the_message(valid):
    def change(manifest):
        manifest["format_version"] = 99
        manifest["package_version"] = "9\x1b[31m"

    message = refused(with_manifest(valid, change), "upgrade|Upgrade")
    assert "\x1b" not in message and r"9\x1b[31m" in message


def test_sizes_are_checked_before_any_array_is_read(valid, monkeypatch):
    from sk_hamiltonian import _io_zip

    read = []
    monkeypatch.setattr(_io_zip.Container, "read_array",
                        lambda self, name, *args: read.append(name))

    def more_terms(manifest):
        regressor_spec(manifest)["fitted"]["powers_"]["shape"] = [10**6, 2]

    refused(with_manifest(valid, more_terms), r"coef_ declares shape \(9,\), expected \(1000000,\)")
    assert read == []


# ---------------------------------------------- structured mutations, bounded
#: Arrays of the regressor, where they sit in its manifest entry.
ARRAYS = {"coef_": "fitted", "powers_": "fitted", "periodic_": "fitted", "domain_": "fitted",
          "damping_": "fitted", "state_scale_": "fitted", "support_": "fitted",
          "_state_magnitude": "private"}
#: Values of scalars that a fitted model of the valid file cannot hold.
BAD_SCALARS = {
    ("fitted", "n_features_in_"): [0, -2, 1, 3, 4, 10**9, 2.0, True, "2", None],
    ("fitted", "time_scale_"): [-1.0, 0.0, 1e-9, 1e30, {"float": "inf"}, {"float": "nan"}, "1"],
    ("fitted", "dt_"): [-0.02, 0.0, 1e-300, 1e300, {"float": "inf"}, [0.02]],
    ("fitted", "rank_"): [-1, 10**6, 1.0],
    ("fitted", "n_terms_"): [-1, 10**6],
    ("fitted", "solver_"): ["pickle", 1],
    ("params", "degree"): [0, 2, 4, 10**8, 3000, -1, 3.0, "3", {"scalar": 3.0, "dtype": "<f8"}],
    ("params", "momentum_degree"): [0, 1, -1],
    ("params", "separable"): [True, 1],
    ("params", "max_interaction"): [1, 0],
    ("params", "periodic"): [[True, False], [True]],
    ("params", "domain"): [[[-1, 1], [-1, 1]], [[0, 1]]],
    ("params", "damping"): [False],
}
DTYPES = ["<u8", "<i4", "<f4", "|b1", "<f2", ">f8", "<i8", "<f8", "<c16", "|O", "|V8", "<U4"]


@st.composite
def mutations(draw):
    kind = draw(st.sampled_from(["shape", "dtype", "content", "reference", "size", "scalar"]))
    if kind == "scalar":
        where = draw(st.sampled_from(sorted(BAD_SCALARS)))
        return kind, where, draw(st.sampled_from(BAD_SCALARS[where]))
    target = draw(st.sampled_from(sorted(ARRAYS)))
    if kind == "shape":
        how = draw(st.sampled_from(["plus", "times", "append", "drop", "huge"]))
        return kind, target, (how, draw(st.integers(1, 6)))
    if kind == "dtype":
        return kind, target, draw(st.sampled_from(DTYPES))
    if kind == "content":
        return kind, target, draw(st.sampled_from(["nan", "inf", "negative", "uint"]))
    if kind == "reference":
        return kind, target, draw(st.sampled_from(["duplicate", "missing", "unknown", "other"]))
    return kind, target, draw(st.sampled_from(["append", "truncate", "inflate"]))


def mutate(valid, mutation):
    """``valid`` changed by ``mutation`` so that it is no valid model file."""
    kind, target, how = mutation
    parts = members(valid)
    manifest = json.loads(parts["manifest.json"])
    spec = regressor_spec(manifest)
    if kind == "scalar":
        section, key = target
        spec[section][key] = how
        parts["manifest.json"] = json.dumps(manifest)
        return rebuild(parts)
    ref = spec[ARRAYS[target]][target]
    array = np.load(io.BytesIO(parts[ref["array"]]))
    if kind == "shape":
        shape, (change, k) = list(ref["shape"]), how
        if change == "plus":
            shape[0] += k
        elif change == "times":
            shape[-1] *= k + 1
        elif change == "append":
            shape.append(k)
        elif change == "drop":
            shape = shape[:-1] if len(shape) > 1 else []
        else:
            shape[0] = 10 ** (6 + k)
        ref["shape"] = shape
    elif kind == "dtype":
        ref["dtype"] = how if how != ref["dtype"] else "<c8"
    elif kind == "content":
        if how == "uint" or array.dtype.kind != "f":
            values = (array.astype(np.uint64) + np.uint64(2**63))
        else:
            values = array.copy()
            values.flat[-1] = {"nan": np.nan, "inf": np.inf, "negative": -1.0}[how]
            if how == "negative" and target in ("coef_", "domain_"):
                values.flat[-1] = np.nan  # a negative coefficient or bound can be valid
        parts[ref["array"]] = npy(values)
        ref["dtype"] = values.dtype.str
    elif kind == "reference":
        others = [spec[ARRAYS[name]][name]["array"] for name in ARRAYS if name != target]
        if how == "duplicate":
            ref["array"] = others[0]
        elif how == "missing":
            ref["array"] = "arrays/0777.npy"
        elif how == "unknown":
            spec["fitted"]["extra_"] = dict(ref)
        else:  # an unlisted member under its own name, besides the listed ones
            parts["arrays/0778.npy"] = npy(array)
    else:
        data = parts[ref["array"]]
        parts[ref["array"]] = {"append": data + b"\0" * 64, "truncate": data[:-8],
                               "inflate": data + b"\0" * 8 * 2**20}[how]
    parts["manifest.json"] = json.dumps(manifest)
    return rebuild(parts)


@FUZZ
@given(mutation=mutations())
def test_structured_mutations_are_refused_within_bounds(valid, monkeypatch, mutation):
    data = mutate(valid, mutation)
    peak, read = measured_refusal(data, monkeypatch)
    legit = sum(len(v) for v in members(valid).values())
    # Nothing beyond the valid file's own members is ever read, and the
    # memory stays that of a small model.
    assert read <= legit, (mutation, read, legit)
    assert peak < 4 * 2**20, (mutation, peak)


@pytest.mark.parametrize("cls,n_states,degree", [
    (HamiltonianRegressor, 4, 8), (VectorFieldRegressor, 4, 8), (HamiltonianRegressor, 8, 4),
])
def test_loading_costs_a_first_prediction_and_a_few_times_the_arrays(cls, n_states, degree,
                                                                     monkeypatch):
    import tracemalloc

    import sk_hamiltonian.io as model_io

    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(1000, n_states))
    model = cls(degree=degree).fit(X, rng.normal(size=X.shape))
    buffer = io.BytesIO()
    save(model, buffer)
    data = buffer.getvalue()
    arrays = sum(len(v) for k, v in members(data).items() if k != "manifest.json")

    def peak(action):
        tracemalloc.start()
        try:
            action()
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    loading = peak(lambda: load(io.BytesIO(data)))
    # What any use of the model costs: the first prediction of one state, on
    # a model loaded without the probes of its dynamics.
    monkeypatch.setattr(model_io, "check_dynamics", lambda *args: None)
    fresh = load(io.BytesIO(data))
    predicting = peak(lambda: fresh.predict(X[:1]))
    assert loading <= predicting + 6 * arrays + 2**18, (loading, predicting, arrays)
