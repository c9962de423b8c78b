"""DerivativeTransformer: finite differences, polynomial de-noising, layout, errors."""

import numpy as np
import pytest
from sklearn.base import clone

from sk_hamiltonian import DerivativeTransformer, unpack_derivatives
from sk_hamiltonian._derivatives import finite_difference


def harmonic(n_traj, n_times, dt, phase0=0.0):
    t = dt * np.arange(n_times)
    phases = phase0 + np.arange(n_traj)[:, None]
    X = np.stack([-np.sin(t + phases), np.cos(t + phases)], axis=-1)
    dX = np.stack([-np.cos(t + phases), -np.sin(t + phases)], axis=-1)
    return X, dX


def test_finite_differences_exact_for_quadratics():
    dt = 0.3
    t = dt * np.arange(7)
    X = np.stack([1 + 2 * t - 3 * t**2, t**2], axis=-1)[None]
    exact = np.stack([2 - 6 * t, 2 * t], axis=-1)
    assert np.allclose(finite_difference(X, dt)[0], exact, atol=1e-12)


def test_finite_differences_second_order_everywhere():
    errors = []
    for dt in (0.02, 0.01):
        X, dX = harmonic(2, 30, dt)
        errors.append(np.abs(finite_difference(X, dt) - dX).max(axis=(0, 2)))
    # End points included: each halving of dt divides the error by about 4.
    ratio = errors[0] / errors[1]
    assert np.all((ratio > 3.5) & (ratio < 4.5))


def test_polynomial_exact_for_polynomials_and_smooths():
    dt = 0.1
    t = dt * np.arange(12)
    X = np.stack([t**3 - t, 2 * t**2], axis=-1)[None]
    exact = np.stack([3 * t**2 - 1, 4 * t], axis=-1)
    Xt = DerivativeTransformer(dt=dt, degree=3).fit_transform(X)
    data = unpack_derivatives(Xt)
    assert np.allclose(data.derivatives[0], exact, atol=1e-10)
    assert np.allclose(data.states[0], X[0], atol=1e-12)
    assert np.allclose(data.times[0], t)


def test_polynomial_denoises_states_and_keeps_observations():
    rng = np.random.default_rng(0)
    X, dX = harmonic(5, 60, 0.05)
    noisy = X * (1 + rng.uniform(-0.05, 0.05, X.shape))
    data = unpack_derivatives(DerivativeTransformer(dt=0.05, degree=6).fit_transform(noisy))
    assert np.array_equal(data.observed, noisy)
    assert np.abs(data.states - X).mean() < 0.5 * np.abs(noisy - X).mean()
    fd = finite_difference(noisy, 0.05)
    assert np.abs(data.derivatives - dX).mean() < 0.2 * np.abs(fd - dX).mean()
    raw = unpack_derivatives(
        DerivativeTransformer(dt=0.05, degree=6, smooth_states=False).fit_transform(noisy)
    )
    assert np.array_equal(raw.states, noisy)
    assert np.allclose(raw.derivatives, data.derivatives)


def test_list_input_of_different_lengths_matches_array_input():
    X, _ = harmonic(3, 20, 0.1)
    ragged = [X[0], X[1, :15], X[2, :9]]
    out = DerivativeTransformer(dt=0.1, degree=4).fit_transform(ragged)
    assert isinstance(out, list) and [o.shape for o in out] == [(20, 7), (15, 7), (9, 7)]
    alone = DerivativeTransformer(dt=0.1, degree=4).fit_transform(X[1:2, :15])
    assert np.allclose(out[1], alone[0])


def test_one_sample_is_one_trajectory():
    # Transforming a subset of trajectories gives the same rows: folds of
    # trajectories are processed independently.
    X, _ = harmonic(6, 25, 0.1)
    transformer = DerivativeTransformer(dt=0.1, degree=5)
    full = transformer.fit_transform(X)
    assert np.allclose(transformer.transform(X[[4, 1]]), full[[4, 1]])
    assert np.allclose(clone(transformer).fit(X[:2]).transform(X), full)


@pytest.mark.parametrize(
    "params, X, match",
    [
        ({"dt": None}, np.zeros((2, 10, 2)), "needs the sampling step"),
        ({"dt": 0.1, "method": "finite_difference"}, np.zeros((2, 2, 2)), "at least 3"),
        ({"dt": 0.1, "degree": 5}, np.zeros((2, 5, 2)), "lower `degree`"),
        ({"dt": 0.1}, np.zeros((2, 10, 3)), "must be even"),
        ({"dt": 0.1}, np.zeros((10, 2)), "3-D array"),
        ({"dt": 0.1}, np.full((2, 10, 2), np.nan), "NaN"),
    ],
)
def test_errors_name_the_problem(params, X, match):
    with pytest.raises(ValueError, match=match):
        DerivativeTransformer(**params).fit(X)


def test_parameter_validation():
    with pytest.raises(ValueError, match="method"):
        DerivativeTransformer(dt=0.1, method="spline").fit(np.zeros((1, 10, 2)))
    with pytest.raises(ValueError, match="dt"):
        DerivativeTransformer(dt=-1.0).fit(np.zeros((1, 10, 2)))


def test_transform_checks_state_dimension():
    transformer = DerivativeTransformer(dt=0.1).fit(np.zeros((1, 10, 2)))
    with pytest.raises(ValueError, match="fitted with 2"):
        transformer.transform(np.zeros((1, 10, 4)))


def test_unpack_rejects_raw_trajectories():
    with pytest.raises(ValueError, match="DerivativeTransformer first"):
        unpack_derivatives(np.zeros((2, 10, 4)))
