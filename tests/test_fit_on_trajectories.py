"""HamiltonianRegressor(fit_on="trajectories"): the trajectory fit for pipeline users, and its intervals."""

import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, load, save
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms, term_intervals

DT = 0.01
SPACE = dict(degree=4, periodic=[False, True], momentum_degree=2, threshold=0.03)


def pendulum(n, noise, seed=0):
    return make_trajectories(single_pendulum(), n, 40, dt=DT, noise=noise, random_state=seed)


def pipeline(**params):
    return make_pipeline(DerivativeTransformer(dt=DT, degree=3),
                         HamiltonianRegressor(**{**SPACE, "fit_on": "trajectories", **params}))


def fitted(X, **params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pipeline(**params).fit(X)


def coefficients(model):
    return {t.text: t.coefficient for t in hamiltonian_terms(model)}


@pytest.fixture(scope="module")
def noisy():
    return pendulum(120, 0.04)


@pytest.fixture(scope="module")
def noisy_fit(noisy):
    return fitted(noisy)


def test_exact_trajectories_give_the_exact_coefficients():
    model = fitted(pendulum(30, 0.0))[-1]
    assert model.trajectory_fit_status_ == "refined"
    found = coefficients(model)
    assert set(found) == {"p^2", "cos(q)"}
    # The least-squares start carries the de-noising polynomial's bias; the
    # trajectories do not (RK4's own error at this step is what is left).
    np.testing.assert_allclose([found["p^2"], found["cos(q)"]], [0.5, -9.8], rtol=1e-6)


def test_the_fit_beats_its_least_squares_start_on_noisy_data():
    # At 8 % noise the de-noised states still carry noise, and the
    # least-squares coefficients its bias (errors in variables).
    truth = {"p^2": 0.5, "cos(q)": -9.8}

    def error(model):
        found = coefficients(model)
        return max(abs(found[k] / v - 1) for k, v in truth.items())

    ratios = []
    for seed in range(3):
        X = pendulum(120, 0.08, seed=seed)
        ratios.append(error(fitted(X, fit_on="derivatives")[-1]) / error(fitted(X)[-1]))
    assert min(ratios) > 1 and np.exp(np.mean(np.log(ratios))) > 2, ratios


def test_the_outcome_is_set_as_fitted_attributes(noisy, noisy_fit):
    model = noisy_fit[-1]
    assert model.trajectory_fit_status_ == "refined"
    # Uniform relative noise of 4 %: standard deviation 0.04 / sqrt(3).
    np.testing.assert_allclose(np.sqrt(model.noise_[:, 1]), 0.04 / np.sqrt(3), rtol=0.1)
    assert model.trajectory_misfit_.shape == (len(noisy),)
    assert 0.8 < np.median(model.trajectory_misfit_) < 1.2
    n = len(model.coef_)
    assert model.coef_covariance_.shape == (n, n)
    np.testing.assert_allclose(model.coef_covariance_, model.coef_covariance_.T)


def test_intervals_shrink_as_one_over_the_root_of_the_trajectories():
    widths = []
    for n in (40, 160):
        model = fitted(pendulum(n, 0.04, seed=1))[-1]
        intervals = {t.text: t.high - t.low for t in term_intervals(model)}
        widths.append(np.array([intervals["p^2"], intervals["cos(q)"]]))
    ratio = widths[0] / widths[1]
    # Four times the trajectories: half the width, up to the spread of two
    # estimates of it.
    assert np.all((ratio > 1.5) & (ratio < 2.7)), ratio


def test_formula_with_the_fits_own_intervals(noisy_fit):
    text = format_hamiltonian(noisy_fit[-1], intervals=True)
    assert text.endswith("(90% intervals of the trajectory fit)")
    assert "(±" in text


def test_clone_params_pickle_and_grid_search_with_two_jobs(noisy):
    pipe = pipeline()
    assert clone(pipe).get_params()["hamiltonianregressor__fit_on"] == "trajectories"
    grid = {"hamiltonianregressor__threshold": [0.01, 0.03]}
    searches = []
    for n_jobs in (1, 2):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            searches.append(GridSearchCV(pipe, grid, cv=3, n_jobs=n_jobs).fit(noisy))
    np.testing.assert_allclose(searches[0].cv_results_["mean_test_score"],
                               searches[1].cv_results_["mean_test_score"], rtol=1e-12)
    np.testing.assert_array_equal(searches[0].best_estimator_[-1].coef_,
                                  searches[1].best_estimator_[-1].coef_)
    assert searches[0].best_estimator_[-1].trajectory_fit_status_ == "refined"


def test_a_model_file_keeps_the_fit_and_its_covariance(noisy_fit, tmp_path):
    path = tmp_path / "pendulum.skh"
    save(noisy_fit, path)
    model, loaded = noisy_fit[-1], load(path)[-1]
    for name in ("coef_", "coef_covariance_", "noise_", "trajectory_misfit_"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(model, name))
    assert loaded.trajectory_fit_status_ == model.trajectory_fit_status_
    assert format_hamiltonian(loaded, intervals=True) == format_hamiltonian(model, intervals=True)


def test_what_it_cannot_take_is_refused_with_the_fix(noisy):
    Xt = DerivativeTransformer(dt=DT).fit_transform(noisy)
    states = Xt[..., 1:3].reshape(-1, 2)
    with pytest.raises(ValueError, match="pass the output of DerivativeTransformer"):
        HamiltonianRegressor(**SPACE, fit_on="trajectories").fit(states, states)
    with pytest.raises(ValueError, match="does not take sample_weight"):
        HamiltonianRegressor(**SPACE, fit_on="trajectories").fit(
            Xt, sample_weight=np.ones(len(Xt)))


def test_each_variance_is_the_larger_of_the_sandwich_and_the_model_based():
    from sk_hamiltonian._trajectory_fit.covariance import (
        parameter_covariance, sandwich_covariance)

    rng = np.random.default_rng(0)
    per_cluster = np.array([[4.0, 1.0], [1.0, 2.0]])
    information = 400 * per_cluster
    # Scores whose spread is twice the model's in the first parameter and a
    # tenth of it in the second: the sandwich is wider, then narrower.
    scores = rng.standard_normal((400, 2)) @ np.linalg.cholesky(per_cluster).T
    scores *= [2.0, 0.1]
    clusters = np.arange(400)
    sandwich = sandwich_covariance(information, scores, clusters)
    model_based = np.linalg.inv(information)
    covariance = parameter_covariance(information, scores, clusters)
    variances = np.diag(covariance)
    np.testing.assert_allclose(variances, np.maximum(np.diag(sandwich), np.diag(model_based)))
    assert np.diag(sandwich)[0] > model_based[0, 0] and np.diag(sandwich)[1] < model_based[1, 1]
    # The sandwich's correlation is kept, so the matrix stays a covariance.
    correlation = covariance[0, 1] / np.sqrt(variances[0] * variances[1])
    np.testing.assert_allclose(correlation, sandwich[0, 1] / np.sqrt(np.diag(sandwich).prod()))
    assert np.linalg.eigvalsh(covariance).min() >= 0
