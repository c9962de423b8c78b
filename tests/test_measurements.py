"""Real measurements: scores independent of the origin, damping from noisy irregular records."""

import warnings

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.model_selection import multistep_scorer


def pendulum_runs_at(times, system, rng, noise):
    """Noisy pendulum trajectories sampled at the given stamps, the times first."""
    x0 = rng.uniform(system.domain[:, 0] / 2, system.domain[:, 1] / 2, size=(times.shape[0], 2))
    # All at once on the union of the stamps; RK4 steps of 0.005 are exact
    # far beyond the 1e-10 the scores are compared to (same data both times).
    union = np.unique(times)
    solved = system.solve(x0, union, max_step=0.005)
    X = np.stack([S[np.searchsorted(union, t)] for t, S in zip(times, solved)])
    X = X * (1 + rng.uniform(-noise, noise, X.shape))
    return np.concatenate([times[..., None], X], axis=-1)


@pytest.fixture(scope="module")
def pendulum_runs():
    """40 trajectories of 21 samples: a uniform step 0.02, and jittered stamps."""
    system = single_pendulum()
    uniform = make_trajectories(
        system, 40, 20, dt=0.02, noise=0.01, domain=system.domain / 2, random_state=0
    )
    rng = np.random.default_rng(1)
    steps = rng.uniform(0.5, 1.5, size=(40, 20)) * 0.02
    times = np.concatenate([np.zeros((40, 1)), np.cumsum(steps, axis=1)], axis=1)
    return uniform, pendulum_runs_at(times, system, rng, noise=0.01)


@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
@pytest.mark.parametrize("stamps", [False, True])
def test_scores_do_not_depend_on_where_the_states_are(pendulum_runs, Regressor, stamps):
    """Translating every state by a constant changes no score (to 1e-10).

    The domain follows the data and every error is measured in units of the
    training spread, so a sensor offset cannot change model selection. Both
    scores, both regressors, through a pipeline, with a uniform step or time
    stamps. Measured: scores 0.99, differences at most 1.5e-15.
    """
    uniform, with_times = pendulum_runs
    X = with_times if stamps else uniform
    offset = np.array([3.0, -7.0])
    shifted = X.copy()
    shifted[..., -2:] += offset
    transformer = DerivativeTransformer(dt=None if stamps else 0.02)
    scores = []
    for data in (X, shifted):
        pipe = make_pipeline(transformer, Regressor(degree=4)).fit(data[:30])
        scores.append([pipe.score(data[30:]), multistep_scorer(3)(pipe, data[30:])])
    scores = np.array(scores)
    assert scores.min() > 0.5  # real models, not two failures that agree
    np.testing.assert_allclose(scores[0], scores[1], rtol=0, atol=1e-10)


def test_scores_do_not_depend_on_where_the_clock_starts(pendulum_runs):
    """Time stamps shifted by 1000: the same scores, to 1e-10.

    Every time enters as a difference, so only the round-off of the shifted
    stamps (about 1e-13 of 1000) remains. Measured: differences 1.5e-14.
    """
    _, X = pendulum_runs
    later = X.copy()
    later[..., 0] += 1000.0
    scores = []
    for data in (X, later):
        pipe = make_pipeline(DerivativeTransformer(), HamiltonianRegressor(degree=4))
        pipe.fit(data[:30])
        scores.append([pipe.score(data[30:]), multistep_scorer(3)(pipe, data[30:])])
    np.testing.assert_allclose(scores[0], scores[1], rtol=0, atol=1e-10)


def test_damping_from_a_noisy_irregularly_stamped_record():
    """A damped pendulum (gamma = 0.1), one record of 2 001 jittered samples.

    Steps uniform in [0.5, 1.5] * 0.01, +-2 % multiplicative noise, default
    transformer (sliding degree-5 polynomials in the actual times) and
    HamiltonianRegressor(6, damping=True). Measured over noise seeds 0-4:
    gamma = 0.1016, 0.0946, 0.0999, 0.0994, 0.1003 (at most 5.4 % off); the
    tolerance of 10 % leaves room for other seeds. With finite differences
    instead, the same records gave 0.000-0.141: the noise, amplified by the
    short steps, biases the fit.
    """
    gamma = 0.1
    system = single_pendulum(damping=gamma)
    rng = np.random.default_rng(0)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.5, 1.5, 2000) * 0.01)])
    X = system.solve(system.initial_state, t, max_step=0.001)
    X = X * (1 + rng.uniform(-0.02, 0.02, X.shape))
    pipe = make_pipeline(DerivativeTransformer(), HamiltonianRegressor(6, damping=True))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # neither smoothing nor conservation complaints
        pipe.fit(np.column_stack([t, X])[None])
    assert pipe[-1].damping_[0] == pytest.approx(gamma, rel=0.10)
    assert pipe[-1].energy_trend_z_ < -5  # the data lose energy, and the check sees it
