"""Mixed variables: Legendre polynomials and Fourier terms of one coordinate in one space."""

import numpy as np
import pytest
from numpy.polynomial import legendre

from sk_hamiltonian._space import ModelSpace, index_set
from sk_hamiltonian._space.mixed import code_frequency, factor_degrees, mixed_code
from sk_hamiltonian._space.readable import ReadableBasis

DOMAIN = np.array([[-1.0, 2.0], [-3.0, 4.0]])
MIXED = np.array([False, True])


def _factor(code, x, low, high, mixed):
    """One factor of a basis function, from its definition."""
    if mixed and code < 0:
        k = abs(int(code_frequency(code)))
        return np.cos(k * x) if code_frequency(code) > 0 else np.sin(k * x)
    xi = (2 * x - (low + high)) / (high - low)
    return legendre.legval(xi, np.eye(code + 1)[code])


def _values(powers, X):
    return np.stack([
        np.prod([_factor(row[i], X[:, i], *DOMAIN[i], MIXED[i]) for i in range(2)], axis=0)
        for row in powers
    ], axis=1)


def test_codes_of_a_mixed_variable():
    assert mixed_code(1) == -1 and mixed_code(-1) == -2 and mixed_code(2) == -3
    assert code_frequency(-3) == 2 and code_frequency(-4) == -2 and code_frequency(5) == 0
    powers = np.array([[2, -3], [1, 4], [0, -2]])
    assert factor_degrees(powers, MIXED).tolist() == [[2, 2], [1, 4], [0, 1]]


def test_index_set_holds_polynomial_and_trigonometric_terms_of_each_degree():
    powers = index_set(2, 3, mixed=MIXED)
    degrees = factor_degrees(powers, MIXED).sum(axis=1)
    assert degrees.max() == 3 and np.all(np.diff(degrees) >= 0)  # graded
    # Degree 1 in q: q, cos q, sin q; with the momentum's p: p, p q, p cos q, p sin q.
    rows = {tuple(r) for r in powers.tolist()}
    assert {(0, 1), (0, -1), (0, -2), (1, 1), (1, -1), (1, -2), (1, 0)} <= rows
    assert len(rows) == powers.shape[0]
    # Without mixed variables the index set is unchanged.
    assert np.array_equal(index_set(2, 3), index_set(2, 3, mixed=[False, False]))


def test_values_gradients_and_hessians_match_their_definition():
    powers = index_set(2, 4, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    X = np.random.default_rng(0).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(9, 2))
    np.testing.assert_allclose(space.values(X), _values(powers, X), atol=1e-13)
    h = 1e-6
    numeric = np.stack([(space.values(X + h * e) - space.values(X - h * e)) / (2 * h)
                        for e in np.eye(2)], axis=1)
    np.testing.assert_allclose(space.gradients(X), numeric, atol=1e-7)
    coef = np.random.default_rng(1).normal(size=powers.shape[0])
    grad = lambda Y: space.gradient_dot(Y, coef)  # noqa: E731
    numeric = np.stack([(grad(X + h * e) - grad(X - h * e)) / (2 * h) for e in np.eye(2)], axis=2)
    np.testing.assert_allclose(space.hessian_dot(X, coef), numeric, atol=1e-6)
    np.testing.assert_allclose(space.value_dot(X, coef), space.values(X) @ coef, atol=1e-12)


def test_a_sparse_subset_evaluates_as_the_dense_space():
    powers = index_set(2, 5, mixed=MIXED)
    keep = np.zeros(powers.shape[0], dtype=bool)
    keep[[2, 5, 11]] = True
    dense, sparse = ModelSpace(DOMAIN, powers, mixed=MIXED), ModelSpace(DOMAIN, powers[keep], mixed=MIXED)
    X = np.random.default_rng(2).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(5, 2))
    coef = np.zeros(powers.shape[0])
    coef[keep] = [1.5, -2.0, 0.25]
    np.testing.assert_allclose(sparse.gradient_dot(X, coef[keep]), dense.gradient_dot(X, coef),
                               atol=1e-12)


def test_readable_basis_is_monomials_and_angles():
    powers = index_set(2, 4, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    readable = ReadableBasis(powers, DOMAIN, [False, False], MIXED)
    X = np.random.default_rng(3).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(11, 2))
    for j, (a, code) in enumerate(powers):
        q = X[:, 1]
        factor = q**code if code >= 0 else _factor(code, q, *DOMAIN[1], True)
        fitting = readable.to_fitting[:, [j]].toarray().ravel()
        difference = space.values(X) @ fitting - X[:, 0] ** a * factor
        assert np.ptp(difference) < 1e-10  # equal up to the dropped constant


def test_derivative_maps_give_the_gradient():
    powers = index_set(2, 5, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    maps = space.derivative_maps()
    X = np.random.default_rng(4).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(6, 2))
    values = maps.value_space.values(X)
    gradients = space.gradients(X)
    for i, T in enumerate(maps.maps_t):
        np.testing.assert_allclose(values @ T.T.toarray(), gradients[:, i], atol=1e-10)


@pytest.mark.parametrize("n_states", [3, 40])
def test_compiled_kernels_agree_with_numpy(n_states):
    pytest.importorskip("numba", reason="the compiled kernels need numba (extra 'fast')")
    from sk_hamiltonian import config_context

    powers = index_set(2, 5, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    X = np.random.default_rng(5).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(n_states, 2))
    coef = np.random.default_rng(6).normal(size=powers.shape[0])
    results = []
    for kernels in ("numpy", "numba"):
        with config_context(kernels=kernels):
            results.append((space.value_dot(X, coef), space.gradient_dot(X, coef),
                            space.hessian_dot(X, coef)))
    for numpy_result, compiled in zip(*results):
        np.testing.assert_allclose(compiled, numpy_result, rtol=1e-12, atol=1e-12)
