"""fit_on="weak": the weak form over windows of samples, no derivative estimate."""

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from sk_hamiltonian._training_data import WEAK_WINDOW
from sk_hamiltonian.datasets import (
    damped_pendulum,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian.inspection import hamiltonian_terms

HH_TERMS = {"p1^2": 0.5, "p2^2": 0.5, "q1^2": 0.5, "q2^2": 0.5, "q1^2*q2": 1.0,
            "q2^3": -1 / 3}


def _layout(system, n, samples, dt, noise=0.0, seed=0, method="finite_difference"):
    X = make_trajectories(system, n, samples - 1, dt, noise=noise, random_state=seed)
    return DerivativeTransformer(dt=dt, method=method).fit_transform(X)


def _terms(model):
    return {t.text: t.coefficient for t in hamiltonian_terms(model)}


def test_clean_data_give_the_hamiltonian_to_quadrature_accuracy():
    Xt = _layout(henon_heiles(), 100, 41, 0.05)
    model = HamiltonianRegressor(degree=3, fit_on="weak", threshold=0.01).fit(Xt)
    terms = _terms(model)
    assert set(terms) == set(HH_TERMS)
    # What is left is the trapezoid rule's error on 21 samples of the bump
    # times the field (measured: 1.3e-4 relative at most), far below what
    # noise does to any fit; Simpson's fit gets 1e-12 on clean data.
    for name, exact in HH_TERMS.items():
        assert terms[name] == pytest.approx(exact, rel=5e-4), name


def test_noise_barely_biases_the_weak_form():
    # Henon-Heiles at 2 % noise: the Simpson fit's potential terms come out 1.5
    # to 2.5 % too small (the noise of a pair's ends enters its target and its
    # regressors alike); the weak form's within 1 % (measured 0.1 to 0.7 %).
    Xt = _layout(henon_heiles(), 300, 41, 0.05, noise=0.02)
    weak = _terms(HamiltonianRegressor(degree=3, momentum_degree=2, threshold=0.1,
                                       fit_on="weak").fit(Xt))
    simpson = _terms(HamiltonianRegressor(degree=3, momentum_degree=2, threshold=0.1,
                                          fit_on="simpson").fit(Xt))
    weak_error = max(abs(weak[k] / v - 1) for k, v in HH_TERMS.items())
    simpson_error = max(abs(simpson[k] / v - 1) for k, v in HH_TERMS.items())
    assert weak_error < 0.01 < simpson_error


def test_windows_cover_each_trajectory_and_short_ones_are_one_window():
    Xt = _layout(single_pendulum(), 3, 60, 0.01)
    model = HamiltonianRegressor(degree=2, fit_on="weak")
    data = model._training_data(Xt, None, None)
    X, w, rate, _ = data.windows(_Space())
    assert X.shape[1] == WEAK_WINDOW
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    # 60 samples, windows of 21 every 5, and one ending at the last sample.
    assert X.shape[0] == 3 * 9 == data.windows_count()
    np.testing.assert_allclose(X[8, -1], data.trajectories[0][1][-1], rtol=1e-14)
    short = _layout(single_pendulum(), 2, 8, 0.01)
    X, w, _, _ = model._training_data(short, None, None).windows(_Space())
    assert X.shape[0] == 2 and np.all(w[:, 8:] == 0)


class _Space:
    """A space that wraps nothing (the windows need only wrap_difference)."""

    def wrap_difference(self, D):
        return D


def test_irregular_time_stamps_and_periodic_angles():
    system = single_pendulum()
    rng = np.random.default_rng(0)
    trajectories = []
    for _ in range(60):
        t = np.cumsum(rng.uniform(0.005, 0.015, size=41))
        x0 = rng.uniform([-2, -np.pi], [2, np.pi])
        states = system.solve(x0, t - t[0], max_step=1e-3)
        states[:, 1] = (states[:, 1] + np.pi) % (2 * np.pi) - np.pi  # wrapped angles
        trajectories.append(np.column_stack([t, states]))
    Xt = DerivativeTransformer(method="finite_difference").fit_transform(trajectories)
    model = HamiltonianRegressor(degree=2, periodic=[False, True], momentum_degree=2,
                                 threshold=0.01, fit_on="weak").fit(Xt)
    terms = _terms(model)
    assert set(terms) == {"p^2", "cos(q)"}
    # The trapezoid rule on uneven samples (measured: 3e-4 relative).
    assert terms["p^2"] == pytest.approx(0.5, rel=1e-3)
    assert terms["cos(q)"] == pytest.approx(-9.8, rel=1e-3)


def test_friction_in_the_weak_form():
    Xt = _layout(damped_pendulum(0.3), 200, 41, 0.01)
    model = HamiltonianRegressor(degree=4, periodic=[False, True], momentum_degree=2,
                                 damping=True, threshold=0.01, fit_on="weak").fit(Xt)
    assert model.damping_[0] == pytest.approx(0.3, rel=1e-3)


def test_the_baseline_and_every_solver_take_the_weak_form():
    Xt = _layout(henon_heiles(), 80, 41, 0.05)
    field = VectorFieldRegressor(degree=3, fit_on="weak").fit(Xt)
    X = np.random.default_rng(3).uniform(-0.5, 0.5, size=(20, 4))
    # The weak form's quadrature error, as above (measured: 1.5e-4 relative).
    np.testing.assert_allclose(field.predict(X), henon_heiles().vector_field(X), rtol=1e-3,
                               atol=1e-4)
    coefs = [HamiltonianRegressor(degree=4, fit_on="weak", solver=solver).fit(Xt).coef_
             for solver in ("lstsq", "normal", "sketch")]
    np.testing.assert_allclose(coefs[1], coefs[0], rtol=1e-7, atol=1e-9)
    # The sketch's conjugate gradients stop at a relative residual (measured
    # 3e-9 here); "iterative" needs samples spread over the box, which these
    # short trajectories are not, for any fit target.
    np.testing.assert_allclose(coefs[2], coefs[0], rtol=1e-5, atol=1e-6)


def test_weak_needs_trajectories():
    X = np.random.default_rng(0).normal(size=(30, 2))
    with pytest.raises(ValueError, match="fit_on='weak' fits trajectories"):
        HamiltonianRegressor(fit_on="weak").fit(X, X)
