"""Fitting pairs of observed steps by Simpson's rule (fit_on="simpson")."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from sk_hamiltonian.datasets import fput_chain, make_trajectories, single_pendulum
from sk_hamiltonian.inspection import hamiltonian_terms

N_MASSES = 5


def chain_truth():
    """Readable terms of five unit masses and unit springs between two walls."""
    truth = {}
    for i in range(1, N_MASSES + 1):
        truth[f"p{i}^2"] = 0.5
        truth[f"q{i}^2"] = 1.0  # two springs hold every mass
        if i < N_MASSES:
            truth[f"q{i}*q{i + 1}"] = -1.0
    return truth


def worst_relative_error(model):
    """Largest relative error of a true term, and the spurious terms."""
    terms = {term.text: term.coefficient for term in hamiltonian_terms(model)}
    truth = chain_truth()
    worst = max(abs(terms.get(name, 0.0) / value - 1.0) for name, value in truth.items())
    return worst, sorted(set(terms) - set(truth))


@pytest.fixture(scope="module")
def chain_record():
    """One trajectory of 800 steps of dt = 0.1 (the sparse-SINN protocol).

    The reference solutions of this module take RK4 steps of a tenth of the
    smallest interval, not solve's default hundredth: ten times faster, and
    within 1.2e-7 (relative) of it; the errors that this module's tests
    check came out the same to three digits both ways.
    """
    chain = fput_chain(N_MASSES, alpha=0.0, beta=0.0)
    rng = np.random.default_rng(0)
    times = 0.1 * np.arange(801)
    record = chain.solve(rng.uniform(-0.5, 0.5, 2 * N_MASSES), times, max_step=0.01)
    return chain, rng, times, record


def steps_layout(times, states):
    X = np.concatenate([times[:, None], states], axis=1)[None]
    return DerivativeTransformer(method="finite_difference").fit_transform(X)


def test_simpson_learns_the_hamiltonian_not_the_modified_one(chain_record):
    _, _, times, record = chain_record
    Xt = steps_layout(times, record)
    simpson = HamiltonianRegressor(degree=2, fit_on="simpson", threshold=0.03).fit(Xt)
    steps = HamiltonianRegressor(degree=2, fit_on="steps", threshold=0.03).fit(Xt)
    worst, spurious = worst_relative_error(simpson)
    # Measured: 6e-6 (the O(dt**4) error of the rule at omega dt ~ 0.2).
    assert worst < 1e-4 and spurious == []
    # The AVF steps fit learns the modified Hamiltonian, (omega dt)**2 / 12 off.
    assert worst_relative_error(steps)[0] > 1e-3


def test_simpson_handles_uneven_time_steps(chain_record):
    chain, rng, _, _ = chain_record
    times = np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.15, 800)])
    record = chain.solve(rng.uniform(-0.5, 0.5, 2 * N_MASSES), times, max_step=0.005)
    model = HamiltonianRegressor(degree=2, fit_on="simpson", threshold=0.03).fit(
        steps_layout(times, record)
    )
    worst, spurious = worst_relative_error(model)
    # Simpson's weights for two unequal intervals keep the rule exact for
    # quadratics in time; with equal weights the error would be first order.
    assert worst < 1e-4 and spurious == []


def test_simpson_simulates_with_rk4_by_default(chain_record):
    chain, rng, times, record = chain_record
    model = HamiltonianRegressor(degree=2, fit_on="simpson").fit(steps_layout(times, record))
    start = rng.uniform(-0.5, 0.5, 2 * N_MASSES)
    t = times[:201]
    Y = model.simulate(start, t)
    assert np.array_equal(Y, model.simulate(start, t, method="rk4"))
    truth = chain.solve(start, t, max_step=0.01)
    # Measured: 1.5e-4 over 20 time units.
    assert np.linalg.norm(Y - truth) / np.linalg.norm(truth) < 1e-3


@pytest.mark.parametrize("solver", ["normal", "iterative", "sketch"])
def test_every_solver_gives_the_simpson_fit(chain_record, solver):
    _, _, times, record = chain_record
    Xt = steps_layout(times, record)
    reference = HamiltonianRegressor(degree=2, fit_on="simpson", solver="lstsq").fit(Xt)
    model = HamiltonianRegressor(degree=2, fit_on="simpson", solver=solver).fit(Xt)
    assert np.allclose(model.coef_, reference.coef_, rtol=1e-7, atol=1e-9)


def test_simpson_partial_fit_equals_fit(chain_record):
    _, _, times, record = chain_record
    Xt = steps_layout(times, record)
    # The record cut into two trajectories of 401 samples, fed in two calls.
    first, second = Xt[:, :401], Xt[:, 400:]
    domain = np.column_stack([record.min(axis=0), record.max(axis=0)])
    model = HamiltonianRegressor(degree=2, domain=domain, fit_on="simpson")
    model.partial_fit(first).partial_fit(second)
    both = HamiltonianRegressor(degree=2, domain=domain, fit_on="simpson", solver="normal").fit(
        np.concatenate([first, second])
    )
    assert np.allclose(model.coef_, both.coef_, rtol=1e-10, atol=1e-12)


def test_simpson_recovers_friction():
    system = single_pendulum(damping=0.3)
    X = make_trajectories(system, 300, 10, 0.01, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=8, damping=True, fit_on="simpson").fit(Xt)
    # Measured: 0.29994.
    assert model.damping_[0] == pytest.approx(0.3, rel=1e-3)


def test_simpson_fit_of_the_baseline(chain_record):
    chain, rng, times, record = chain_record
    model = VectorFieldRegressor(degree=1, fit_on="simpson").fit(steps_layout(times, record))
    start = rng.uniform(-0.5, 0.5, 2 * N_MASSES)
    truth = chain.solve(start, times[:201], max_step=0.01)
    Y = model.simulate(start, times[:201])
    # Measured: 1.2e-4.
    assert np.linalg.norm(Y - truth) / np.linalg.norm(truth) < 1e-3


def test_simpson_needs_three_samples_per_trajectory():
    system = single_pendulum()
    X = make_trajectories(system, 20, 1, 0.01, random_state=0)  # two samples each
    Xt = DerivativeTransformer(dt=0.01, degree=1).fit_transform(X)
    with pytest.raises(ValueError, match="at least three samples.*fit_on='steps'"):
        HamiltonianRegressor(degree=2, fit_on="simpson").fit(Xt)


def test_simpson_needs_trajectories():
    X = np.random.default_rng(0).uniform(-1, 1, size=(50, 2))
    with pytest.raises(ValueError, match="fit_on='simpson'.*DerivativeTransformer"):
        HamiltonianRegressor(degree=2, fit_on="simpson").fit(X, X)


def test_simpson_counts_pairs_when_underdetermined():
    system = single_pendulum()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        X = make_trajectories(system, 2, 3, 0.01, random_state=0)
        Xt = DerivativeTransformer(dt=0.01, degree=2).fit_transform(X)
    with pytest.raises(ValueError, match="4 pairs of steps"):
        HamiltonianRegressor(degree=6, fit_on="simpson").fit(Xt)
