"""Linear friction fitted with H~, its exact discrete dissipation, and the energy check."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import ConservationWarning, DerivativeTransformer, HamiltonianRegressor
from sk_hamiltonian.datasets import make_trajectories, single_pendulum

GAMMA = 0.3


@pytest.fixture(scope="module")
def damped_data():
    system = single_pendulum(damping=GAMMA)
    X = make_trajectories(system, 300, 10, 0.01, random_state=0)
    return system, DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)


@pytest.mark.parametrize("fit_on", ["derivatives", "steps", "simpson"])
def test_damping_is_recovered_from_clean_data(damped_data, fit_on):
    _, Xt = damped_data
    model = HamiltonianRegressor(degree=8, damping=True, fit_on=fit_on).fit(Xt)
    # Measured: 0.29996 (derivatives), 0.29995 (steps), 0.29994 (simpson).
    assert model.damping_.shape == (1,)
    assert model.damping_[0] == pytest.approx(GAMMA, rel=0.05)
    assert model.n_terms_ == model.coef_.size + 1
    # The damped model loses energy along the data as they do: no warning.
    assert model.energy_trend_ < 0 and model.energy_trend_z_ < -5


def test_conservative_fit_of_dissipative_data_warns_and_names_damping(damped_data):
    _, Xt = damped_data
    with pytest.warns(ConservationWarning, match="damping=True"):
        model = HamiltonianRegressor(degree=8).fit(Xt)
    assert model.energy_trend_ < 0 and model.energy_trend_z_ < -5
    assert np.all(model.damping_ == 0)


def test_conservative_data_do_not_warn_and_get_no_damping():
    system = single_pendulum()
    X = make_trajectories(system, 300, 10, 0.01, random_state=1)
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConservationWarning)
        conservative = HamiltonianRegressor(degree=8).fit(Xt)
    assert abs(conservative.energy_trend_z_) < 5
    # A damping fitted to conservative data comes out at (or is clipped to) ~0.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConservationWarning)
        damped = HamiltonianRegressor(degree=8, damping=True).fit(Xt)
    assert 0 <= damped.damping_[0] < 1e-3


def test_avf_dissipates_exactly_the_discrete_energy_law(damped_data):
    system, Xt = damped_data
    model = HamiltonianRegressor(degree=8, damping=True).fit(Xt)
    h = 0.05
    t = h * np.arange(101)
    Y = model.simulate(system.initial_state, t, method="avf", max_step=np.inf)
    H = model.hamiltonian(Y)
    # H~(y1) - H~(y0) = -h sum_i gamma_i (dq_i / h)^2, the discrete form of
    # dH/dt = -gamma (dq/dt)^2, to round-off.
    law = -model.damping_[0] * np.diff(Y[:, 1]) ** 2 / h
    assert np.abs(np.diff(H) - law).max() < 1e-12 * np.abs(np.diff(H)).max()
    assert np.all(np.diff(H) < 0)
    # It follows the damped field: second-order convergence to RK4 at a fine step.
    short = t[:21]
    reference = model.simulate(system.initial_state, short, method="rk4", max_step=1e-3)
    errors = [
        np.abs(model.simulate(system.initial_state, short, method="avf", max_step=step)
               - reference).max()
        for step in (0.05, 0.025)
    ]
    assert 1.8 < np.log2(errors[0] / errors[1]) < 2.2
    # Conservative explicit symplectic methods refuse a damped model.
    with pytest.raises(ValueError, match="damping"):
        HamiltonianRegressor(degree=4, damping=True, separable=True).fit(Xt).simulate(
            system.initial_state, t, method="leapfrog"
        )


def test_damped_vector_field_is_hamiltonian_minus_friction(damped_data):
    _, Xt = damped_data
    model = HamiltonianRegressor(degree=8, damping=True).fit(Xt)
    X = np.array([[0.5, 0.3], [-1.0, 1.2]])
    grad = model.gradient(X)
    expected = np.column_stack([-grad[:, 1] - model.damping_[0] * grad[:, 0], grad[:, 0]])
    assert np.allclose(model.predict(X), expected)
