"""DerivativeTransformer: finite differences, polynomial de-noising, time stamps, windows."""

import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    ConservationWarning,
    DerivativeTransformer,
    HamiltonianRegressor,
    SmoothingWarning,
    unpack_derivatives,
)
from sk_hamiltonian._derivatives import finite_difference
from sk_hamiltonian._differentiation import (
    finite_difference_at,
    noise_level,
    polynomial_operators,
    windowed_irregular,
    windowed_uniform,
)
from sk_hamiltonian.datasets import henon_heiles, make_trajectories, single_pendulum


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
        ({"dt": None}, np.zeros((2, 10, 2)), "pass the sampling step"),
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


# --------------------------------------------------------------------------
# Time stamps (dt=None: the first column holds the times)


def with_times(t, X):
    """Trajectories ``X`` (n_traj, n_times, n_states) with time column(s) ``t``."""
    t = np.broadcast_to(t, X.shape[:2])
    return np.concatenate([t[..., None], X], axis=-1)


def irregular_times(rng, n_times, dt, n_traj=1):
    steps = rng.uniform(0.5, 1.5, size=(n_traj, n_times - 1)) * dt
    return np.concatenate([np.zeros((n_traj, 1)), np.cumsum(steps, axis=1)], axis=1)


def test_three_point_differences_exact_for_quadratics_on_any_grid():
    rng = np.random.default_rng(1)
    t = irregular_times(rng, 9, 0.2)[0]
    X = np.stack([1 + 2 * t - 3 * t**2, t**2], axis=-1)
    exact = np.stack([2 - 6 * t, 2 * t], axis=-1)
    assert np.allclose(finite_difference_at(X, t), exact, atol=1e-11)
    Xt = DerivativeTransformer(method="finite_difference").fit_transform(with_times(t, X[None]))
    assert np.allclose(unpack_derivatives(Xt).derivatives[0], exact, atol=1e-11)


def test_three_point_differences_second_order_on_irregular_grids():
    # Random uneven stencils anchored at one point, shrunk by 2: the error at
    # the anchor (inside, first sample, last sample) falls by about 4.
    rng = np.random.default_rng(2)
    h1, h2 = rng.uniform(0.01, 0.03, size=(2, 20, 1))
    anchors = {
        1: np.concatenate([-h1, 0 * h1, h2], axis=1),
        0: np.concatenate([0 * h1, h1, h1 + h2], axis=1),
        2: np.concatenate([-h1 - h2, -h2, 0 * h1], axis=1),
    }
    for position, offsets in anchors.items():
        errors = []
        for scale in (1.0, 0.5):
            t = 0.3 + scale * offsets
            D = finite_difference_at(np.sin(t)[..., None], t)
            errors.append(np.abs(D[:, position, 0] - np.cos(0.3)))
        ratio = errors[0] / errors[1]
        assert np.all((ratio > 3.7) & (ratio < 4.3)), (position, ratio)


@pytest.mark.parametrize("method", ["finite_difference", "polynomial"])
@pytest.mark.parametrize("n_times", [41, 300])  # one polynomial, and sliding windows
def test_uniform_time_stamps_reduce_to_dt(method, n_times):
    X, _ = harmonic(3, n_times, 0.02)
    with_dt = DerivativeTransformer(dt=0.02, method=method).fit_transform(X)
    # A time origin other than 0 changes nothing either.
    stamped = DerivativeTransformer(method=method).fit_transform(
        with_times(7.0 + 0.02 * np.arange(n_times), X)
    )
    a, b = unpack_derivatives(with_dt), unpack_derivatives(stamped)
    assert np.allclose(a.derivatives, b.derivatives, rtol=0, atol=1e-11)
    assert np.allclose(a.states, b.states, rtol=0, atol=1e-12)
    assert np.array_equal(a.observed, b.observed)
    assert np.allclose(b.times, 7.0 + 0.02 * np.arange(n_times))


def test_irregular_sliding_windows_match_savitzky_golay_on_uniform_grids():
    t = 0.01 * np.arange(200)
    X = np.stack([np.sin(3 * t), np.cos(2 * t) + t], axis=-1)
    a = windowed_uniform(X[None], [0.01], 4, 30)
    b = windowed_irregular(X, t, 4, 30)
    assert np.allclose(a[0][0], b[0], atol=1e-12)
    assert np.allclose(a[1][0], b[1], atol=1e-10)


@pytest.mark.parametrize("n_times, window", [(15, "auto"), (120, 25)])
def test_polynomial_in_the_actual_times_is_exact_for_polynomials(n_times, window):
    rng = np.random.default_rng(3)
    t = irregular_times(rng, n_times, 0.05)[0]
    X = np.stack([t**3 - t, 2 * t**2 + 1], axis=-1)
    exact = np.stack([3 * t**2 - 1, 4 * t], axis=-1)
    Xt = DerivativeTransformer(degree=3, window=window).fit_transform(with_times(t, X[None]))
    data = unpack_derivatives(Xt)
    assert np.allclose(data.derivatives[0], exact, atol=1e-8)
    assert np.allclose(data.states[0], X, atol=1e-10)


def test_sliding_window_is_the_least_squares_polynomial_around_each_sample():
    rng = np.random.default_rng(4)
    t = irregular_times(rng, 60, 0.05)[0]
    X = np.column_stack([np.sin(2 * t), np.cos(t)]) + rng.normal(scale=0.01, size=(60, 2))
    degree, window = 3, 11
    smoothed, dXdt = windowed_irregular(X, t, degree, window)
    # Samples 0 and 2 use the first window, 30 the one centred on it, 59 the last.
    for i, start in ((0, 0), (2, 0), (30, 25), (59, 49)):
        members = slice(start, start + window)
        for f in range(2):
            poly = np.polynomial.Polynomial.fit(t[members], X[members, f], degree)
            assert smoothed[i, f] == pytest.approx(poly(t[i]), abs=1e-10)
            assert dXdt[i, f] == pytest.approx(poly.deriv()(t[i]), abs=1e-8)


def test_short_trajectories_keep_the_whole_trajectory_fit():
    # The paper's 41-sample trajectories: one polynomial each, as before
    # windows existed, for every degree (auto windows hold at least 48).
    rng = np.random.default_rng(5)
    X = rng.normal(size=(4, 41, 2))
    for degree in (2, 3, 5, 8):
        smooth, differentiate = polynomial_operators(41, 0.01, degree)
        data = unpack_derivatives(DerivativeTransformer(dt=0.01, degree=degree).fit_transform(X))
        assert np.array_equal(data.derivatives, np.einsum("ij,bjk->bik", differentiate, X))
        assert np.array_equal(data.states, np.einsum("ij,bjk->bik", smooth, X))
    transformer = DerivativeTransformer(dt=0.01, degree=8).fit(X)
    assert transformer.window_ == 72
    assert DerivativeTransformer(dt=0.01).fit(X).window_ == 48


def test_a_window_longer_than_the_trajectory_is_one_polynomial():
    X, _ = harmonic(2, 100, 0.05)
    with warnings.catch_warnings():
        # One polynomial over most of a period: residuals far above the
        # (round-off) noise level of these clean samples.
        warnings.simplefilter("ignore", SmoothingWarning)
        whole = DerivativeTransformer(dt=0.05, degree=6, window=100).fit_transform(X)
        local = DerivativeTransformer(dt=0.05, degree=6, window=99).fit_transform(X)
    smooth, differentiate = polynomial_operators(100, 0.05, 6)
    assert np.array_equal(
        unpack_derivatives(whole).derivatives, np.einsum("ij,bjk->bik", differentiate, X)
    )
    assert not np.allclose(
        unpack_derivatives(local).derivatives, unpack_derivatives(whole).derivatives
    )


def test_irregular_henon_heiles_vector_field_from_time_stamps():
    """Steps uniform in [0.5, 1.5] dt: the time stamps, not a mean dt, give the field."""
    system, dt = henon_heiles(), 0.01
    rng = np.random.default_rng(0)
    x0 = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(40, 4))
    times = irregular_times(rng, 41, dt, n_traj=40)
    # All trajectories at once on the union of their stamps; RK4 steps of
    # dt / 20 leave an error of about 1e-12, far below what is measured.
    union = np.unique(times)
    solved = system.solve(x0, union, max_step=dt / 20)
    X = [
        np.column_stack([t, S[np.searchsorted(union, t)]]) for t, S in zip(times, solved)
    ]
    truth = np.concatenate([system.vector_field(T[:, 1:]) for T in X])

    def error(transformer, data):
        derivatives = unpack_derivatives(transformer.fit_transform(data)).derivatives
        return np.linalg.norm(np.concatenate(derivatives) - truth) / np.linalg.norm(truth)

    # Measured (this data): 0.006 % with differences, 0.001 % with the
    # degree-5 polynomial; with the mean step instead, 22 % and 13 %.
    assert error(DerivativeTransformer(method="finite_difference"), X) < 5e-3
    assert error(DerivativeTransformer(), X) < 5e-3
    states = [T[:, 1:] for T in X]
    assert error(DerivativeTransformer(dt=dt, method="finite_difference"), states) > 0.05


@pytest.mark.parametrize(
    "X, match",
    [
        (np.zeros((2, 10, 4)), r"X has 4 columns"),
        ([np.column_stack([np.arange(10.0), np.zeros((10, 2))]),
          np.column_stack([[0, 1, 2, 2, 3, 4, 5, 6, 7, 8.0], np.zeros((10, 2))])],
         r"X\[1\]: the time stamps .* sample 3 has t=2\.0 after t=2\.0"),
        ([np.column_stack([np.arange(10.0), np.zeros((10, 2))]),
          np.column_stack([-np.arange(10.0), np.zeros((10, 2))])],
         r"X\[1\]: the time stamps .* strictly increasing"),
        ([np.column_stack([np.arange(10.0), np.zeros((10, 2))]),
          np.column_stack([[0, 1, np.inf, 3.0], np.zeros((4, 2))])], r"X\[1\] contains NaN"),
        ([np.zeros((10, 3)), np.zeros((2, 3))], r"X\[1\] has 2 sample\(s\); at least 3"),
    ],
)
def test_time_stamp_errors_name_the_trajectory(X, match):
    with pytest.raises(ValueError, match=match):
        DerivativeTransformer(method="finite_difference").fit_transform(X)


def test_window_must_exceed_degree():
    with pytest.raises(ValueError, match=r"window=5 must exceed degree=5"):
        DerivativeTransformer(dt=0.1, degree=5, window=5).fit(np.zeros((1, 60, 2)))
    with pytest.raises(ValueError, match="window"):
        DerivativeTransformer(dt=0.1, window=1).fit(np.zeros((1, 60, 2)))


# --------------------------------------------------------------------------
# Long records


@pytest.fixture(scope="module")
def long_pendulum_record():
    """2 001 samples at dt = 0.01 (about 10 periods), +-2 % multiplicative noise."""
    system, dt = single_pendulum(), 0.01
    clean = system.solve(system.initial_state, dt * np.arange(2001), max_step=dt / 10)
    rng = np.random.default_rng(0)
    return clean * (1 + rng.uniform(-0.02, 0.02, clean.shape)), dt


def test_one_long_noisy_record_with_default_settings(long_pendulum_record):
    """Fit on the first 80 %, roll out over the last 20 % as one trajectory."""
    X, dt = long_pendulum_record
    train, test = X[None, :1601], X[None, 1600:]
    with warnings.catch_warnings():
        warnings.simplefilter("error", SmoothingWarning)
        model = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor(6)).fit(train)
        # Measured 0.988 (seeds 0-2 of the noise: 0.988, 0.975, 0.988).
        assert model.score(test) >= 0.9
    # One polynomial over the whole record cannot follow it: it says so, and
    # the model it feeds fails on the held-out part.
    whole = make_pipeline(DerivativeTransformer(dt=dt, window=2001), HamiltonianRegressor(6))
    with pytest.warns(SmoothingWarning, match=r"degree=5, window=2001 samples"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConservationWarning)
            whole.fit(train)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SmoothingWarning)  # transforming the test part
        assert whole.score(test) < 0.5


def test_no_smoothing_warning_on_the_papers_noisy_bursts():
    # Example 1's data (8 % noise, 41 samples, Q = 5): residuals are 1.6 times
    # the noise level estimated by the median of sixth differences (the noise
    # is multiplicative, with heavier tails than a Gaussian), below the
    # threshold of 3.
    X = make_trajectories(single_pendulum(), 200, 40, 0.01, noise=0.08, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", SmoothingWarning)
        for degree in (3, 5, 8):
            DerivativeTransformer(dt=0.01, degree=degree).fit_transform(X)


def test_noise_level_from_sixth_differences():
    rng = np.random.default_rng(6)
    t = 0.01 * np.arange(3000)
    signal = np.column_stack([np.sin(3 * t), 5 * np.cos(t)])
    sigma = np.array([0.02, 0.1])
    estimate = noise_level([signal + rng.normal(size=signal.shape) * sigma])
    assert np.allclose(estimate, sigma, rtol=0.05)
    assert noise_level([signal[:6]]) is None  # too short for sixth differences
