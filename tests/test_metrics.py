"""sk_hamiltonian.metrics: errors, blow-up, deviation norms, orders, H~ offset and scale."""

import math
import warnings

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, DomainWarning, HamiltonianRegressor
from sk_hamiltonian.datasets import henon_heiles, make_trajectories
from sk_hamiltonian.metrics import (
    BLOWUP_BOUND,
    blowup_time,
    convergence_orders,
    hamiltonian_deviation,
    hamiltonian_offset,
    hamiltonian_range,
    mask_blowup,
    relative_error,
)


# ------------------------------------------------------------ relative_error
def test_relative_error_is_the_norm_ratio_per_time():
    rng = np.random.default_rng(0)
    U, V = rng.normal(size=(7, 4)), rng.normal(size=(7, 4))
    expected = [np.linalg.norm(V[k] - U[k]) / np.linalg.norm(U[k]) for k in range(7)]
    np.testing.assert_allclose(relative_error(V, U), expected, rtol=1e-14)


def test_relative_error_batches_and_propagates_nan():
    rng = np.random.default_rng(1)
    U, V = rng.normal(size=(3, 5, 2)), rng.normal(size=(3, 5, 2))
    V[1, 3:] = np.nan  # trajectory 1 failed at its fourth time
    e = relative_error(V, U)
    assert e.shape == (3, 5)
    assert np.isnan(e[1, 3:]).all() and np.isfinite(e[1, :3]).all()
    np.testing.assert_allclose(e[0], relative_error(V[0], U[0]))


@pytest.mark.parametrize("X, X_true, match", [
    (np.ones((3, 2)), np.ones((4, 2)), "same shape"),
    (np.ones(3), np.ones(3), "shape"),
    (np.ones((2, 2)), np.array([[1.0, 1.0], [0.0, 0.0]]), "zero state at index \\(1,\\)"),
])
def test_relative_error_rejects_bad_input(X, X_true, match):
    with pytest.raises(ValueError, match=match):
        relative_error(X, X_true)


# --------------------------------------------------------------- blow-up
def test_blowup_time_is_the_first_time_out_of_the_bound():
    t = np.linspace(0.0, 2.0, 21)
    X = np.column_stack([np.zeros_like(t), np.exp(2 * t)])  # exp(2t) > 10 from t = 1.2
    assert blowup_time(t, X) == pytest.approx(1.2)
    assert blowup_time(t, X, bound=100.0) == math.inf  # exp(4) = 54.6
    assert blowup_time(t, -X) == pytest.approx(1.2)  # absolute value
    assert BLOWUP_BOUND == 10.0


def test_blowup_time_counts_non_finite_states_and_batches():
    t = np.arange(5.0)
    X = np.zeros((3, 5, 2))
    X[0, 2, 1] = np.nan  # a failed simulation
    X[1, 3, 0] = np.inf
    times = blowup_time(t, X)
    assert isinstance(times, np.ndarray)
    np.testing.assert_array_equal(times, [2.0, 3.0, np.inf])
    assert isinstance(blowup_time(t, X[2]), float)


def test_mask_blowup_keeps_nan_after_a_return_into_the_bound():
    X = np.array([[1.0, 0.0], [11.0, 0.0], [1.0, 0.0], [1.0, 0.0]])
    masked = mask_blowup(X)
    np.testing.assert_array_equal(masked[0], X[0])
    assert np.isnan(masked[1:]).all()
    assert X[1, 0] == 11.0  # a copy: the input is untouched
    np.testing.assert_array_equal(mask_blowup(X, bound=20.0), X)


@pytest.mark.parametrize("bound", [0, -1.0, True, "10", float("nan")])
def test_blowup_rejects_a_bad_bound(bound):
    with pytest.raises(ValueError, match="bound must be a positive number"):
        mask_blowup(np.zeros((2, 2)), bound=bound)


def test_blowup_time_checks_t_against_x():
    with pytest.raises(ValueError, match="one time per row of X \\(4\\)"):
        blowup_time(np.arange(3.0), np.zeros((4, 2)))


# ------------------------------------------------------- deviation and orders
def test_hamiltonian_deviation_norms_of_a_known_signal():
    t = np.linspace(0.0, 2 * np.pi, 20_001)
    H = 3.0 + 1e-3 * np.sin(t)  # dH = 1e-3 sin t
    norms = hamiltonian_deviation(t, H)
    assert norms["linf"] == pytest.approx(1e-3, rel=1e-8)
    assert norms["l2"] == pytest.approx(1e-3 * math.sqrt(np.pi), rel=1e-7)  # int sin^2 = pi
    assert norms["tv"] == pytest.approx(4e-3, rel=1e-7)  # up 1, down 2, up 1


def test_hamiltonian_deviation_refuses_nan():
    with pytest.raises(ValueError, match="blowup_time"):
        hamiltonian_deviation([0.0, 1.0, 2.0], [1.0, np.nan, 1.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        hamiltonian_deviation([0.0, 0.0, 1.0], [1.0, 1.0, 1.0])
    with pytest.raises(ValueError, match="same, non-zero length"):
        hamiltonian_deviation([0.0, 1.0], [1.0, 1.0, 1.0])


def test_convergence_orders_recovers_the_exponent():
    steps = np.array([0.1, 0.05, 0.02, 0.01])
    np.testing.assert_allclose(convergence_orders(steps, 7.0 * steps**4), 4.0, rtol=1e-12)
    np.testing.assert_allclose(convergence_orders(steps, steps**1.5), 1.5, rtol=1e-12)
    assert convergence_orders(steps, steps**2).shape == (3,)


@pytest.mark.parametrize("steps, errors, match", [
    ([0.1], [1.0], "at least 2"),
    ([0.1, 0.05], [1.0, 0.0], "error of zero has no order"),
    ([0.1, -0.05], [1.0, 0.5], "steps must be positive"),
    ([0.1, 0.1], [1.0, 0.5], "consecutive steps must differ"),
    ([0.1, 0.05], [1.0, np.nan], "errors must be positive and finite"),
])
def test_convergence_orders_rejects_bad_input(steps, errors, match):
    with pytest.raises(ValueError, match=match):
        convergence_orders(steps, errors)


# ------------------------------------------------------ H~ offset and range
@pytest.fixture(scope="module")
def henon_model():
    system = henon_heiles()
    X = make_trajectories(system, 300, 2, dt=0.01, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    with warnings.catch_warnings():
        # A few training states leave the box within their two steps.
        warnings.simplefilter("ignore", DomainWarning)
        model = HamiltonianRegressor(degree=3, domain=system.domain).fit(Xt)
    return system, model


def test_hamiltonian_offset_aligns_h_tilde_with_h(henon_model):
    system, model = henon_model
    C = hamiltonian_offset(model, system.hamiltonian)
    rng = np.random.default_rng(5)
    X = rng.uniform(-0.8, 0.8, size=(500, 4))
    gap = system.hamiltonian(X) - model.hamiltonian(X)
    # H~ is exact up to a constant here (cubic H, degree 3): the gap is C everywhere.
    assert np.ptp(gap) < 1e-3 * np.ptp(system.hamiltonian(X))
    assert C == pytest.approx(np.mean(gap), abs=1e-3)
    # Same samples, same constant: the seed fixes the estimate.
    assert hamiltonian_offset(model, system.hamiltonian, random_state=0) == C


def test_hamiltonian_range_of_a_known_h(henon_model):
    system, model = henon_model
    # H~ ~ H + const, and H of Henon-Heiles on [-1, 1]^4 spans about [0, 2.33]
    # (the sampled range is a little smaller than the true one).
    assert hamiltonian_range(model) == pytest.approx(
        np.ptp(system.hamiltonian(np.random.default_rng(0).uniform(-1, 1, (20_000, 4)))),
        rel=1e-2,
    )
    small = hamiltonian_range(model, [[-0.1, 0.1]] * 4)
    assert small < 0.05 * hamiltonian_range(model)


def test_offset_and_range_check_their_arguments(henon_model):
    system, model = henon_model
    with pytest.raises(ValueError, match="domain must have shape \\(4, 2\\)"):
        hamiltonian_range(model, [[-1, 1], [-1, 1]])
    with pytest.raises(ValueError, match="low < high"):
        hamiltonian_range(model, [[1, -1]] * 4)
    with pytest.raises(ValueError, match="n_samples must be a positive integer"):
        hamiltonian_range(model, n_samples=0)
    with pytest.raises(ValueError, match="one finite value per state"):
        hamiltonian_offset(model, lambda X: np.full(len(X), np.nan))
    with pytest.raises(ValueError, match="one finite value per state"):
        hamiltonian_offset(model, lambda X: X)
    with pytest.raises(Exception, match="not fitted"):
        hamiltonian_range(HamiltonianRegressor())
