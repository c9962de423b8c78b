"""Trajectories far outside the rest are named, with what to do; clean and noisy data are not.

Issue 32: 5 % of the paper's noisy pendulum trajectories replaced by
garbage (played backwards, or with spikes) degraded the fit with no
warning, or with a SmoothingWarning that suggested a smaller window.
"""

import warnings

import numpy as np
import pytest
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    OutlierWarning,
    SmoothingWarning,
    VectorFieldRegressor,
)
from sk_hamiltonian.datasets import make_trajectories, single_pendulum


def garbage(kind, seed, n_trajectories=200, noise=0.08):
    """The paper's noisy pendulum with 5 % of the trajectories replaced by garbage."""
    X = make_trajectories(single_pendulum(), n_trajectories, 40, 0.01, noise=noise,
                          random_state=seed)
    rng = np.random.default_rng(1000 + seed)
    bad = np.sort(rng.choice(n_trajectories, n_trajectories // 20, replace=False))
    spread = X.reshape(-1, 2).std(axis=0)
    for k in bad:
        if kind == "reversed":
            X[k] = X[k][::-1]
        else:  # three samples off by twice the data's spread
            samples = rng.choice(X.shape[1], 3, replace=False)
            X[k, samples] += rng.choice([-1, 1], (3, 2)) * 2 * spread
    return X, set(bad.tolist())


def fit_recording(X, Q=5, n=6, Regressor=HamiltonianRegressor):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Xt = DerivativeTransformer(dt=0.01, degree=Q).fit_transform(X)
        model = Regressor(degree=n).fit(Xt)
    return model, caught


def named_by(caught, who):
    return [w for w in caught if issubclass(w.category, OutlierWarning)
            and str(w.message).startswith(who)]


@pytest.mark.parametrize("seed", [0, 1])
def test_trajectories_played_backwards_are_named_by_the_regressor(seed):
    X, bad = garbage("reversed", seed)
    _, caught = fit_recording(X)
    (warning,) = named_by(caught, "HamiltonianRegressor")
    named = set(warning.message.trajectories)
    # Measured over seeds 0-9: 8 to 10 of the 10 named, never a clean one.
    assert len(named & bad) >= 8 and named <= bad
    message = str(warning.message)
    assert f"trajectories {sorted(named)} (numbered within the X this fit was given" in message
    assert "refit without them only if they are corrupt" in message
    assert warning.filename == __file__
    assert not named_by(caught, "DerivativeTransformer")


@pytest.mark.parametrize("seed", [0, 1])
def test_spiky_trajectories_are_named_by_the_transformer_not_blamed_on_the_window(seed):
    X, bad = garbage("spikes", seed)
    _, caught = fit_recording(X)
    (warning,) = named_by(caught, "DerivativeTransformer")
    named = set(warning.message.trajectories)
    assert len(named & bad) >= 8 and named <= bad
    assert "no window or degree fits" in str(warning.message)
    assert "drop or repair those that are corrupt" in str(warning.message)
    assert warning.filename == __file__
    # The other trajectories are fitted as well as the noise allows: no
    # advice to change the window.
    assert not [w for w in caught if issubclass(w.category, SmoothingWarning)]


@pytest.mark.parametrize("noise", [0.0, 0.02, 0.08])
@pytest.mark.parametrize("Q,n", [(3, 8), (5, 6)])
def test_clean_and_noisy_data_name_no_trajectory(noise, Q, n):
    # Measured: no OutlierWarning in 240 fits of 200 trajectories (seeds
    # 0-19) and 120 of 500 (seeds 0-9) over these settings.
    X = make_trajectories(single_pendulum(), 200, 40, 0.01, noise=noise, random_state=3)
    _, caught = fit_recording(X, Q, n)
    assert not [w for w in caught if issubclass(w.category, OutlierWarning)]


def test_the_baseline_names_them_too_and_few_trajectories_are_not_judged():
    X, bad = garbage("reversed", 0)
    _, caught = fit_recording(X, Regressor=VectorFieldRegressor)
    (warning,) = named_by(caught, "VectorFieldRegressor")
    assert len(set(warning.message.trajectories) & bad) >= 8
    # Among nine trajectories there is no "rest" to judge by.
    few = X[sorted(bad)[:1] + list(range(20, 28))]
    _, caught = fit_recording(few, n=4)
    assert not [w for w in caught if issubclass(w.category, OutlierWarning)]


def test_inside_grid_search_the_numbering_is_the_folds_not_the_users():
    # Second contact: inside GridSearchCV the regressor sees only the fold's
    # training trajectories; the warning numbered them "as in X", which
    # they are not, and called them corrupt.
    X, bad = garbage("reversed", 0)
    pipe = make_pipeline(DerivativeTransformer(dt=0.01, degree=5), HamiltonianRegressor(degree=6))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        GridSearchCV(pipe, {"hamiltonianregressor__degree": [6]}, cv=KFold(2)).fit(X)
    # The first fold trains on the second half of X: its indices are
    # shifted by 100 from the user's.
    (in_fold,) = [w for w in named_by(caught, "HamiltonianRegressor")
                  if "of 100 trajectories" in str(w.message)
                  and min(w.message.trajectories) + 100 in bad]
    named = {k + 100 for k in in_fold.message.trajectories}
    assert named <= bad and not set(in_fold.message.trajectories) <= bad
    message = str(in_fold.message)
    assert "numbered as in X" not in message
    assert "numbered within the X this fit was given" in message
    assert "check them with a fit on the full data" in message
    assert "or sound but where the model fits worst" in message
