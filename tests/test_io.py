"""Model files: exact round trips of every estimator, model space and pipeline."""

import json
import warnings
import zipfile

import numpy as np
import pytest
from sklearn.pipeline import Pipeline, make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    ModelFileError,
    VectorFieldRegressor,
    load,
    save,
)
from sk_hamiltonian.datasets import make_trajectories
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.io import read_manifest


@pytest.fixture(scope="module")
def pendulum():
    return make_trajectories("single_pendulum", 30, 30, 0.02, noise=0.01, random_state=3)


@pytest.fixture(scope="module")
def two_dof():
    return make_trajectories("henon_heiles", 40, 12, 0.02, random_state=1)


def fitted(estimator, X):
    with warnings.catch_warnings():
        # Conservation and domain warnings of small fits are not the subject here.
        warnings.simplefilter("ignore")
        return estimator.fit(X)


def round_trip(model, tmp_path, **kwargs):
    path = tmp_path / "model.skh"
    save(model, path, **kwargs)
    return load(path)


def assert_same_fitted_state(a, b):
    """Every public fitted attribute equal, bit for bit, with its dtype."""
    attrs_a = {k: v for k, v in vars(a).items() if k.endswith("_") and not k.startswith("_")}
    attrs_b = {k: v for k, v in vars(b).items() if k.endswith("_") and not k.startswith("_")}
    assert attrs_a.keys() == attrs_b.keys()
    for key, value in attrs_a.items():
        other = attrs_b[key]
        if isinstance(value, np.ndarray):
            assert other.dtype == value.dtype and other.shape == value.shape, key
            assert np.array_equal(value, other, equal_nan=value.dtype.kind == "f"), key
        elif isinstance(value, float) and np.isnan(value):
            assert np.isnan(other), key
        else:
            assert value == other and type(value)(other) == value, key
    assert a.get_params(deep=False).keys() == b.get_params(deep=False).keys()


def assert_same_behaviour(model, loaded, X, x0, methods):
    assert_same_fitted_state(model, loaded)
    # The private state is rebuilt, not saved: this is what it must reproduce.
    assert np.array_equal(loaded._state_magnitude, model._state_magnitude)
    states = X.reshape(-1, X.shape[-1])[:50]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert np.array_equal(model.predict(states), loaded.predict(states))
        if hasattr(model, "hamiltonian"):
            assert np.array_equal(model.hamiltonian(states), loaded.hamiltonian(states))
            assert np.array_equal(model.gradient(states), loaded.gradient(states))
        t = np.linspace(0, 1, 11)
        for method in methods:
            a = model.simulate(x0, t, method=method)
            b = loaded.simulate(x0, t, method=method)
            assert np.array_equal(a, b), method


SPACES = [
    dict(degree=4),
    dict(degree=4, periodic=[False, True]),
    dict(degree=4, momentum_degree=2),
    dict(degree=4, separable=True),
    dict(degree=3, max_interaction=1),
    dict(degree=4, domain=[[-4.0, 4.0], [-2.0, 2.0]]),
    dict(degree=6, threshold=0.01),
    dict(degree=5, periodic=[False, True], separable=True, threshold=0.03),
    dict(degree=4, solver="sketch"),  # solver_ is checked on loading
]


@pytest.mark.parametrize("space", SPACES, ids=lambda s: ",".join(map(str, s)))
@pytest.mark.parametrize("damping", [False, True])
def test_hamiltonian_round_trip_is_exact(tmp_path, pendulum, space, damping):
    pipe = fitted(
        make_pipeline(DerivativeTransformer(dt=0.02, method="finite_difference"),
                      HamiltonianRegressor(damping=damping, **space)), pendulum,
    )
    loaded = round_trip(pipe, tmp_path)
    assert isinstance(loaded, Pipeline) and [n for n, _ in loaded.steps] == [
        n for n, _ in pipe.steps]
    assert_same_fitted_state(pipe[0], loaded[0])
    # The explicit symplectic methods need a separable model without friction.
    explicit = space.get("separable") and not pipe[-1].damping_.any()
    methods = ["rk4", "avf"] + (["leapfrog", "yoshida4"] if explicit else [])
    assert_same_behaviour(pipe[-1], loaded[-1], pendulum, pendulum[0, 0], methods)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the explicit domain is smaller than the data
        assert np.array_equal(pipe.predict(pendulum), loaded.predict(pendulum))
        assert pipe.score(pendulum[:4]) == loaded.score(pendulum[:4])
    assert format_hamiltonian(pipe[-1]) == format_hamiltonian(loaded[-1])
    assert loaded.get_params()["hamiltonianregressor__damping"] is damping


@pytest.mark.parametrize("space", SPACES, ids=lambda s: ",".join(map(str, s)))
def test_vector_field_round_trip_is_exact(tmp_path, pendulum, space):
    pipe = fitted(
        make_pipeline(DerivativeTransformer(dt=0.02, method="finite_difference"),
                      VectorFieldRegressor(**space)), pendulum,
    )
    loaded = round_trip(pipe, tmp_path)
    assert_same_behaviour(pipe[-1], loaded[-1], pendulum, pendulum[0, 0], ["rk4", "avf"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the explicit domain is smaller than the data
        assert pipe.score(pendulum[:4]) == loaded.score(pendulum[:4])


@pytest.mark.parametrize("threshold", [0.0, 0.05])
@pytest.mark.parametrize("fit_on", ["derivatives", "steps", "simpson"])
@pytest.mark.parametrize("cls", [HamiltonianRegressor, VectorFieldRegressor])
def test_fit_targets_and_two_degrees_of_freedom(tmp_path, two_dof, cls, fit_on, threshold):
    pipe = fitted(
        make_pipeline(DerivativeTransformer(dt=0.02, method="finite_difference"),
                      cls(degree=3, fit_on=fit_on, threshold=threshold)), two_dof,
    )
    if threshold:
        assert pipe[-1].n_terms_ < pipe[-1].powers_.shape[0] * (
            1 if cls is HamiltonianRegressor else 4)  # the threshold dropped terms
    loaded = round_trip(pipe, tmp_path)
    methods = ["rk4"] + (["avf"] if cls is HamiltonianRegressor else [])
    assert_same_behaviour(pipe[-1], loaded[-1], two_dof, two_dof[:3, 0], methods)
    # The default integrator and step follow fit_on and dt_ after loading too.
    t = np.linspace(0, 0.5, 6)
    assert np.array_equal(pipe[-1].simulate(two_dof[0, 0], t),
                          loaded[-1].simulate(two_dof[0, 0], t))


def test_vector_field_on_plain_arrays_with_1d_target_and_feature_names(tmp_path):
    pd = pytest.importorskip("pandas")
    rng = np.random.default_rng(0)
    X = pd.DataFrame(rng.uniform(-1, 1, size=(80, 3)), columns=["a", "b", "c"])
    y = X["a"] * X["b"] - X["c"] ** 2
    model = VectorFieldRegressor(degree=2).fit(X, y)
    loaded = round_trip(model, tmp_path)
    assert loaded.coef_.ndim == 1
    assert list(loaded.feature_names_in_) == ["a", "b", "c"]
    assert np.isnan(loaded.time_scale_) and np.isnan(loaded.dt_)
    assert np.array_equal(model.predict(X), loaded.predict(X))
    with pytest.raises(ValueError, match="feature names"):
        loaded.predict(X[["c", "b", "a"]])


def test_unfitted_estimators_and_list_parameters_round_trip(tmp_path):
    model = HamiltonianRegressor(degree=5, domain=[[-1, 1], [-2, 2]], periodic=(False, True))
    loaded = round_trip(model, tmp_path)
    assert loaded.get_params() == model.get_params()
    assert isinstance(loaded.domain, list) and isinstance(loaded.periodic, tuple)
    assert not hasattr(loaded, "coef_")
    # Coupling groups of different sizes have no array form: saved item by item.
    groups = HamiltonianRegressor(couplings=[(0, 1, 2), (2, 3)])
    loaded = round_trip(groups, tmp_path)
    assert loaded.couplings == [(0, 1, 2), (2, 3)]
    transformer = round_trip(DerivativeTransformer(window=9, degree=3), tmp_path)
    assert transformer.get_params() == DerivativeTransformer(window=9, degree=3).get_params()


def test_derivative_transformer_transforms_identically(tmp_path, pendulum):
    transformer = DerivativeTransformer(dt=0.02, degree=4, window=11).fit(pendulum)
    loaded = round_trip(transformer, tmp_path)
    assert loaded.window_ == 11
    assert np.array_equal(transformer.transform(pendulum), loaded.transform(pendulum))


def test_manifest_records_versions_classes_and_provenance(tmp_path, pendulum):
    pipe = fitted(make_pipeline(DerivativeTransformer(dt=0.02), HamiltonianRegressor(4)),
                  pendulum)
    path = tmp_path / "m.skh"
    save(pipe, path, provenance={"data_shape": list(pendulum.shape), "fit_time": 0.5})
    manifest = read_manifest(path)
    assert manifest["format_version"] == 2  # lists, tuples and numpy scalars exactly
    assert manifest["package_version"] == __import__("sk_hamiltonian").__version__
    assert manifest["provenance"] == {"data_shape": [30, 31, 2], "fit_time": 0.5}
    assert set(manifest["written"]) == {"time", "numpy", "scikit-learn", "python"}
    classes = [step["model"]["class"] for step in manifest["model"]["steps"]]
    assert classes == ["DerivativeTransformer", "HamiltonianRegressor"]
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        assert names[0] == "manifest.json"
        assert all(name.startswith("arrays/") and name.endswith(".npy") for name in names[1:])
        assert json.loads(archive.read("manifest.json"))["format"] == "sk_hamiltonian.model"


def test_file_objects_work(tmp_path, pendulum):
    import io

    model = fitted(HamiltonianRegressor(3, fit_on="steps"),
                   DerivativeTransformer(dt=0.02).fit_transform(pendulum))
    buffer = io.BytesIO()
    save(model, buffer)
    buffer.seek(0)
    assert np.array_equal(load(buffer).coef_, model.coef_)


@pytest.mark.parametrize(
    "obj,message",
    [
        (Pipeline([("scale", __import__("sklearn.preprocessing").preprocessing.StandardScaler())]),
         "StandardScaler"),
        (object(), "model files hold HamiltonianRegressor"),
    ],
)
def test_save_refuses_other_types(tmp_path, obj, message):
    with pytest.raises(TypeError, match=message):
        save(obj, tmp_path / "x.skh")


def test_save_refuses_a_search_and_says_what_to_save(tmp_path, pendulum):
    from sklearn.model_selection import GridSearchCV

    search = GridSearchCV(make_pipeline(DerivativeTransformer(dt=0.02), HamiltonianRegressor()),
                          {"hamiltonianregressor__degree": [3]}, cv=2)
    with pytest.raises(TypeError, match="save its best_estimator_"):
        save(search, tmp_path / "x.skh")


def test_save_refuses_bad_provenance(tmp_path):
    with pytest.raises(TypeError, match="JSON-serializable"):
        save(HamiltonianRegressor(), tmp_path / "x.skh", provenance={"x": object()})
    with pytest.raises(TypeError, match="must be a dict"):
        save(HamiltonianRegressor(), tmp_path / "x.skh", provenance=[1])


def test_missing_file_and_directory(tmp_path):
    with pytest.raises(ModelFileError, match="file not found"):
        load(tmp_path / "absent.skh")
    with pytest.raises(ModelFileError, match="is a directory"):
        load(tmp_path)


def test_skops_round_trip_with_our_types_trusted(tmp_path, two_dof):
    sio = pytest.importorskip("skops.io")
    from sk_hamiltonian.io import SKOPS_TRUSTED

    for estimator in (HamiltonianRegressor(3, separable=True, damping=True),
                      VectorFieldRegressor(3, periodic=[False, False, True, True])):
        pipe = fitted(make_pipeline(DerivativeTransformer(dt=0.02), estimator), two_dof)
        pipe[-1].simulate(two_dof[0, 0], [0.0, 0.1])  # builds the cached contraction plans
        path = tmp_path / "model.skops"
        sio.dump(pipe, path)
        untrusted = sio.get_untrusted_types(file=path)
        assert set(untrusted) <= set(SKOPS_TRUSTED), set(untrusted) - set(SKOPS_TRUSTED)
        with pytest.raises(Exception, match="[Uu]ntrusted"):
            sio.load(path)  # skops refuses our types unless they are trusted
        loaded = sio.load(path, trusted=SKOPS_TRUSTED)
        t = np.linspace(0, 1, 11)
        assert np.array_equal(pipe.predict(two_dof[:3]), loaded.predict(two_dof[:3]))
        assert np.array_equal(pipe[-1].simulate(two_dof[0, 0], t),
                              loaded[-1].simulate(two_dof[0, 0], t))


def test_derivative_transformer_refuses_dataframe_output_clearly():
    transformer = DerivativeTransformer()
    assert transformer.set_output(transform="default") is transformer
    assert transformer.set_output() is transformer
    for kind in ("pandas", "polars"):
        with pytest.raises(ValueError, match="derivative layout.*unpack_derivatives"):
            transformer.set_output(transform=kind)
    pipe = make_pipeline(DerivativeTransformer(dt=0.1), HamiltonianRegressor())
    with pytest.raises(ValueError, match="DerivativeTransformer cannot output 'pandas'"):
        pipe.set_output(transform="pandas")


# ------------------------------------------------------------- exact parameters
def identical(a, b):
    """Same type and value, recursively (an ndarray: same dtype, shape and entries)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and bool(np.all(a == b))
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(identical(x, y) for x, y in zip(a, b))
    if isinstance(a, (float, np.floating)) and np.isnan(a):
        return bool(np.isnan(b))
    return bool(a == b)


def assert_identical_params(model, loaded):
    original, back = model.get_params(deep=False), loaded.get_params(deep=False)
    assert original.keys() == back.keys()
    for key, value in original.items():
        if key != "steps":
            assert identical(value, back[key]), (key, value, back[key])


#: (parameter, values of different types) that fit accepts on the pendulum.
REGRESSOR_PARAMS = [
    ("degree", [4, np.int64(4), np.int32(4), np.uint8(4)]),
    ("domain", [
        [[-4, 4], [-3, 3]], ((-4, 4), (-3, 3)), [[-4.0, 4], [-3, 3.5]],
        [(np.float64(-4), 4), (-3, np.int64(3))], [np.array([-4.0, 4.0]), np.array([-3, 3])],
        np.array([[-4, 4], [-3, 3]]), np.array([[-4, 4], [-3, 3]], dtype=np.float32),
    ]),
    ("periodic", [[False, True], (0, 1), np.array([False, True]), [np.False_, np.True_]]),
    ("momentum_degree", [2, np.int16(2)]),
    ("separable", [True, np.True_]),
    ("max_interaction", [1, np.int64(1)]),
    ("couplings", [[(0, 1)], [[0, 1]], ((0, 1),), np.array([[0, 1]]), [np.array([0, 1])]]),
    ("fit_on", ["steps", np.str_("simpson")]),
    ("threshold", [0.01, 0, np.float32(0.01), np.float64(0.01), np.int64(0)]),
    ("solver", ["normal", np.str_("lstsq")]),
    ("verbose", [0, False, np.int64(0)]),
]
CASES = [
    (cls, name, value)
    for cls in (HamiltonianRegressor, VectorFieldRegressor)
    for name, values in REGRESSOR_PARAMS + ([("damping", [True, np.True_])]
                                            if cls is HamiltonianRegressor else [])
    for value in values
]


@pytest.mark.parametrize(
    "cls,name,value", CASES,
    ids=[f"{c.__name__[:3]}-{n}-{type(v).__name__}{k}" for k, (c, n, v) in enumerate(CASES)],
)
def test_every_parameter_type_fit_accepts_round_trips_exactly(tmp_path, pendulum, cls, name,
                                                              value):
    pipe = fitted(make_pipeline(DerivativeTransformer(dt=0.02, method="finite_difference"),
                                cls(**{"degree": 3, name: value})), pendulum)
    loaded = round_trip(pipe, tmp_path)
    assert_identical_params(pipe[-1], loaded[-1])
    assert_same_fitted_state(pipe[-1], loaded[-1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an explicit domain smaller than the data
        assert np.array_equal(pipe.predict(pendulum[:3]), loaded.predict(pendulum[:3]))


@pytest.mark.parametrize("params", [
    dict(dt=np.float32(0.02)), dict(dt=np.float64(0.02)), dict(dt=1),
    dict(degree=np.int64(3), window=np.int64(9)), dict(window=9, smooth_states=np.True_),
    dict(method=np.str_("finite_difference")),
])
def test_derivative_transformer_parameter_types_round_trip_exactly(tmp_path, pendulum, params):
    transformer = DerivativeTransformer(**{"dt": 0.02, **params}).fit(pendulum)
    loaded = round_trip(transformer, tmp_path)
    assert_identical_params(transformer, loaded)
    assert loaded.window_ == transformer.window_
    assert np.array_equal(transformer.transform(pendulum), loaded.transform(pendulum))


def test_pipeline_parameters_round_trip_exactly(tmp_path):
    for pipe in (make_pipeline(DerivativeTransformer(), HamiltonianRegressor(), verbose=np.False_),
                 Pipeline([("h", HamiltonianRegressor())], transform_input=["x"])):
        loaded = round_trip(pipe, tmp_path)
        assert_identical_params(pipe, loaded)


@pytest.mark.parametrize("dtype", [np.float32, np.int64])
def test_fitted_arrays_are_float64_whatever_the_input_dtype(tmp_path, dtype):
    rng = np.random.default_rng(0)
    X = (rng.uniform(-1, 1, size=(200, 2)) * 10).astype(dtype)
    y = np.column_stack([-X[:, 1], X[:, 0]]).astype(np.float64)
    for model in (HamiltonianRegressor(degree=2), VectorFieldRegressor(degree=2),
                  HamiltonianRegressor(degree=2, domain=np.array([[-10, 10], [-10, 10]]))):
        model.fit(X, y)
        for key in ("domain_", "state_scale_", "coef_"):
            assert getattr(model, key).dtype == np.float64, (key, model)
        assert model._state_magnitude.dtype == np.float64
        assert model.powers_.dtype == np.int64
        assert_same_fitted_state(model, round_trip(model, tmp_path))


def test_a_file_of_format_1_with_an_integer_domain_loads(tmp_path, pendulum):
    # Format 1 saved domain_ as int64 when `domain` was given as integers,
    # and could not load it back; it loads now, converted exactly.
    model = fitted(make_pipeline(DerivativeTransformer(dt=0.02),
                                 HamiltonianRegressor(3, domain=[[-4, 4], [-3, 3]])), pendulum)
    path = tmp_path / "m.skh"
    save(model, path)
    with zipfile.ZipFile(path) as archive:
        parts = {name: archive.read(name) for name in archive.namelist()}
    manifest = json.loads(parts["manifest.json"])
    manifest["format_version"] = 1
    ref = manifest["model"]["steps"][1]["model"]["fitted"]["domain_"]
    buffer = __import__("io").BytesIO()
    np.save(buffer, model[-1].domain_.astype(np.int64))
    parts[ref["array"]], ref["dtype"] = buffer.getvalue(), "<i8"
    parts["manifest.json"] = json.dumps(manifest)
    with zipfile.ZipFile(path, "w") as archive:
        for name, content in parts.items():
            archive.writestr(name, content)
    loaded = load(path)
    assert loaded[-1].domain_.dtype == np.float64
    assert np.array_equal(loaded[-1].domain_, [[-4.0, 4.0], [-3.0, 3.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert np.array_equal(loaded.predict(pendulum[:2]), model.predict(pendulum[:2]))


def test_save_refuses_an_attribute_load_would_not_read(tmp_path):
    X = np.random.default_rng(0).uniform(-1, 1, size=(60, 2))
    model = VectorFieldRegressor(degree=2).fit(X, X[:, ::-1])
    model.note_ = "fitted on Tuesday"
    with pytest.raises(TypeError, match="note_ are not fitted values a VectorFieldRegressor "
                                        "has .* keep such notes in provenance"):
        save(model, tmp_path / "m.skh")
    assert not (tmp_path / "m.skh").exists()


# ------------------------------------------------------------------ atomic saves
@pytest.fixture(scope="module")
def two_models():
    X = np.random.default_rng(0).uniform(-1, 1, size=(60, 2))
    return (VectorFieldRegressor(degree=1).fit(X, X[:, ::-1]),
            VectorFieldRegressor(degree=3).fit(X, X[:, ::-1] ** 2))


def fail_on_second_member(monkeypatch, error):
    """Make the writer raise ``error`` after the manifest and one array are written."""
    from sk_hamiltonian import _io_zip

    written = []
    original = _io_zip._write_member

    def write_member(archive, name, array):
        if written:
            raise error
        written.append(name)
        original(archive, name, array)

    monkeypatch.setattr(_io_zip, "_write_member", write_member)


@pytest.mark.parametrize("error", [
    RuntimeError("injected"), KeyboardInterrupt(), OSError(28, "No space left on device"),
], ids=["error", "interrupt", "disk-full"])
def test_a_failed_save_leaves_the_previous_file_and_nothing_else(tmp_path, monkeypatch,
                                                                 two_models, error):
    old, new = two_models
    path = tmp_path / "model.skh"
    save(old, path)
    before = path.read_bytes()
    fail_on_second_member(monkeypatch, error)
    with pytest.raises(type(error)):
        save(new, path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.skh"]
    assert np.array_equal(load(path).coef_, old.coef_)
    # Without a previous file, a failed save leaves none.
    with pytest.raises(type(error)):
        save(new, tmp_path / "fresh.skh")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.skh"]


def test_a_killed_save_leaves_the_previous_file(tmp_path, two_models):
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    old, _ = two_models
    path = tmp_path / "model.skh"
    save(old, path)
    before = path.read_bytes()
    marker = tmp_path / "writing"
    script = f"""
import time, numpy as np
from sk_hamiltonian import VectorFieldRegressor, save, _io_zip
X = np.random.default_rng(1).uniform(-1, 1, size=(60, 2))
model = VectorFieldRegressor(degree=3).fit(X, X[:, ::-1])
original = _io_zip._write_member
def write_member(archive, name, array):
    original(archive, name, array)
    open({str(marker)!r}, "w").close()  # half written: now kill me
    time.sleep(600)
_io_zip._write_member = write_member
save(model, {str(path)!r})
"""
    root = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(root)] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])))
    process = subprocess.Popen([sys.executable, "-c", script], env=env,
                               stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120  # a wait, not a timing assertion
        while not marker.exists() and process.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert marker.exists(), process.stderr.read() if process.poll() is not None else ""
        process.send_signal(signal.SIGKILL)
    finally:
        process.kill()
        process.wait()
    assert path.read_bytes() == before
    assert np.array_equal(load(path).coef_, old.coef_)
    # What a killed save can leave: its hidden temporary file, never a partial model.skh.
    leftovers = {p.name for p in tmp_path.iterdir()} - {"model.skh", "writing"}
    assert all(name.startswith(".model.skh.") and name.endswith(".tmp") for name in leftovers)


def test_save_replaces_keeping_the_permissions_and_writes_through_a_link(tmp_path, two_models):
    import os
    import stat

    old, new = two_models
    path = tmp_path / "model.skh"
    save(old, path)
    os.chmod(path, 0o640)
    link = tmp_path / "link.skh"
    link.symlink_to(path)
    save(new, link)
    assert link.is_symlink()
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o640
    assert np.array_equal(load(path).coef_, new.coef_)


def test_save_into_a_missing_folder_names_the_file(tmp_path, two_models):
    target = tmp_path / "absent" / "model.skh"
    with pytest.raises(FileNotFoundError) as info:
        save(two_models[0], target)
    assert info.value.filename == str(target)
