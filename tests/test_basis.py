"""The Legendre gradient basis: counts, ordering, values and derivatives."""

from math import comb

import numpy as np
import pytest
from numpy.polynomial import legendre

from sk_hamiltonian._basis import (
    gradient_dot,
    gradient_matrix,
    hessian_dot,
    legendre_tables,
    map_to_window,
    n_basis_functions,
    total_degree_powers,
    value_matrix,
)

DOMAIN = np.array([[-2.0, 2.0], [-1.0, 2.0], [-2.0, 1.0], [-1.0, 1.0]])


@pytest.mark.parametrize("n_features, degree", [(2, 6), (4, 3), (4, 5), (3, 4)])
def test_powers_count_order_and_uniqueness(n_features, degree):
    powers = total_degree_powers(n_features, degree)
    # The paper's N = C(n + 2d, 2d) - 1 unknowns, constant excluded.
    assert powers.shape == (comb(degree + n_features, n_features) - 1, n_features)
    assert powers.shape[0] == n_basis_functions(n_features, degree)
    assert len({tuple(p) for p in powers}) == powers.shape[0]
    assert np.all(np.diff(powers.sum(axis=1)) >= 0)
    assert powers.sum(axis=1).min() == 1 and powers.sum(axis=1).max() == degree
    with_constant = total_degree_powers(n_features, degree, include_constant=True)
    assert np.array_equal(with_constant[0], np.zeros(n_features))
    assert np.array_equal(with_constant[1:], powers)


def test_window_maps_box_corners():
    corners = DOMAIN.T  # rows: all lows, all highs
    assert np.allclose(map_to_window(corners, DOMAIN), [[-1] * 4, [1] * 4])


def test_tables_match_numpy_legendre():
    x = np.linspace(-1.2, 1.2, 9)[:, None]
    tables = legendre_tables(x, 12, n_derivatives=2)
    for k in range(13):
        unit = np.eye(13)[k]
        for r in range(3):
            expected = legendre.legval(x[:, 0], legendre.legder(unit, r))
            assert np.allclose(tables[r][:, 0, k], expected, rtol=1e-12, atol=1e-9)


def test_values_are_tensor_products():
    rng = np.random.default_rng(0)
    X = rng.uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(6, 4))
    powers = total_degree_powers(4, 4)
    xi = map_to_window(X, DOMAIN)
    V = value_matrix(X, DOMAIN, powers)
    for j in (0, 7, 33, powers.shape[0] - 1):
        expected = np.prod(
            [legendre.legval(xi[:, i], np.eye(5)[powers[j, i]]) for i in range(4)], axis=0
        )
        assert np.allclose(V[:, j], expected)


def test_gradient_and_hessian_match_finite_differences():
    rng = np.random.default_rng(1)
    X = rng.uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(5, 4))
    powers = total_degree_powers(4, 5)
    coef = rng.normal(size=powers.shape[0])
    G = gradient_matrix(X, DOMAIN, powers)
    assert np.allclose(gradient_dot(X, DOMAIN, powers, coef), G @ coef)
    H = hessian_dot(X, DOMAIN, powers, coef)
    eps = 1e-6
    for i in range(4):
        e = np.zeros(4)
        e[i] = eps
        dV = (value_matrix(X + e, DOMAIN, powers) - value_matrix(X - e, DOMAIN, powers)) / (2 * eps)
        assert np.allclose(G[:, i], dV, rtol=1e-6, atol=1e-6)
        dG = (gradient_dot(X + e, DOMAIN, powers, coef) - gradient_dot(X - e, DOMAIN, powers, coef))
        assert np.allclose(H[:, :, i], dG / (2 * eps), rtol=1e-6, atol=1e-5)
    assert np.allclose(H, np.swapaxes(H, 1, 2))


def test_basis_functions_have_zero_mean_on_the_box():
    # The rule that fixes H~'s constant: every non-constant tensor Legendre
    # polynomial integrates to zero over the box (Gauss rule exact at this degree).
    nodes, weights = legendre.leggauss(4)
    grid = np.stack(np.meshgrid(*[nodes] * 2, indexing="ij"), axis=-1).reshape(-1, 2)
    w = np.outer(weights, weights).ravel()
    domain = np.array([[-3.0, 5.0], [0.0, 1.0]])
    X = 0.5 * (grid + 1) * (domain[:, 1] - domain[:, 0]) + domain[:, 0]
    V = value_matrix(X, domain, total_degree_powers(2, 6))
    assert np.abs(w @ V).max() < 1e-13
