"""Model spaces: 1-D families, index sets, tensor products, Gram matrix."""

import itertools
from math import comb

import numpy as np
import pytest
from numpy.polynomial import legendre

from sk_hamiltonian._space import ModelSpace, index_set
from sk_hamiltonian._space.fourier import (
    MAX_SEGMENT_NODES,
    MIN_SEGMENT_NODES,
    fourier_tables,
    phase_nodes,
    segment_phase_limits,
    wrap_to_period,
)
from sk_hamiltonian._space.gram import corollary_samples, gradient_gram, stability_constant
from sk_hamiltonian._space.legendre import gauss_on_unit, interval_to_window, legendre_tables

DOMAIN = np.array([[-2.0, 2.0], [-1.0, 2.0], [-2.0, 1.0], [-1.0, 1.0]])


def box(periodic, m, low=-1.0, high=1.5):
    domain = np.tile([low, high], (m, 1))
    periodic = np.zeros(m, bool) if periodic is None else np.asarray(periodic, bool)
    domain[periodic] = [-np.pi, np.pi]
    return domain, periodic


# ----------------------------------------------------------------- index sets
@pytest.mark.parametrize("n_states, degree", [(2, 6), (4, 3), (4, 5), (3, 4)])
def test_total_degree_count_order_and_uniqueness(n_states, degree):
    powers = index_set(n_states, degree)
    # The paper's N = C(n + 2d, 2d) - 1 unknowns, constant excluded.
    assert powers.shape == (comb(degree + n_states, n_states) - 1, n_states)
    assert len({tuple(p) for p in powers}) == powers.shape[0]
    total = powers.sum(axis=1)
    assert np.all(np.diff(total) >= 0) and total.min() == 1 and total.max() == degree
    # Within a degree: decreasing in the first variable (the paper's order).
    for k in range(1, degree + 1):
        assert np.all(np.diff(powers[total == k, 0]) <= 0)
    with_constant = index_set(n_states, degree, include_constant=True)
    assert np.array_equal(with_constant[0], np.zeros(n_states))
    assert np.array_equal(with_constant[1:], powers)


def brute_force(n_states, degree, periodic=None, momentum_degree=None, separable=False,
                max_interaction=None, couplings=None):
    periodic = np.zeros(n_states, bool) if periodic is None else np.asarray(periodic)
    d = n_states // 2
    ranges = [range(-degree, degree + 1) if periodic[i] else range(degree + 1)
              for i in range(n_states)]
    rows = set()
    for alpha in itertools.product(*ranges):
        a = np.abs(alpha)
        if not 0 < a.sum() <= degree:
            continue
        if momentum_degree is not None and a[:d].sum() > momentum_degree:
            continue
        if separable and a[:d].any() and a[d:].any():
            continue
        if max_interaction is not None and np.count_nonzero(a) > max_interaction:
            continue
        depends = set(np.flatnonzero(a))
        if couplings is not None and len(depends) > 1 and not any(
                depends <= set(group) for group in couplings):
            continue
        rows.add(alpha)
    return rows


@pytest.mark.parametrize(
    "n_states, degree, constraints",
    [
        (4, 5, dict(momentum_degree=2)),
        (4, 4, dict(separable=True)),
        (6, 4, dict(max_interaction=2)),
        (4, 4, dict(periodic=[0, 0, 1, 1], momentum_degree=2)),
        (4, 5, dict(periodic=[0, 1, 0, 1], separable=True, max_interaction=1)),
        # Overlapping groups of different sizes, a group across the halves.
        (6, 4, dict(couplings=[(0, 1, 2), (2, 3), (3, 5)])),
        (6, 4, dict(couplings=[(0, 3), (1, 2), (3, 4, 5)], separable=True)),
        (6, 3, dict(couplings=[(0, 1, 2, 3)], max_interaction=2, periodic=[0, 0, 0, 1, 0, 1])),
    ],
)
def test_generated_sets_equal_filtered_total_degree(n_states, degree, constraints):
    powers = index_set(n_states, degree, **constraints)
    assert {tuple(p) for p in powers} == brute_force(n_states, degree, **constraints)
    assert len({tuple(p) for p in powers}) == powers.shape[0]


def test_mechanical_fourier_and_lattice_counts():
    # NOTES: degree <= 2 in p x Fourier |k|_1 <= 8 in q has 6 x 145 - 1 = 869
    # functions; with the frequency counting toward the total degree n = 10:
    # 1 x F(10) + 2 x F(9) + 3 x F(8) - 1, F(K) = 2K^2 + 2K + 1.
    F = lambda K: 2 * K * K + 2 * K + 1  # noqa: E731
    powers = index_set(4, 10, periodic=[0, 0, 1, 1], momentum_degree=2)
    assert powers.shape[0] == F(10) + 2 * F(9) + 3 * F(8) - 1
    # An 8-particle chain: separable, pairwise, degree 4 -> 400 of 4 844 terms.
    assert index_set(16, 4).shape[0] == 4844
    assert index_set(16, 4, separable=True, max_interaction=2).shape[0] == 400
    # 64 variables: generated directly (a total-degree list would hold 814 385).
    assert index_set(64, 4, separable=True, max_interaction=2).shape[0] == 6208
    # Nearest neighbours only: 64 x 4 functions of one variable, and 31 bonds
    # x 6 pairs of positive degrees with sum <= 4.
    bonds = [(32 + i, 33 + i) for i in range(31)]
    assert index_set(64, 4, separable=True, couplings=bonds).shape[0] == 64 * 4 + 31 * 6


# ------------------------------------------------------------- 1-D families
def test_legendre_tables_match_numpy():
    x = np.linspace(-1.2, 1.2, 9)[:, None]
    tables = legendre_tables(x, 12, n_derivatives=2)
    for k in range(13):
        for r in range(3):
            expected = legendre.legval(x[:, 0], legendre.legder(np.eye(13)[k], r))
            assert np.allclose(tables[r][:, 0, k], expected, rtol=1e-12, atol=1e-9)


def test_fourier_tables_values_and_derivatives():
    theta = np.linspace(-7, 7, 23)[:, None]
    tables = fourier_tables(theta, 6, n_derivatives=2)
    k = np.arange(1, 7)
    t = theta[:, 0, None]
    assert np.allclose(tables[0][:, 0, 0], 1.0)
    assert np.allclose(tables[0][:, 0, 1::2], np.cos(k * t), atol=1e-13)
    assert np.allclose(tables[0][:, 0, 2::2], np.sin(k * t), atol=1e-13)
    assert np.allclose(tables[1][:, 0, 1::2], -k * np.sin(k * t), atol=1e-12)
    assert np.allclose(tables[1][:, 0, 2::2], k * np.cos(k * t), atol=1e-12)
    assert np.allclose(tables[2][:, 0, 1::2], -(k**2) * np.cos(k * t), atol=1e-11)
    assert np.allclose(tables[1][:, 0, 0], 0.0) and np.allclose(tables[2][:, 0, 0], 0.0)


def gauss_error(n_nodes, phase):
    """Error of the rule in averaging ``exp(i phase xi)`` over ``[0, 1]``."""
    nodes, weights = gauss_on_unit(n_nodes)
    # About the midpoint the odd part averages to zero on both sides, and the
    # even part's exact average sin(phase / 2) / (phase / 2) has no cancellation.
    t = phase * (nodes - 0.5)
    return abs(weights @ np.cos(t) - np.sinc(phase / (2 * np.pi)))


def test_phase_limits_are_where_each_rule_reaches_round_off():
    limits = segment_phase_limits()
    assert limits.shape == (MAX_SEGMENT_NODES + 1,) and np.all(np.diff(limits) > 0)
    for n_nodes in range(MIN_SEGMENT_NODES, 25):
        # Within its limit a rule is at round-off: 2**-53 plus the rounding
        # of its own n_nodes-term sum.
        assert gauss_error(n_nodes, limits[n_nodes]) <= 2.0**-53 + n_nodes * 2.0**-52
        # The bound is tight: at twice the limit the error is far above round-off.
        assert gauss_error(n_nodes, 2 * limits[n_nodes]) > 1e-14
    assert phase_nodes(0.0) == MIN_SEGMENT_NODES
    assert phase_nodes(limits[9]) == 9 and phase_nodes(limits[9] * (1 + 1e-12)) == 10
    assert phase_nodes(1e3) == phase_nodes(np.nan) == MAX_SEGMENT_NODES


def test_window_and_period_maps():
    xi, scale = interval_to_window(DOMAIN.T, DOMAIN[:, 0], DOMAIN[:, 1])
    assert np.allclose(xi, [[-1] * 4, [1] * 4])
    assert np.allclose(scale, 2 / (DOMAIN[:, 1] - DOMAIN[:, 0]))
    x = np.array([-np.pi, np.pi, 3 * np.pi + 0.5, -7.0])
    wrapped = wrap_to_period(x, -np.pi, np.pi)
    assert np.all((wrapped >= -np.pi) & (wrapped < np.pi))
    assert np.allclose(np.cos(wrapped), np.cos(x)) and np.allclose(np.sin(wrapped), np.sin(x))


# ------------------------------------------------------------ tensor products
def test_values_are_tensor_products_of_legendre():
    rng = np.random.default_rng(0)
    X = rng.uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(6, 4))
    powers = index_set(4, 4)
    xi, _ = interval_to_window(X, DOMAIN[:, 0], DOMAIN[:, 1])
    V = ModelSpace(DOMAIN, powers).values(X)
    for j in (0, 7, 33, powers.shape[0] - 1):
        expected = np.prod(
            [legendre.legval(xi[:, i], np.eye(5)[powers[j, i]]) for i in range(4)], axis=0
        )
        assert np.allclose(V[:, j], expected)


def test_periodic_values_are_trigonometric_in_the_angle():
    domain, periodic = box([0, 1], 2, low=-1.0, high=2.0)
    domain[1] = [0.5, 3.0]  # a period of length 2.5
    space = ModelSpace(domain, index_set(2, 3, periodic=periodic), periodic)
    X = np.random.default_rng(3).uniform([-1, 0.5], [2, 3], size=(5, 2))
    theta = 2 * np.pi * (X[:, 1] - 0.5) / 2.5
    V = space.values(X)
    for j, (a, k) in enumerate(space.powers):
        P = legendre.legval((2 * X[:, 0] - 1.0) / 3.0, np.eye(4)[a])
        T = np.ones(5) if k == 0 else (np.cos(k * theta) if k > 0 else np.sin(-k * theta))
        assert np.allclose(V[:, j], P * T)
    # Periodic in the angle: shifting by one period changes nothing.
    assert np.allclose(space.values(X + [0.0, 2.5]), V, atol=1e-12)


@pytest.mark.parametrize(
    "m, degree, constraints",
    [
        (4, 5, {}),
        (4, 5, dict(periodic=[0, 0, 1, 1], momentum_degree=2)),
        (8, 4, dict(separable=True, max_interaction=2)),
        (2, 6, dict(periodic=[0, 1], max_interaction=1)),
    ],
)
def test_gradients_and_hessians_match_finite_differences(m, degree, constraints):
    domain, periodic = box(constraints.get("periodic"), m)
    space = ModelSpace(domain, index_set(m, degree, **constraints), periodic)
    rng = np.random.default_rng(1)
    X = rng.uniform(domain[:, 0], domain[:, 1], size=(5, m))
    coef = rng.normal(size=space.n_terms)
    G = space.gradients(X)
    assert G.shape == (5, m, space.n_terms)
    assert np.allclose(space.gradient_dot(X, coef), G @ coef, atol=1e-12)
    H = space.hessian_dot(X, coef)
    assert np.allclose(H, np.swapaxes(H, 1, 2))
    eps = 1e-6
    for i in range(m):
        e = np.zeros(m)
        e[i] = eps
        dV = (space.values(X + e) - space.values(X - e)) / (2 * eps)
        assert np.allclose(G[:, i], dV, rtol=1e-6, atol=1e-6)
        dG = (space.gradient_dot(X + e, coef) - space.gradient_dot(X - e, coef)) / (2 * eps)
        assert np.allclose(H[:, :, i], dG, rtol=1e-6, atol=1e-5)


def test_basis_functions_have_zero_mean_on_the_box():
    # The rule that fixes H~'s constant: every non-constant tensor function
    # integrates to zero over the box (Gauss / trapezoid rules exact here).
    nodes, weights = legendre.leggauss(4)
    k = 16
    domain = np.array([[-3.0, 5.0], [0.0, 2 * np.pi]])
    q = np.arange(k) / k * 2 * np.pi
    grid = np.array(list(itertools.product(0.5 * (nodes + 1) * 8 - 3.0, q)))
    w = np.outer(weights / 2, np.full(k, 1 / k)).ravel()
    space = ModelSpace(domain, index_set(2, 6, periodic=[0, 1]), [False, True])
    assert np.abs(w @ space.values(grid)).max() < 1e-13


def test_wrap_and_outside_treat_angles_as_circles():
    domain, periodic = box([0, 1], 2)
    space = ModelSpace(domain, index_set(2, 2, periodic=periodic), periodic)
    X = np.array([[0.0, 4.0], [2.0, 0.0], [0.0, -10.0]])
    assert space.outside(X).tolist() == [False, True, False]
    wrapped = space.wrap(X)
    assert np.allclose(wrapped[:, 0], X[:, 0])
    assert np.allclose(np.exp(1j * wrapped[:, 1]), np.exp(1j * X[:, 1]))
    assert np.allclose(space.wrap_difference([[0.0, 2 * np.pi - 0.1]]), [[0.0, -0.1]])


def test_unwrap_continues_angles_from_the_chart_of_the_start():
    domain, periodic = box([0, 1], 2)
    space = ModelSpace(domain, index_set(2, 2, periodic=periodic), periodic)
    # An angle about pi, as the data give it, and its run wrapped into [-pi, pi).
    q = np.pi + 1.2 * np.sin(np.linspace(0, 6, 61))
    chart = np.column_stack([np.cos(q), q])
    wrapped = space.wrap(chart)
    assert np.abs(np.diff(wrapped[:, 1])).max() > 6  # the wrapped run jumps
    np.testing.assert_allclose(space.unwrap(wrapped, chart[0]), chart, atol=1e-12)
    # Runs of several initial states at once; a NaN stays NaN from its time on.
    runs = np.stack([wrapped, wrapped])
    runs[1, 30:] = np.nan
    unwrapped = space.unwrap(runs, chart[0])
    np.testing.assert_allclose(unwrapped[0], chart, atol=1e-12)
    np.testing.assert_allclose(unwrapped[1, :30], chart[:30], atol=1e-12)
    assert np.isnan(unwrapped[1, 30:]).all()
    # Without periodic variables nothing changes.
    plain = ModelSpace(domain, index_set(2, 2), np.zeros(2, bool))
    assert np.array_equal(plain.unwrap(wrapped, chart[0]), wrapped)


# ----------------------------------------------------------- Gram, stability
@pytest.mark.parametrize("periodic, m, degree", [([0, 0], 2, 6), ([0, 1], 2, 5), ([0, 0, 1, 1], 4, 4)])
def test_closed_form_gram_matches_quadrature(periodic, m, degree):
    domain, periodic = box(periodic, m, low=-2.0, high=3.0)
    space = ModelSpace(domain, index_set(m, degree, periodic=periodic), periodic)
    nodes, weights = legendre.leggauss(degree + 2)
    axes, w_axes = [], []
    for i in range(m):
        if periodic[i]:
            k = 2 * degree + 3
            axes.append(-np.pi + 2 * np.pi * np.arange(k) / k)
            w_axes.append(np.full(k, 1 / k))
        else:
            axes.append(-2.0 + 2.5 * (nodes + 1))
            w_axes.append(weights / 2)
    X = np.array(list(itertools.product(*axes)))
    w = np.prod(np.array(list(itertools.product(*w_axes))), axis=1)
    G = space.gradients(X)
    expected = np.einsum("s,sij,sik->jk", w, G, G)
    gram = gradient_gram(space)
    assert np.allclose(gram.toarray(), expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
    # Sparse: functions couple only if they differ in one variable.
    assert gram.nnz < 0.2 * space.n_terms**2


def test_stability_constant_is_basis_independent_and_grows_with_degree():
    domain = np.array([[-1.0, 1.0], [0.0, 3.0]])
    k4 = stability_constant(ModelSpace(domain, index_set(2, 4)))
    k6 = stability_constant(ModelSpace(domain, index_set(2, 6)))
    # Rescaling the box rescales gradients and Gram alike: K_N is unchanged.
    k6_scaled = stability_constant(ModelSpace(domain * 3.0, index_set(2, 6)))
    assert k6 > 2 * k4 > 0
    assert k6_scaled == pytest.approx(k6, rel=1e-9)
    # Corollary 3.4 at r = 1: K_N <= lambda K / log K with lambda ~ 0.054.
    K = corollary_samples(k6)
    lam = (3 * np.log(1.5) - 1) / 4
    assert K / np.log(K) >= k6 / lam > (K - 1) / np.log(K - 1)
