"""The compiled (numba) kernels against the numpy path, and the kernels switch."""

import os
import warnings

import numpy as np
import pytest

import sk_hamiltonian
from sk_hamiltonian import config_context, get_config, set_config
from sk_hamiltonian._numba import numba_available
from sk_hamiltonian._space import ModelSpace, index_set

# The process-wide default (SK_HAMILTONIAN_KERNELS may set it for a whole run).
DEFAULT = get_config()["kernels"]

needs_numba = pytest.mark.skipif(
    not numba_available(), reason="numba is not installed (pip install sk_hamiltonian[fast])"
)

# (n_states, degree, periodic, constraints): every family and index-set kind.
SPACES = [
    (2, 6, [False, False], {}),
    (4, 5, [False] * 4, {}),
    (4, 4, [False, False, True, True], {}),
    (2, 3, [True, True], {}),
    (4, 6, [False, False, True, True], {"momentum_degree": 2}),
    (6, 3, [False] * 6, {"separable": True, "max_interaction": 2}),
    (1, 7, [False], {}),
    (3, 4, [True, False, True], {"include_constant": True}),
    # Mixed coordinates: Legendre and Fourier columns in one table.
    (2, 5, [False, False], {"mixed": [False, True]}),
    (4, 4, [False, False, True, False], {"mixed": [False, False, False, True],
                                         "momentum_degree": 2}),
]


def _space(n_states, degree, periodic, constraints):
    domain = np.column_stack([-1.5 * np.ones(n_states), np.linspace(1.0, 2.0, n_states)])
    powers = index_set(n_states, degree, periodic=np.array(periodic), **constraints)
    return ModelSpace(domain, powers, np.array(periodic), constraints.get("mixed"))


def _states(space, n, seed=0):
    rng = np.random.default_rng(seed)
    low, high = space.domain.T
    # Slightly beyond the box too: the compiled tables must extrapolate as numpy's do.
    return rng.uniform(low - 0.1 * (high - low), high + 0.1 * (high - low), size=(n, space.n_states))


def test_config_default_and_choices():
    # memory_limit (issue 32) is the other key; tests/test_sizes.py checks it.
    assert get_config() == {"kernels": DEFAULT, "memory_limit": "auto"}
    assert DEFAULT == os.environ.get("SK_HAMILTONIAN_KERNELS", "auto")
    with pytest.raises(ValueError, match="kernels must be one of"):
        set_config(kernels="fortran")
    with config_context(kernels="numpy"):
        assert get_config()["kernels"] == "numpy"
        with pytest.raises(ValueError, match="kernels must be one of"):
            with config_context(kernels="cuda"):
                pass  # pragma: no cover
        assert get_config()["kernels"] == "numpy"
    assert get_config()["kernels"] == DEFAULT
    assert sk_hamiltonian.set_config is set_config


def test_numba_choice_without_numba_says_how_to_install(monkeypatch):
    monkeypatch.setattr(sk_hamiltonian._numba, "_NUMBA", False)
    with pytest.raises(ImportError, match=r"sk_hamiltonian\[fast\]"):
        set_config(kernels="numba")
    assert get_config()["kernels"] == DEFAULT
    # "auto" then quietly means numpy.
    from sk_hamiltonian._config import use_numba

    assert not use_numba()


def test_config_context_restores_on_error():
    with pytest.raises(RuntimeError):
        with config_context(kernels="numpy"):
            raise RuntimeError("boom")
    assert get_config()["kernels"] == DEFAULT


@needs_numba
@pytest.mark.parametrize("periodic", [False, True])
def test_contractions_agree_on_a_set_with_holes(periodic):
    # The compiled tree numbers each level's nodes by their largest child
    # and skips the columns a node lacks; a random subset of terms (a sparse
    # model's, not downward closed) leaves holes below the largest ones.
    space = _space(4, 8, [False, False, periodic, periodic], {})
    keep = np.random.default_rng(3).random(space.n_terms) < 0.6
    space = ModelSpace(space.domain, space.powers[keep], space.periodic)
    assert space._flat(1, kernels="numba", n_samples=50) is None  # the tree, not flat products
    X = _states(space, 50)
    coef = np.random.default_rng(4).standard_normal(space.n_terms)
    results = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            results[kernels] = [space.value_dot(X, coef), space.gradient_dot(X, coef),
                                space.hessian_dot(X, coef)]
    for a, b in zip(results["numpy"], results["numba"]):
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max())


@needs_numba
@pytest.mark.parametrize("spec", SPACES, ids=lambda s: f"m{s[0]}n{s[1]}{s[3]}{sum(s[2])}p")
# 600 samples: split between threads on a machine with two cores or more.
@pytest.mark.parametrize("n_samples", [1, 5, 300, 600])
def test_contractions_agree(spec, n_samples):
    space = _space(*spec)
    X = _states(space, n_samples)
    rng = np.random.default_rng(1)
    coef = rng.standard_normal(space.n_terms)
    coef2 = rng.standard_normal((space.n_terms, 3))
    results = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            results[kernels] = [
                space.value_dot(X, coef), space.gradient_dot(X, coef), space.hessian_dot(X, coef),
                space.value_dot(X, coef2), space.gradient_dot(X, coef2),
            ]
    for a, b in zip(results["numpy"], results["numba"]):
        assert a.shape == b.shape
        scale = np.abs(a).max()
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * scale)


@needs_numba
# 3 states one at a time, 40 in lanes: each path caches its own binding.
@pytest.mark.parametrize("n_samples", [3, 40])
def test_coefficients_changed_in_place_are_seen(n_samples):
    space = _space(*SPACES[1])
    X = _states(space, n_samples)
    coef = np.ones(space.n_terms)
    with config_context(kernels="numba"):
        first = space.gradient_dot(X, coef)
        coef[5] = -4.0
        second = space.gradient_dot(X, coef)
    with config_context(kernels="numpy"):
        expected = space.gradient_dot(X, coef)
    assert not np.allclose(first, second)
    np.testing.assert_allclose(second, expected, rtol=1e-12, atol=1e-12)


def test_lanes_split_batches_into_equal_passes():
    from sk_hamiltonian._kernels import MAX_LANES
    from sk_hamiltonian._kernels import lanes as _lanes

    for n in [1, 15, 16, MAX_LANES, MAX_LANES + 1, 1000, 4 * MAX_LANES]:
        lanes = _lanes(n)
        n_passes = -(-n // lanes)
        assert lanes <= MAX_LANES and lanes % 8 == 0
        assert n_passes == -(-n // MAX_LANES)  # no more passes than needed
        assert n_passes * lanes - n < 8 * n_passes  # the last pass short by less than 8 per pass


def test_children_by_parent_groups_every_node_under_its_parent():
    from sk_hamiltonian._space.kernel_tree import children_by_parent, tree_arrays

    space = _space(*SPACES[4])
    tree, _ = tree_arrays(space)
    level_start, level_parent, node_counts = tree[6], tree[7], tree[9]
    child_order, child_start, child_offset = children_by_parent(tree)
    for L in range(node_counts.size - 1):
        parent = level_parent[level_start[L]:level_start[L + 1]]
        order = child_order[level_start[L]:level_start[L + 1]]
        starts = child_start[child_offset[L]:child_offset[L + 1]]
        assert np.array_equal(np.sort(order), np.arange(parent.size))
        assert starts[0] == 0 and starts[-1] == parent.size
        for P in range(node_counts[L + 1]):
            assert np.all(parent[order[starts[P]:starts[P + 1]]] == P)


@needs_numba
@pytest.mark.parametrize("spec", SPACES, ids=lambda s: f"m{s[0]}n{s[1]}{s[3]}{sum(s[2])}p")
def test_batches_in_lanes_agree(spec):
    # Around the batch sizes where the lanes start, fill a pass, and leave a
    # short last pass (257: two passes of 136 lanes, 15 of them repeats).
    from sk_hamiltonian._kernels import LANE_ROWS, MAX_LANES
    from sk_hamiltonian._space.compiled import _contract_in_lanes, in_lanes

    space = _space(*spec)
    coef = np.random.default_rng(2).standard_normal(space.n_terms)
    for n in [LANE_ROWS - 1, LANE_ROWS, MAX_LANES + 1]:
        X = _states(space, n, seed=n)
        results = {}
        for kernels in ("numpy", "numba"):
            with config_context(kernels=kernels):
                results[kernels] = [space.value_dot(X, coef), space.gradient_dot(X, coef),
                                    space.gradient_dot(X, coef[:, None])]
        # The lanes themselves, also on the spaces that take flat products
        # (a few terms): one variable (no level above the leaves), Fourier only.
        value, grad, _ = _contract_in_lanes(space, X, coef, 1)
        results["lanes"] = [value[:, 0], grad[:, :, 0], grad,
                            _contract_in_lanes(space, X, coef, 0)[0][:, 0]]
        results["numpy"].append(results["numpy"][0])
        for a, b in zip(results["numpy"], results["numba"]):
            assert a.shape == b.shape
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max())
        for a, b in zip(results["numpy"], results["lanes"]):
            assert a.shape == b.shape
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-12 * np.abs(a).max())
        expected = n >= LANE_ROWS and space._flat(1, kernels="numba") is None
        assert in_lanes(space, coef, 1, n) == expected


def test_one_variable_results_outlive_the_next_call():
    # The numpy contraction of a 1-D space once returned a view of its
    # workspace, which the next call overwrote.
    space = _space(*SPACES[6])
    X = _states(space, 300)
    coef = np.random.default_rng(1).standard_normal(space.n_terms)
    with config_context(kernels="numpy"):
        first = space.value_dot(X, coef)
        kept = first.copy()
        space.value_dot(X, 2 * coef)
    np.testing.assert_array_equal(first, kept)
    np.testing.assert_allclose(first, space.values(X) @ coef, rtol=1e-12, atol=1e-12)


def _fitted(kind, periodic=False, damping=False, separable=False):
    from sk_hamiltonian import HamiltonianRegressor, VectorFieldRegressor
    from sk_hamiltonian.datasets import load_system

    system = load_system("henon_heiles")
    rng = np.random.default_rng(3)
    X = rng.uniform(-0.5, 0.5, size=(400, 4))
    dX = system.vector_field(X)
    if damping:
        dX[:, :2] -= 0.05 * dX[:, 2:]
    domain = np.array([[-0.5, 0.5]] * 4)
    if kind == "value":
        return VectorFieldRegressor(degree=4, domain=domain).fit(X, dX)
    params = dict(degree=5, domain=domain, damping=damping, separable=separable)
    if periodic:
        params.update(periodic=[False, False, True, True], domain=np.array([[-0.5, 0.5]] * 2 + [[-np.pi, np.pi]] * 2))
    return HamiltonianRegressor(**params).fit(X, dX)


MODELS = {
    "hamiltonian": dict(kind="gradient"),
    "damped": dict(kind="gradient", damping=True),
    "separable": dict(kind="gradient", separable=True),
    "periodic": dict(kind="gradient", periodic=True),
    "vector_field": dict(kind="value"),
}


@needs_numba
@pytest.mark.filterwarnings("ignore::sk_hamiltonian.DomainWarning")
@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("method", ["rk4", "avf", "leapfrog", "yoshida4"])
def test_simulations_agree(name, method):
    model = _fitted(**MODELS[name])
    if method in ("leapfrog", "yoshida4") and name != "separable":
        with pytest.raises(ValueError, match="separable|damping"):
            model.simulate([0.1, 0.0, 0.2, -0.1], np.linspace(0, 1, 3), method=method)
        return
    x0 = np.array([[0.1, 0.0, 0.2, -0.1], [0.0, 0.2, -0.1, 0.3], [0.05, -0.1, 0.0, 0.1]])
    t = np.linspace(0, 3.0, 31)
    paths = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            paths[kernels] = model.simulate(x0, t, method=method, max_step=0.05)
    assert paths["numba"].shape == paths["numpy"].shape
    np.testing.assert_allclose(paths["numba"], paths["numpy"], rtol=0, atol=1e-11)


@needs_numba
@pytest.mark.filterwarnings("ignore::sk_hamiltonian.DomainWarning")
@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("n_samples", [1, 7, 600])
def test_predictions_agree(name, n_samples):
    # predict's compiled field applies the structure (and damping) itself.
    model = _fitted(**MODELS[name])
    X = np.random.default_rng(5).uniform(-0.55, 0.55, size=(n_samples, 4))
    results = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            results[kernels] = model.predict(X)
    scale = np.abs(results["numpy"]).max()
    np.testing.assert_allclose(results["numba"], results["numpy"], rtol=0, atol=1e-12 * scale)


@needs_numba
@pytest.mark.parametrize("method", ["rk4", "avf"])
def test_compiled_failure_matches_numpy(method):
    model = _fitted("gradient")
    x0 = np.array([[0.1, 0.0, 0.2, -0.1], [40.0, 0.0, 0.0, 0.0]])
    t = np.linspace(0, 50.0, 11)
    results = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            with pytest.raises(sk_hamiltonian.SimulationError) as info:
                model.simulate(x0, t, method=method, max_step=0.1)
            with pytest.warns(sk_hamiltonian.DomainWarning):
                paths = model.simulate(x0, t, method=method, max_step=0.1, on_failure="nan")
            results[kernels] = (info.value.failed_at, paths)
    np.testing.assert_array_equal(results["numba"][0], results["numpy"][0])
    assert results["numba"][0][0] == t.size and results["numba"][0][1] < t.size
    # NaN where the trajectory failed, the same states elsewhere.
    np.testing.assert_allclose(results["numba"][1], results["numpy"][1], rtol=0, atol=1e-9)


@needs_numba
@pytest.mark.filterwarnings("ignore::sk_hamiltonian.DomainWarning")
@pytest.mark.parametrize("name", ["periodic", "damped"])
def test_rk4_of_many_states_in_lanes_agrees(name, monkeypatch):
    # Enough states for the lanes, in one thread: the periodic model's 41 in
    # one pass of 48 lanes, wrapped; the damped model's 300 in two passes of
    # 152, three of them failing at different times in both passes (the
    # others must not notice).
    from sk_hamiltonian._kernels import LANE_ROWS, _lanes_jit

    calls = []
    rk4 = _lanes_jit.rk4
    monkeypatch.setattr(_lanes_jit, "rk4", lambda *args: calls.append(1) or rk4(*args))
    model = _fitted(**MODELS[name])
    x0 = np.random.default_rng(6).uniform(-0.3, 0.3, size=(41 if name == "periodic" else 300, 4))
    if name == "periodic":
        x0[:, 2:] += 3.0  # outside the period: wrapped at every output time
    else:
        x0[[3, 30, 200], 0] = [40.0, 25.0, 30.0]
    t = np.linspace(0, 5.0, 11)
    results = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            paths = model.simulate(x0, t, method="rk4", max_step=0.1, on_failure="nan")
            results[kernels] = (np.isnan(paths).any(axis=(1, 2)), paths)
    assert len(calls) == 1 and x0.shape[0] >= LANE_ROWS
    failed = results["numpy"][0]
    assert np.flatnonzero(failed).tolist() == ([] if name == "periodic" else [3, 30, 200])
    np.testing.assert_array_equal(results["numba"][0], failed)
    # Relative as well: the failing states reach thousands before they fail.
    np.testing.assert_allclose(results["numba"][1], results["numpy"][1], rtol=1e-12, atol=1e-11)
    if name == "periodic":
        low, high = model._space.domain[2:].T
        assert np.all((results["numba"][1][:, :, 2:] >= low) & (results["numba"][1][:, :, 2:] < high))


@needs_numba
def test_compiled_simulation_does_not_step_in_python(monkeypatch):
    from sk_hamiltonian._integrate import FixedStepIntegrator

    model = _fitted("gradient")

    def forbidden(self, y, h):
        raise AssertionError("stepped in Python")

    monkeypatch.setattr(FixedStepIntegrator, "step", forbidden)
    with config_context(kernels="numba"):
        path = model.simulate([0.1, 0.0, 0.2, -0.1], np.linspace(0, 1, 11), method="rk4")
    assert np.isfinite(path).all()
    with config_context(kernels="numpy"), pytest.raises(AssertionError, match="Python"):
        model.simulate([0.1, 0.0, 0.2, -0.1], np.linspace(0, 1, 11), method="rk4")


@needs_numba
@pytest.mark.filterwarnings("ignore::sk_hamiltonian.DomainWarning")
def test_many_initial_states_in_threads_agree():
    # Enough states and steps to run in one thread per core.
    model = _fitted("gradient", damping=True)
    x0 = np.random.default_rng(5).uniform(-0.2, 0.2, size=(40, 4))
    t = np.linspace(0, 20.0, 2001)
    with config_context(kernels="numpy"):
        expected = model.simulate(x0, t, method="rk4", max_step=0.01)
    with config_context(kernels="numba"):
        got = model.simulate(x0, t, method="rk4", max_step=0.01)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10)


def _blas_threads_now():
    from threadpoolctl import threadpool_info

    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


def test_limit_blas_small_work_runs_on_one_thread(monkeypatch):
    from sk_hamiltonian import _threads as threads

    before = _blas_threads_now()
    with threads.limit_blas(threads.PARALLEL_FLOPS / 10):
        assert all(n == 1 for n in _blas_threads_now())
    assert _blas_threads_now() == before
    with threads.limit_blas(threads.SERIAL_FLOPS * 10):
        assert _blas_threads_now() == before
    assert threads.blas_threads(threads.SERIAL_FLOPS * 10) is None
    assert threads.gram_flops(1000, 20) == 0.5 * 1000 * 20**2
    # Work in between: every core only while one is idle.
    middle = (threads.PARALLEL_FLOPS * threads.SERIAL_FLOPS) ** 0.5
    monkeypatch.setattr(threads, "idle_cores", lambda: 0.0)
    assert threads.blas_threads(middle) == 1
    with threads.limit_blas(middle):
        assert all(n == 1 for n in _blas_threads_now())
    monkeypatch.setattr(threads, "idle_cores", lambda: 1.0)
    assert threads.blas_threads(middle) is None
    assert threads.blas_threads(threads.PARALLEL_FLOPS / 10) == 1


def test_idle_cores_counts_other_processes_only():
    from sk_hamiltonian import _threads as threads

    idle = threads.idle_cores()
    # This process's own running threads (the test's) are not "others".
    assert idle <= (os.cpu_count() or 1) - 1
    assert threads._own_running_tasks() >= 1


def test_pack_keeps_every_item_at_its_offset_and_shape():
    from sk_hamiltonian._kernels.packing import SLOTS, pack

    items = [np.arange(6, dtype=np.int64).reshape(2, 3), np.linspace(0, 1, 4), 17,
             np.array([True, False, True]), np.arange(24.0).reshape(2, 3, 4),
             np.zeros((0, 2), dtype=np.int64), np.zeros((0, 1))]
    ints, floats = pack(items)
    assert ints.dtype == np.int64 and floats.dtype == np.float64
    for k, item in enumerate(items):
        offset, *dims = ints[SLOTS * k : SLOTS * (k + 1)]
        if isinstance(item, int):
            assert offset == item
            continue
        source = floats if item.dtype.kind == "f" else ints
        assert dims == list(item.shape) + [1] * (SLOTS - 1 - item.ndim)
        np.testing.assert_array_equal(source[offset : offset + item.size].reshape(item.shape), item)
    with pytest.raises(ValueError, match="at most 3"):
        pack([np.zeros((1, 1, 1, 1))])


def _checked_calls(monkeypatch):
    """Count the calls of the one-call kernel behind predict (it must be taken)."""
    from sk_hamiltonian._kernels import _checked_jit

    calls = []
    kernel = _checked_jit.checked_fields
    monkeypatch.setattr(_checked_jit, "checked_fields", lambda *a: calls.append(1) or kernel(*a))
    return calls


def _sparse_model():
    from sk_hamiltonian import HamiltonianRegressor

    rng = np.random.default_rng(4)
    X = rng.uniform(-1, 1, size=(300, 2))
    dX = np.column_stack([-X[:, 1] - 2 * X[:, 1] ** 3, X[:, 0]])  # H = p^2/2 + q^2/2 + q^4/2
    return HamiltonianRegressor(degree=6, threshold=0.01).fit(X, dX)


@needs_numba
@pytest.mark.parametrize("name", ["hamiltonian", "damped", "separable", "periodic", "sparse"])
@pytest.mark.parametrize("n_samples", [1, 7])
def test_one_call_prediction_is_the_compiled_field(name, n_samples, monkeypatch):
    # predict of a few states takes the one-call kernel, whose field is the
    # same compiled code as the general compiled path's: equal to the bit.
    from sk_hamiltonian._space import compiled

    model = _sparse_model() if name == "sparse" else _fitted(**MODELS[name])
    if name == "sparse":
        assert model.n_terms_ < model._space.n_terms  # kept terms only
    low, high = model.domain_.T
    X = np.random.default_rng(5).uniform(low, high, size=(n_samples, model.n_features_in_))
    calls = _checked_calls(monkeypatch)
    with config_context(kernels="numba"):
        got = model.predict(X)
        general = compiled.field(model._eval_space, X, model._eval_coef, model.damping_)
    with config_context(kernels="numpy"):
        expected = model.predict(X)
    assert len(calls) == 1  # packed at the first call, then computed
    np.testing.assert_array_equal(got, general)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


@needs_numba
def test_one_call_prediction_warns_and_raises_as_the_general_path(monkeypatch):
    model = _fitted(**MODELS["periodic"])
    calls = _checked_calls(monkeypatch)
    inside = np.array([[0.1, 0.0, 0.2, -0.1]])
    # Two of four states outside the box; the periodic angles never are.
    X = np.array([[0.1, 0.0, 9.0, -9.0], [0.7, 0.0, 0.0, 0.0], [0.0, -0.5, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 0.0]])
    X[2, 1] -= 1e-3
    messages = {}
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            with pytest.warns(sk_hamiltonian.DomainWarning) as record:
                model.predict(X)
            messages[kernels] = [str(w.message) for w in record]
            assert record[0].filename == __file__  # points at the caller
            with pytest.raises(ValueError, match="NaN"):
                model.predict(np.array([[0.1, np.nan, 0.0, 0.0]]))
            with pytest.raises(ValueError, match="infinity"):
                model.predict(np.array([[0.1, 0.0, np.inf, 0.0]]))
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                model.predict(inside)
    assert messages["numba"] == messages["numpy"]
    assert messages["numba"][0].startswith("50.0% of X lie outside the domain")
    # Every compiled prediction above took the one-call kernel once (the
    # states that are not finite: it said so, and the general path raised).
    assert len(calls) == 4


@needs_numba
def test_one_call_prediction_sees_coefficients_changed_in_place(monkeypatch):
    import pickle

    model = _fitted(**MODELS["damped"])
    X = np.array([[0.1, 0.0, 0.2, -0.1], [0.0, 0.2, -0.1, 0.3]])
    calls = _checked_calls(monkeypatch)
    results = []
    with config_context(kernels="numba"):
        results.append(model.predict(X))
        model.coef_[3] += 1.0
        results.append(model.predict(X))
        model.damping_[0] = 0.5
        results.append(model.predict(X))
        model.coef_[0] = np.nan  # a NaN coefficient equals itself: packed once, not forever
        results.append(model.predict(X))
        results.append(model.predict(X))
        again = pickle.loads(pickle.dumps(model))
        assert "_checked_kernel" not in again._space.__dict__
        results.append(again.predict(X))
    # Packed before the first call; after a change of the coefficients the
    # kernel says so and is called again, packed anew (the damping is read
    # at every call); the unpickled model packs its own.
    assert len(calls) == 1 + 2 + 1 + 2 + 1 + 1
    assert not np.allclose(results[0], results[1]) and not np.allclose(results[1], results[2])
    from sk_hamiltonian._space import compiled

    with config_context(kernels="numba"):
        general = compiled.field(model._eval_space, X, model._eval_coef, model.damping_)
    with config_context(kernels="numpy"):
        expected = model.predict(X)
    assert np.isnan(expected).any()
    for got in results[3:]:
        np.testing.assert_array_equal(got, general)
        np.testing.assert_allclose(got, expected, rtol=1e-14, atol=1e-14)  # NaN where numpy's are


@needs_numba
def test_other_inputs_and_hand_set_attributes_take_the_general_path(monkeypatch):
    # Not a plain C-ordered float64 array of a few states, or fitted
    # attributes of another shape than fit gave: no one-call kernel (it
    # does not check shapes), the same answers.
    model = _fitted(**MODELS["damped"])
    X = np.array([[0.1, 0.0, 0.2, -0.1], [0.0, 0.2, -0.1, 0.3]])
    with config_context(kernels="numba"):
        expected = model.predict(X)
        calls = _checked_calls(monkeypatch)
        for other in (np.asfortranarray(X), X.tolist(), X.astype(np.float32), np.tile(X, (8, 1))):
            got = model.predict(other)
            # float32 states: the field of the rounded states.
            np.testing.assert_allclose(got[:2], expected, rtol=1e-6)
        model.damping_ = np.append(model.damping_, 0.0)
        model.predict(X)
    assert calls == []
