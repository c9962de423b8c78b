"""Whether the trajectories reach more than one level of the learned energy."""

import numpy as np
import pytest

from sk_hamiltonian.datasets import anharmonic_spring, single_pendulum
from sk_hamiltonian.model_selection._energy_levels import one_level

SYSTEMS = [single_pendulum, anharmonic_spring]
DT = 0.04


def records(system, n_records, n_times, noise, seed=3):
    """Records from states drawn in the system's box, with Gaussian noise of each variable's sd.

    The middle half of the box: no pendulum goes over the top, whose unwound
    angle would make the noise radians.
    """
    rng = np.random.default_rng(seed)
    box = np.asarray(system.domain, dtype=float) / 2
    x0 = rng.uniform(box[:, 0], box[:, 1], size=(n_records, 2))
    X = system.solve(x0, DT * np.arange(n_times), max_step=DT / 4)
    return X + noise * X.reshape(-1, 2).std(axis=0) * rng.standard_normal(X.shape)


def pieces(X, n_pieces):
    return [piece for T in X for piece in np.array_split(T, n_pieces)]


@pytest.mark.parametrize("system", SYSTEMS)
@pytest.mark.parametrize("noise", [0.0, 0.02, 0.08])
def test_the_segments_of_one_record_lie_on_one_level(system, noise):
    system = system()
    X = records(system, 1, 1000, noise)
    found = one_level(system.hamiltonian, pieces(X, 25))
    assert found is not None and found["n_trajectories"] == 25
    if noise == 0:
        assert found["span"] < 1e-6  # the integrator's error only
    truth = system.hamiltonian(records(system, 1, 1, 0.0)[0])[0]
    np.testing.assert_allclose(found["energy"], truth, atol=0.05 * abs(truth) + 0.01)


@pytest.mark.parametrize("system", SYSTEMS)
@pytest.mark.parametrize("shape", [(2, 500), (5, 200), (200, 40)])
def test_records_started_across_the_box_reach_many_levels(system, shape):
    system = system()
    X = records(system, *shape, noise=0.08)
    assert one_level(system.hamiltonian, pieces(X, 5)) is None


def test_records_started_on_one_level_are_one_level_and_a_nearby_one_is_not():
    # Ten short records of the pendulum, all started at H = -4: one level;
    # one of them moved to H = -3 (a tenth of the range) is not.
    system = single_pendulum()
    q = np.linspace(-1.0, 1.0, 10)
    starts = np.column_stack([np.sqrt(2 * (-4.0 + 9.8 * np.cos(q))), q])
    X = system.solve(starts, 0.01 * np.arange(200))
    assert one_level(system.hamiltonian, list(X)) is not None
    starts[0, 0] = np.sqrt(2 * (-3.0 + 9.8 * np.cos(q[0])))
    X = system.solve(starts, 0.01 * np.arange(200))
    assert one_level(system.hamiltonian, list(X)) is None
