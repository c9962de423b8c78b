"""Fitting the observed steps instead of estimated derivatives (fit_on="steps")."""

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from sk_hamiltonian.datasets import henon_heiles, make_trajectories


@pytest.fixture(scope="module")
def henon_heiles_data():
    system = henon_heiles()
    X = make_trajectories(system, 500, 2, 0.01, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    t = np.arange(0, 20 + 1e-9, 0.01)
    # RK4 at dt / 10: within 3e-13 (relative) of solve's default dt / 100 here,
    # far below the errors compared with it (1e-6 and up), in a tenth of the 12 s.
    return system, Xt, t, system.solve(system.initial_state, t, max_step=0.001)


def max_error(Y, truth):
    return (np.linalg.norm(Y - truth, axis=1) / np.linalg.norm(truth, axis=1)).max()


def test_steps_fit_is_free_of_derivative_bias(henon_heiles_data):
    system, Xt, t, truth = henon_heiles_data
    steps = HamiltonianRegressor(degree=4, domain=system.domain, fit_on="steps").fit(Xt)
    derivatives = HamiltonianRegressor(degree=4, domain=system.domain).fit(Xt)
    assert steps.dt_ == pytest.approx(0.01)
    # By default a steps model runs the AVF map at the training step.
    Y = steps.simulate(system.initial_state, t)
    assert np.array_equal(Y, steps.simulate(system.initial_state, t, method="avf", max_step=0.01))
    # Measured up to T = 20: 2.6e-5 (steps) against 3.1e-4 (derivatives, whose
    # O(dt^2) finite-difference bias the Hamiltonian cannot absorb).
    assert max_error(Y, truth) < 1e-4
    assert max_error(derivatives.simulate(system.initial_state, t), truth) > 1e-4
    # It still conserves its H~ exactly.
    H = steps.hamiltonian(Y)
    assert np.ptp(H) < 1e-12 * np.abs(H).max()


def test_steps_fit_works_with_one_step_per_trajectory(henon_heiles_data):
    system, _, t, truth = henon_heiles_data
    X = make_trajectories(system, 1000, 1, 0.01, random_state=0)
    # Two samples: a degree-1 polynomial interpolates them (no smoothing), and
    # the steps fit never uses the derivative estimate.
    Xt = DerivativeTransformer(dt=0.01, degree=1).fit_transform(X)
    model = HamiltonianRegressor(degree=4, domain=system.domain, fit_on="steps").fit(Xt)
    # Measured: 3.1e-5.
    assert max_error(model.simulate(system.initial_state, t), truth) < 1e-4


def test_steps_fit_of_the_baseline_runs_its_averaged_map(henon_heiles_data):
    system, Xt, t, truth = henon_heiles_data
    model = VectorFieldRegressor(degree=3, domain=system.domain, fit_on="steps").fit(Xt)
    derivatives = VectorFieldRegressor(degree=3, domain=system.domain).fit(Xt)
    # Measured: 1.3e-9 against 3.8e-4.
    assert max_error(model.simulate(system.initial_state, t), truth) < 1e-6
    assert max_error(derivatives.simulate(system.initial_state, t), truth) > 1e-4


def test_steps_fit_needs_trajectories():
    X = np.random.default_rng(0).uniform(-1, 1, size=(50, 2))
    with pytest.raises(ValueError, match="fit_on='steps'.*DerivativeTransformer"):
        HamiltonianRegressor(degree=2, fit_on="steps").fit(X, X)


def test_steps_fit_uses_each_pairs_own_time_step(henon_heiles_data):
    system, Xt, _, _ = henon_heiles_data
    # The same steps, with times scaled by 2, give a field half as fast.
    slow = Xt.copy()
    slow[..., 0] *= 2
    fast = HamiltonianRegressor(degree=3, domain=system.domain, fit_on="steps").fit(Xt)
    half = HamiltonianRegressor(degree=3, domain=system.domain, fit_on="steps").fit(slow)
    assert np.allclose(half.coef_, fast.coef_ / 2, rtol=1e-10, atol=1e-12)
    assert half.dt_ == pytest.approx(0.02)
