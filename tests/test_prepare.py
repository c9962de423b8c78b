"""The search's stage 0: spikes, duplicates, few long records, exact data, the folds."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian.datasets import anharmonic_spring, make_trajectories, single_pendulum
from sk_hamiltonian.exceptions import OutlierWarning
from sk_hamiltonian._spikes import find_spikes
from sk_hamiltonian.model_selection._prepare import MIN_PER_FOLD, prepare

DT = 0.01


def pendulum(n=100, noise=0.08, seed=0, intervals=40):
    return make_trajectories(single_pendulum(), n, intervals, dt=DT, noise=noise,
                             random_state=seed)


def spiked(X, fraction=0.01, seed=1, value=1e6, jump=None):
    """Samples set to ``value`` (a dropped reading), or moved by ``jump``.

    Jumps are put at least three samples from the ends: there a sample is
    compared with a cubic extrapolated from one side, whose own noise is
    eight times the data's, and a jump of this size is within it.
    """
    X = X.copy()
    mask = np.random.default_rng(seed).random(X.shape[:2]) < fraction
    if jump is not None:
        mask[:, :3] = mask[:, -3:] = False
    if jump is None:
        X[mask] = value
    else:
        X[mask] += jump
    return X, mask


def times(X):
    return [DT * np.arange(X.shape[1])] * len(X)


@pytest.mark.parametrize("noise", [0.0, 0.02, 0.08])
def test_no_spike_is_found_in_sound_data(noise):
    # Relative noise is largest where the state is: found spikes there would
    # be the noise model's error, not the data's.
    X = pendulum(noise=noise)
    assert not np.any(find_spikes(times(X), list(X)))


@pytest.mark.parametrize("seed", [0, 4])
def test_no_spike_is_found_on_an_exact_coarsely_sampled_spring(seed):
    # Sampled every 0.05, the cubics' truncation error changes sign along a
    # record: beside a near-zero of it, an end sample's extrapolation stands
    # several times above the median of its neighbours (these seeds each had
    # one sample marked when the neighbours' median was the yardstick).
    X = make_trajectories(anharmonic_spring(), 200, 40, dt=0.05, random_state=seed)
    assert not np.any(find_spikes([0.05 * np.arange(41)] * len(X), list(X)))


@pytest.mark.parametrize("seed", [0, 2])
def test_no_spike_is_found_on_records_that_grow_under_relative_noise(seed):
    # Five records growing 55-fold (an orbit that escapes) among 200 of the
    # pendulum, 2 % relative noise: their last samples are far larger than
    # the rest of the top size bin, and so is their noise (these seeds had two
    # or three samples marked when a bin's noise level ignored that).
    rng = np.random.default_rng(seed)
    X = make_trajectories(single_pendulum(), 200, 40, dt=DT, random_state=seed)
    grow = np.exp(0.1 * np.arange(41))[:, None] * rng.uniform(0.5, 1.5, size=(5, 1, 2))
    X = np.concatenate([X, grow])
    X = X * (1 + 0.02 * rng.standard_normal(X.shape))
    assert not np.any(find_spikes(times(X), list(X)))


def test_two_spikes_side_by_side_are_both_found():
    X = pendulum(noise=0.02)
    X[7, 17:19] = X[30, 8] = X[30, 10] = 1e6
    found = np.array(find_spikes(times(X), list(X)))
    assert sorted(map(tuple, np.argwhere(found))) == [(7, 17), (7, 18), (30, 8), (30, 10)]


def test_three_spikes_within_five_samples_are_found():
    # A sample between spikes (34, beside 32 and 33) stands out of its own
    # cubic as much as a spike does; it once hid them, and 29 with them.
    X = pendulum(noise=0.02)
    X[7, [29, 32, 33]] = 1e6
    found = np.array(find_spikes(times(X), list(X)))
    assert sorted(map(tuple, np.argwhere(found))) == [(7, 29), (7, 32), (7, 33)]


@pytest.mark.parametrize("kind", [dict(value=1e6), dict(value=50.0), dict(jump=1.0)])
def test_spikes_are_found_exactly(kind):
    # A jump of 1 is about 25 times the noise (2 % of states of about 2).
    X, mask = spiked(pendulum(noise=0.02), **kind)
    found = np.array(find_spikes(times(X), list(X)))
    np.testing.assert_array_equal(found, mask)


def test_prepare_cuts_at_spikes_names_them_and_keeps_the_rest():
    X, mask = spiked(pendulum(noise=0.02))
    with pytest.warns(OutlierWarning, match="as spikes") as caught:
        prepared = prepare(list(X), DT, 5, None)
    hit = sorted(int(k) for k in np.flatnonzero(mask.any(axis=1)))
    assert sorted(caught[0].message.trajectories) == hit
    report = prepared.report
    assert sorted(report["left_out"]) == hit
    for k in hit:  # every spike is left out, with the pieces too short to keep
        assert set(np.flatnonzero(mask[k])) <= set(report["left_out"][k])
    kept = sum(len(T) for T in prepared.trajectories)
    left = sum(len(v) for v in report["left_out"].values())
    assert kept + left == X.shape[0] * X.shape[1]  # no sample silently dropped
    assert max(np.abs(T).max() for T in prepared.trajectories) < 100
    # Where each piece comes from, and every piece in the fold of its trajectory.
    for (k, start, stop), T in zip(prepared.origin, prepared.trajectories):
        np.testing.assert_array_equal(T, X[k, start:stop])
    fold_of = {}
    for f, test in enumerate(prepared.folds):
        for row in test:
            assert fold_of.setdefault(prepared.origin[row, 0], f) == f


def test_repeated_trajectories_are_left_out_and_named():
    X = pendulum(n=30)
    copies = np.concatenate([X, X[:5]])
    with pytest.warns(OutlierWarning, match="repeats of earlier"):
        prepared = prepare(list(copies), DT, 5, None)
    assert prepared.report["duplicates"] == {30 + k: k for k in range(5)}
    assert len(prepared.trajectories) == 30


def test_copies_of_one_trajectory_are_too_few_and_say_so():
    X = np.repeat(pendulum(n=1), 30, axis=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutlierWarning)
        with pytest.raises(ValueError, match="Too few data for 5 folds: 1 trajectory of 41 samples"):
            prepare(list(X), DT, 5, None)


def test_few_long_records_are_cut_into_contiguous_blocked_folds():
    system = single_pendulum()
    record = system.solve(system.initial_state, DT * np.arange(4001))
    prepared = prepare([record], DT, 5, None)
    segments = prepared.report["segments"]
    assert segments["n_records"] == 1 and segments["length"] == 200
    assert len(prepared.trajectories) == segments["n_segments"] == 20
    np.testing.assert_array_equal(np.concatenate(prepared.trajectories), record)
    # Each fold holds out one contiguous stretch; no sample is in two folds.
    held = np.concatenate(prepared.folds)
    assert sorted(held) == list(range(20))
    for test in prepared.folds:
        assert np.all(np.diff(test) == 1)


def test_a_shuffled_splitter_of_long_records_is_followed_and_reported_as_such():
    from sklearn.model_selection import KFold

    system = single_pendulum()
    record = system.solve(system.initial_state, DT * np.arange(4001))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # scikit-learn's "groups ... ignored" is not passed on
        prepared = prepare([record], DT, KFold(5, shuffle=True, random_state=0), None)
    held = np.concatenate(prepared.folds)
    assert sorted(held) == list(range(20))
    assert not all(np.all(np.diff(np.sort(test)) == 1) for test in prepared.folds)
    assert "not contiguous stretches" in prepared.report["segments"]["rule"]
    blocked = prepare([record], DT, 5, None)
    assert "each fold holding out a contiguous stretch" in blocked.report["segments"]["rule"]


def test_enough_trajectories_keep_the_folds_of_cv():
    X = pendulum(n=5 * MIN_PER_FOLD)
    prepared = prepare(list(X), DT, 5, None)
    assert prepared.report["segments"] is None
    np.testing.assert_array_equal(np.concatenate(prepared.folds), np.arange(len(X)))


def test_exact_and_noisy_data_are_told_apart():
    assert prepare(list(pendulum(noise=0.0)), DT, 5, None).report["clean"]
    assert not prepare(list(pendulum(noise=0.005)), DT, 5, None).report["clean"]
