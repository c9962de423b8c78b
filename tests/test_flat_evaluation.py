"""Evaluation cost follows the kept terms: exact companions and the flat contraction.

The flat contraction (``sk_hamiltonian/_space/flat.py``) replaces the prefix
tree for small spaces, on both kernel paths. Every test here compares it with
the tree (forced by the cost rule's overhead) or with the explicit products
of every basis function, to round-off.
"""

import warnings

import numpy as np
import pytest

import sk_hamiltonian
from sk_hamiltonian import HamiltonianRegressor, VectorFieldRegressor, config_context
from sk_hamiltonian._numba import numba_available
from sk_hamiltonian._space import ModelSpace, flat, index_set
from sk_hamiltonian._space.readable import ReadableBasis
from sk_hamiltonian.datasets import henon_heiles, single_pendulum

PATHS = ["numpy"] + (["numba"] if numba_available() else [])
FORCE = {"flat": 1e18, "tree": -1e18}

SPACES = [
    (4, 3, [False] * 4, {}),
    (2, 5, [False, True], {}),
    (3, 4, [True, False, False], {"include_constant": True}),
    (6, 3, [False] * 6, {"separable": True, "max_interaction": 2}),
    (1, 6, [False], {}),
]


def _space(n_states, degree, periodic, constraints, keep=0.4, seed=0):
    rng = np.random.default_rng(seed)
    powers = index_set(n_states, degree, periodic=np.array(periodic), **constraints)
    powers = powers[(rng.random(len(powers)) < keep) | (np.arange(len(powers)) == 0)]
    domain = np.column_stack([rng.uniform(-2, -0.5, n_states), rng.uniform(0.8, 2.5, n_states)])
    return ModelSpace(domain, powers, np.array(periodic))


def _states(space, n, seed=1):
    low, high = space.domain.T
    return np.random.default_rng(seed).uniform(low, high, size=(n, space.n_states))


def _forced(monkeypatch, mode):
    for kernels in flat.TREE_OVERHEAD:
        monkeypatch.setitem(flat.TREE_OVERHEAD, kernels, FORCE[mode])


def _reset(space):
    """Forget the space's plans and bindings (the cost rule is read when they are built)."""
    space._flat_plans.clear()
    space._bindings.clear()


# ------------------------------------------------------------- companions
def test_a_kept_monomial_brings_exactly_its_legendre_companions():
    # On a box that is not centred, x0**2 x1 is every P_a(x0) P_b(x1) with
    # a <= 2 and b <= 1 (but the constant), and nothing else: the inverse of
    # the triangular change of basis must not leave round-off above it.
    powers = index_set(2, 6)
    basis = ReadableBasis(powers, [[-1.7, 1.5], [-1.3, 1.4]], np.array([False, False]))
    column = np.flatnonzero((powers == [2, 1]).all(axis=1))[0]
    support = {tuple(p) for p in powers[basis.to_fitting[:, [column]].toarray()[:, 0] != 0]}
    assert support == {(a, b) for a in range(3) for b in range(2)} - {(0, 0)}


def test_a_cosine_on_a_period_from_minus_pi_is_one_fitting_function():
    powers = index_set(1, 4, periodic=np.array([True]))
    basis = ReadableBasis(powers, [[-np.pi, np.pi]], np.array([True]))
    cosine = np.flatnonzero(powers[:, 0] == 1)[0]
    nonzero = basis.to_fitting[:, [cosine]].toarray()[:, 0] != 0
    # cos(q) = -cos(q + pi): one function, no round-off sine.
    assert nonzero.sum() == 1 and powers[nonzero][0, 0] == 1


# --------------------------------------------------------- flat against tree
@pytest.mark.parametrize("kernels", PATHS)
@pytest.mark.parametrize("spec", SPACES, ids=lambda s: f"{s[0]}d-deg{s[1]}")
@pytest.mark.parametrize("targets", [None, 3])
@pytest.mark.parametrize("n_samples", [1, 7, 90])
def test_flat_and_tree_contractions_agree(monkeypatch, kernels, spec, targets, n_samples):
    space = _space(*spec)
    X = _states(space, n_samples)
    rng = np.random.default_rng(2)
    coef = rng.standard_normal(space.n_terms if targets is None else (space.n_terms, targets))
    results = {}
    for mode in FORCE:
        _forced(monkeypatch, mode)
        _reset(space)
        with config_context(kernels=kernels):
            results[mode] = [space.value_dot(X, coef), space.gradient_dot(X, coef)]
            if targets is None:
                results[mode].append(space.hessian_dot(X, coef))
        if mode == "flat":
            assert space._flat(1, kernels=kernels, n_samples=n_samples) is not None
    for a, b in zip(results["flat"], results["tree"]):
        assert a.shape == b.shape
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * np.abs(b).max())
    # And both against the explicit products of every basis function.
    np.testing.assert_allclose(results["flat"][0], space.values(X) @ coef, rtol=1e-12, atol=1e-11)
    grad = np.einsum("sij,j...->si...", space.gradients(X), coef)
    np.testing.assert_allclose(results["flat"][1], grad, rtol=1e-12, atol=1e-11)


@pytest.mark.parametrize("kernels", PATHS)
def test_flat_binding_sees_coefficients_changed_in_place(monkeypatch, kernels):
    _forced(monkeypatch, "flat")
    space = _space(4, 3, [False] * 4, {})
    X = _states(space, 3)
    coef = np.random.default_rng(3).standard_normal(space.n_terms)
    with config_context(kernels=kernels):
        before = space.gradient_dot(X, coef)
        coef[-1] += 1.0
        after = space.gradient_dot(X, coef)
    assert not np.allclose(after, before)
    np.testing.assert_allclose(after, space.gradients(X) @ coef, rtol=1e-12, atol=1e-12)


def test_the_cost_rule_keeps_large_spaces_on_the_tree():
    large = ModelSpace([[-1.0, 1.0]] * 4, index_set(4, 10))
    small = ModelSpace([[-1.0, 1.0]] * 4, index_set(4, 2))
    for kernels in ("numpy", "numba"):
        assert large._flat(1, kernels=kernels) is None
        assert small._flat(1, kernels=kernels) is not None
    # numpy's fixed cost per call counts for a few states only.
    assert flat.choose_flat(1000, 500, "numpy", n_samples=4)
    assert not flat.choose_flat(1000, 500, "numpy", n_samples=1000)


# -------------------------------------------------------------- the models
def _henon_heiles_data(n=500, seed=0):
    system = henon_heiles()
    rng = np.random.default_rng(seed)
    X = rng.uniform(-0.6, 0.6, size=(n, 4)) + [0.1, -0.05, 0.2, 0.1]
    return X, system.vector_field(X)


def _models():
    X, dX = _henon_heiles_data()
    damped = dX.copy()
    damped[:, :2] -= 0.05 * dX[:, 2:]
    pendulum = single_pendulum()
    rng = np.random.default_rng(4)
    P = np.column_stack([rng.uniform(-2, 2, 400), rng.uniform(-np.pi, np.pi, 400)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {
            "hamiltonian": HamiltonianRegressor(degree=5, threshold=0.01).fit(X, dX),
            "damped": HamiltonianRegressor(degree=4, threshold=0.01, damping=True).fit(X, damped),
            "vector_field": VectorFieldRegressor(degree=3, threshold=0.01).fit(X, dX),
            "periodic": HamiltonianRegressor(
                degree=6, threshold=0.01, periodic=[False, True], momentum_degree=2,
            ).fit(P, pendulum.vector_field(P)),
        }


@pytest.fixture(scope="module")
def sparse_models():
    return _models()


def _outputs(model, method):
    X0 = np.array(model._eval_space.domain).mean(axis=1)
    x0 = np.stack([X0, X0 + 0.05])
    t = np.linspace(0.0, 0.5, 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = [model.predict(x0), model.simulate(x0, t, method=method, max_step=0.01)]
    if isinstance(model, HamiltonianRegressor):
        out.append(model.hamiltonian(x0))
    return out


@pytest.mark.parametrize("kernels", PATHS)
@pytest.mark.parametrize("name", ["hamiltonian", "damped", "vector_field", "periodic"])
@pytest.mark.parametrize("method", ["rk4", "avf"])
def test_sparse_models_evaluate_the_same_flat_or_tree(monkeypatch, sparse_models, kernels, name,
                                                      method):
    model = sparse_models[name]
    assert model._eval_space.n_terms < model._space.n_terms  # the kept terms only
    results = {}
    for mode in FORCE:
        _forced(monkeypatch, mode)
        _reset(model._eval_space)
        with config_context(kernels=kernels):
            results[mode] = _outputs(model, method)
    for a, b in zip(results["flat"], results["tree"]):
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("name", ["hamiltonian", "vector_field"])
def test_kept_terms_evaluate_as_the_full_space(sparse_models, name):
    # The reduced space of the kept terms against every basis function of
    # the fitted space, with the dropped coefficients zero.
    model = sparse_models[name]
    X = _henon_heiles_data(7, seed=5)[0]
    full = model._space.values(X) @ model.coef_
    with config_context(kernels="numpy"):
        reduced = model._eval_space.value_dot(X, model._eval_coef)
    np.testing.assert_allclose(reduced, full, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kernels", PATHS)
def test_saved_and_loaded_sparse_model_evaluates_the_same(tmp_path, sparse_models, kernels):
    model = sparse_models["hamiltonian"]
    _reset(model._eval_space)  # other tests forced a contraction
    path = tmp_path / "model.skh"
    sk_hamiltonian.save(model, path)
    loaded = sk_hamiltonian.load(path)
    assert loaded._eval_space.n_terms == model._eval_space.n_terms
    with config_context(kernels=kernels):
        for a, b in zip(_outputs(loaded, "avf"), _outputs(model, "avf")):
            np.testing.assert_array_equal(a, b)
