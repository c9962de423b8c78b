"""Fast evaluation: contractions, forward products and tables against explicit products.

The explicit references are :meth:`ModelSpace.gradients` / ``values`` (one
product of factors per function, checked against numpy.polynomial in
``test_space.py``) contracted with the coefficients by a plain matrix product,
and finite differences for the Hessian. Every path of the kernels is reached:
one state, a few states (padded children), many states (segment sums, over
several chunks), several targets, dense and sparse index sets.
"""

import pickle
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from sk_hamiltonian import HamiltonianRegressor
from sk_hamiltonian._space import ModelSpace, contraction, index_set, tables, tensor
from sk_hamiltonian._space.contraction import ContractionPlan

SPACES = [
    (4, 6, {}),
    (4, 5, dict(periodic=[0, 0, 1, 1], momentum_degree=2)),
    (8, 4, dict(separable=True, max_interaction=2)),
    (6, 4, dict(max_interaction=3)),
    (3, 4, {}),
    (1, 5, {}),
]


def make_space(m, degree, constraints):
    periodic = np.array(constraints.get("periodic", [0] * m), dtype=bool)
    domain = np.tile([-1.0, 1.5], (m, 1))
    domain[periodic] = [-np.pi, np.pi]
    return ModelSpace(domain, index_set(m, degree, **constraints), periodic)


def states(space, n, seed=0):
    rng = np.random.default_rng(seed)
    low, high = space.domain[:, 0], space.domain[:, 1]
    # A little outside the box too: the kernels must not assume the window.
    return rng.uniform(low - 0.1 * (high - low), high + 0.1 * (high - low), size=(n, space.n_states))


@pytest.fixture(autouse=True)
def small_chunks(monkeypatch):
    # Several chunks even for a few dozen samples, so chunk boundaries are tested.
    monkeypatch.setattr(contraction, "CHUNK_BYTES", 4096)
    monkeypatch.setattr(tensor, "CHUNK_ENTRIES", 512)


@pytest.mark.parametrize("m, degree, constraints", SPACES)
@pytest.mark.parametrize("n_samples", [1, 7, 45])
def test_contractions_equal_explicit_products(m, degree, constraints, n_samples):
    space = make_space(m, degree, constraints)
    X = states(space, n_samples)
    rng = np.random.default_rng(1)
    coef, coef2 = rng.normal(size=space.n_terms), rng.normal(size=(space.n_terms, 3))
    G, V = space.gradients(X), space.values(X)
    assert np.allclose(space.value_dot(X, coef), V @ coef, rtol=1e-12, atol=1e-11)
    assert np.allclose(space.value_dot(X, coef2), V @ coef2, rtol=1e-12, atol=1e-11)
    assert np.allclose(space.gradient_dot(X, coef), G @ coef, rtol=1e-12, atol=1e-10)
    assert np.allclose(
        space.gradient_dot(X, coef2), np.einsum("sij,jk->sik", G, coef2), rtol=1e-12, atol=1e-10
    )
    H = space.hessian_dot(X, coef)
    assert H.shape == (n_samples, m, m)
    assert np.array_equal(H, np.swapaxes(H, 1, 2))
    eps = 1e-6
    for i in range(m):
        e = np.zeros(m)
        e[i] = eps
        dG = (space.gradient_dot(X + e, coef) - space.gradient_dot(X - e, coef)) / (2 * eps)
        assert np.allclose(H[:, :, i], dG, rtol=1e-6, atol=1e-5 * np.abs(dG).max())


@pytest.mark.parametrize("m, degree, constraints", SPACES)
def test_both_kernels_agree_where_the_space_chooses_one(m, degree, constraints):
    # The space uses the contraction plan or the slot kernels by cost; both
    # must give the same numbers.
    space = make_space(m, degree, constraints)
    X = states(space, 20, seed=2)
    coef = np.random.default_rng(3).normal(size=space.n_terms)
    T = space.factor_tables(X, 2)
    slots_gradient = tensor.gradient_dot(T, space.layout, coef).T
    slots_hessian = np.moveaxis(tensor.hessian_dot(T, space.layout, coef), -1, 0)
    plan = ContractionPlan(space.columns, space.width)
    results, patterns = plan.contract(T, plan.bind(coef), 2)
    gradient = results[plan.rows(2, [(i,) for i in range(m)]), 0].T
    assert np.allclose(gradient, slots_gradient, rtol=1e-12, atol=1e-10)
    for k, p in enumerate(patterns):
        if len(p) == 2:
            assert np.allclose(results[k, 0], slots_hessian[:, p[0], p[1]], atol=1e-9)


@pytest.mark.parametrize("m, degree, constraints", SPACES)
@pytest.mark.parametrize("order", [0, 1])
def test_adjoint_is_the_transpose(m, degree, constraints, order):
    space = make_space(m, degree, constraints)
    X = states(space, 45, seed=4)
    plan = ContractionPlan(space.columns, space.width)
    rng = np.random.default_rng(5)
    n_patterns = len(plan._step(order)[1])
    weights = rng.normal(size=(n_patterns, 2, X.shape[0]))
    coef = rng.normal(size=(space.n_terms, 2))
    T = space.factor_tables(X, order)
    forward, _ = plan.contract(T, plan.bind(coef), order)
    # <A c, w> = <c, A^T w> for every target.
    left = np.einsum("pks,pks->k", forward, weights)
    right = np.einsum("jk,jk->k", coef, plan.adjoint(T, weights, order))
    assert np.allclose(left, right, rtol=1e-11)


@pytest.mark.parametrize("m, degree, constraints", SPACES)
def test_forward_products_and_rows_by_variable(m, degree, constraints):
    space = make_space(m, degree, constraints)
    X = states(space, 30, seed=6)
    G = space.gradients_t(X)  # (n_terms, m, S)
    G_reference = np.stack([space.gradients(X[s : s + 1])[0].T for s in range(30)], axis=-1)
    assert np.allclose(G, G_reference, rtol=1e-13, atol=1e-12)
    if space.layout.dense:
        rows = [np.flatnonzero(space.columns[:, i] != 0) for i in range(m)]
        outs = [np.empty((r.size, 30)) for r in rows]
        space.gradient_rows_t(X, rows, outs)
        for i in range(m):
            assert np.array_equal(outs[i], G[rows[i], i])


def test_few_point_tables_equal_the_recurrence(monkeypatch):
    space = make_space(4, 9, dict(periodic=[0, 0, 1, 1]))
    X = states(space, 5)
    direct = space.factor_tables(X, 2)  # 20 points: one eval_legendre call
    monkeypatch.setattr(tables, "DIRECT_POINTS", 0)
    recurrence = space.factor_tables(X, 2)
    assert np.allclose(direct, recurrence, rtol=1e-13, atol=1e-12)


def test_changing_coefficients_in_place_is_seen():
    space = make_space(4, 5, {})
    X = states(space, 3)
    coef = np.random.default_rng(7).normal(size=space.n_terms)
    before = space.gradient_dot(X, coef)
    coef[10] += 1.0
    after = space.gradient_dot(X, coef)
    assert np.allclose(after, space.gradients(X) @ coef)
    assert not np.allclose(after, before)


def test_pickled_space_drops_caches_and_evaluates_the_same():
    space = make_space(4, 5, {})
    X = states(space, 4)
    coef = np.random.default_rng(8).normal(size=space.n_terms)
    expected = space.gradient_dot(X, coef)
    state = space.__getstate__()
    assert state["_contraction"] is None and state["_bindings"] == {} and state["_flat_plans"] == {}
    assert np.array_equal(pickle.loads(pickle.dumps(space)).gradient_dot(X, coef), expected)


def test_threads_do_not_share_scratch_buffers():
    space = make_space(4, 8, {})
    coefs = np.random.default_rng(9).normal(size=(8, space.n_terms))
    Xs = [states(space, 300, seed=s) for s in range(8)]
    expected = [space.gradients(X) @ c for X, c in zip(Xs, coefs)]
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda k: space.gradient_dot(Xs[k], coefs[k]), range(8)))
    for got, want in zip(results, expected):
        assert np.allclose(got, want, rtol=1e-12, atol=1e-10)


def test_model_evaluation_matches_explicit_products():
    rng = np.random.default_rng(10)
    X = rng.uniform(-1, 1, size=(400, 4))
    y = rng.normal(size=(400, 4))
    model = HamiltonianRegressor(degree=5, domain=[[-1, 1]] * 4).fit(X, y)
    G = model._space.gradients(X)
    grad = G @ model.coef_
    assert np.allclose(model.gradient(X), grad, rtol=1e-12, atol=1e-10)
    assert np.allclose(model.predict(X), np.column_stack([-grad[:, 2:], grad[:, :2]]), atol=1e-10)
    assert np.allclose(model.predict(X[:1]), model.predict(X)[:1], rtol=1e-12, atol=1e-12)
