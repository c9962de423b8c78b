"""HamiltonianSearchCV: the search over spaces, fit targets, de-noising, degree and threshold."""

import pickle
import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.model_selection import KFold
from sklearn.pipeline import Pipeline

from sk_hamiltonian import (
    ConservationWarning,
    DerivativeTransformer,
    HamiltonianRegressor,
)
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.inspection import hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV, auto_spaces
from sk_hamiltonian.model_selection._fold_problems import FoldProblems
from sk_hamiltonian.model_selection._refine import refine_on_trajectories
from sk_hamiltonian.model_selection._selection import pick_among, pick_within, ties

SPACES = [{}, {"periodic": [False, True], "momentum_degree": 2}]


@pytest.fixture(scope="module")
def pendulum():
    return make_trajectories(single_pendulum(), 80, 30, dt=0.01, noise=0.02, random_state=0)


def small_search(**params):
    defaults = dict(dt=0.01, denoise_degrees=["finite_difference", 5], degrees=[4, 6],
                    spaces=SPACES, fit_on=["derivatives", "simpson"], thresholds=[0.0, 0.03],
                    cv=KFold(3, shuffle=True, random_state=0))
    return HamiltonianSearchCV(**{**defaults, **params})


@pytest.fixture(scope="module")
def fitted(pendulum):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConservationWarning)
        return small_search().fit(pendulum)


def test_auto_spaces_cover_every_family_of_each_position():
    spaces = auto_spaces(2)
    assert len(spaces) == 6
    assert {} in spaces and {"momentum_degree": 2} in spaces
    assert {"periodic": [False, True]} in spaces and {"mixed": [False, True]} in spaces
    # Two degrees of freedom: each position on its own.
    four = auto_spaces(4)
    assert len(four) == 18
    assert {"periodic": [False, False, True, False], "mixed": [False, False, False, True]} in four
    # Beyond, pairwise couplings (tests/test_search_scale.py).
    assert all(space["max_interaction"] == 2 for space in auto_spaces(6))


def test_the_search_finds_the_pendulum_law(fitted):
    model = fitted.best_estimator_[-1]
    terms = {t.text for t in hamiltonian_terms(model)}
    assert terms == {"p^2", "cos(q)"}
    coef = {t.text: t.coefficient for t in hamiltonian_terms(model)}
    assert abs(coef["p^2"] - 0.5) < 0.01 and abs(coef["cos(q)"] + 9.8) < 0.2


def test_cv_results_follow_grid_search_conventions(fitted):
    results = fitted.cv_results_
    n = len(results["params"])
    for key in ("mean_test_score", "std_test_score", "rank_test_score", "split0_test_score",
                "split2_test_score", "mean_equation_error", "n_terms", "stage", "tied",
                "param_hamiltonianregressor__degree", "mean_fit_time"):
        assert len(results[key]) == n, key
    finalists = results["stage"] == "finalist"
    # One finalist per layout and fit target; only they have rollout scores.
    assert finalists.sum() == 4
    assert np.isfinite(results["mean_test_score"][finalists]).all()
    assert np.isnan(results["mean_test_score"][~finalists]).all()
    assert results["rank_test_score"][fitted.best_index_] >= 1
    assert fitted.best_params_ == results["params"][fitted.best_index_]
    assert fitted.best_score_ == results["mean_test_score"][fitted.best_index_]
    assert results["tied"][fitted.best_index_]
    assert fitted.n_splits_ == 3


def test_best_estimator_is_the_pipeline_with_best_params(fitted, pendulum):
    pipe = Pipeline([("derivativetransformer", DerivativeTransformer(dt=0.01)),
                     ("hamiltonianregressor", HamiltonianRegressor())])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConservationWarning)
        refit = clone(pipe).set_params(**fitted.best_params_).fit(pendulum)
    # Stage 4 then refines the refit's coefficients on the raw trajectories.
    assert fitted.refinement_["status"] == "refined"
    assert not np.array_equal(refit[-1].coef_, fitted.best_estimator_[-1].coef_)
    refine_on_trajectories(refit[-1], list(pendulum), 0.01)
    np.testing.assert_array_equal(refit[-1].coef_, fitted.best_estimator_[-1].coef_)
    x0 = np.array([[0.5, 0.3]])
    np.testing.assert_array_equal(fitted.simulate(x0, [0, 0.5]),
                                  fitted.best_estimator_[-1].simulate(x0, [0, 0.5]))
    assert fitted.score(pendulum) == fitted.best_estimator_.score(pendulum)


def test_clone_get_params_and_pickle(fitted):
    params = fitted.get_params()
    assert params["dt"] == 0.01 and params["degrees"] == [4, 6]
    copy = clone(fitted)
    assert not hasattr(copy, "cv_results_")
    assert copy.get_params()["thresholds"] == [0.0, 0.03]
    restored = pickle.loads(pickle.dumps(fitted))
    np.testing.assert_array_equal(restored.best_estimator_[-1].coef_,
                                  fitted.best_estimator_[-1].coef_)


def test_n_jobs_gives_the_same_search(pendulum, fitted):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConservationWarning)
        parallel = small_search(n_jobs=2).fit(pendulum)
    assert parallel.best_params_ == fitted.best_params_
    np.testing.assert_array_equal(parallel.cv_results_["mean_equation_error"],
                                  fitted.cv_results_["mean_equation_error"])
    np.testing.assert_array_equal(parallel.cv_results_["mean_test_score"],
                                  fitted.cv_results_["mean_test_score"])


def test_fold_problems_equal_fits_on_the_training_trajectories(pendulum):
    Xt = DerivativeTransformer(dt=0.01, degree=5).fit_transform(pendulum)
    folds = [test for _, test in KFold(3, shuffle=True, random_state=1).split(pendulum)]
    params = {"periodic": [False, True], "momentum_degree": 2, "fit_on": "simpson"}
    problems = FoldProblems(params, Xt, folds, 6)
    for degree, threshold in ((4, 0.0), (6, 0.03)):
        columns, solution = problems.solve(degree, threshold, fold=1)
        train = np.setdiff1d(np.arange(len(Xt)), folds[1])
        direct = HamiltonianRegressor(**params, degree=degree, threshold=threshold,
                                      domain=problems.domain, solver="normal")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            direct.fit(Xt[train])
        model = problems.fitted(degree, threshold, solution, fold=1)
        np.testing.assert_allclose(model.coef_, direct.coef_, rtol=1e-8, atol=1e-10)
        assert model.n_terms_ == direct.n_terms_
        # The held-out equation error is the relative residual of fold 1's rows.
        held_out = Xt[folds[1]]
        design = direct._design(direct._space)
        A, b = [np.concatenate(part) for part in zip(*design.blocks(
            direct._training_data(held_out, None, None, reset=False)))]
        residual = np.sum((A @ np.concatenate([direct.coef_, []]) - b) ** 2) / np.sum(b**2)
        error = problems.equation_error(columns, solution.coef, fold=1)
        assert error == pytest.approx(residual, rel=1e-8)


def test_ties_are_paired():
    rng = np.random.default_rng(0)
    fold_noise = rng.normal(scale=1e-3, size=5)  # shared by every candidate on a fold
    scores = np.vstack([
        1.0 + fold_noise,
        1.0 + fold_noise - 1e-5 + rng.normal(scale=1e-6, size=5),  # 10 paired SE behind
        1.0 + fold_noise + np.array([1, -1, 1, -1, 0]) * 1e-6,  # no difference on average
    ])
    assert ties(scores, 0, higher_is_better=True, paired=True).tolist() == [True, False, True]
    # Unpaired, the fold noise hides the difference of the second.
    assert ties(scores, 0, higher_is_better=True, paired=False).tolist() == [True, True, True]


def test_the_simplest_of_the_tied_finalists_is_chosen():
    scores = np.array([[1.0, 1.1, 0.9], [1.0, 1.1, 0.9], [1.0, 1.1, 0.9], [0.5, 0.6, 0.4]])
    n_terms, smoothing = [3, 2, 2, 1], [5, 8, 3, 3]
    fit_on = ["simpson", "derivatives", "derivatives", "simpson"]
    index, tied = pick_among(scores, n_terms, smoothing, fit_on, "simplest")
    assert tied.tolist() == [True, True, True, False]
    assert index == 2  # fewest terms, then the smoother layout
    index, _ = pick_among(scores, n_terms, [3, 3, 3, 3], fit_on, "simplest")
    assert index == 1  # same size and layout: the first in the order of the targets
    best, _ = pick_among(scores + [[0.01], [0], [0], [0]], n_terms, smoothing, fit_on,
                         "best_score")
    assert best == 0


def test_pick_within_prefers_fewer_terms_among_ties():
    errors = np.array([[0.10, 0.11, 0.12], [0.101, 0.111, 0.121], [0.2, 0.21, 0.22]])
    index, tied = pick_within(errors, [10, 2, 1])
    assert tied.tolist() == [True, True, False] and index == 1


@pytest.mark.parametrize("params, match", [
    (dict(degrees=[]), "degrees"),
    (dict(degrees=[0]), "degrees"),
    (dict(thresholds=[-1.0]), "thresholds"),
    (dict(denoise_degrees=["fd"]), "denoise_degrees"),
    (dict(fit_on=["steps", "strong"]), "fit_on"),
    (dict(spaces=[{"degree": 3}]), "spaces"),
    (dict(denoise_degrees=[40]), "shortest trajectory"),
    (dict(refine="rollout"), "refine"),
])
def test_bad_parameters_name_themselves(pendulum, params, match):
    with pytest.raises(ValueError, match=match):
        small_search(**params).fit(pendulum)


def test_constant_variable_needs_a_domain_and_says_so(pendulum):
    X = pendulum.copy()
    X[..., 0] = 1.0
    with pytest.raises(ValueError, match="`domain`"):
        small_search(spaces=[{}], fit_on=["derivatives"]).fit(X)


def test_unfitted_search_raises_not_fitted():
    from sklearn.exceptions import NotFittedError

    with pytest.raises(NotFittedError):
        small_search().predict(np.zeros((3, 2)))


def test_an_explicit_domain_reaches_every_candidate_and_the_refit(pendulum):
    X = pendulum.copy()
    X[..., 0] = 1.0  # a constant momentum: the bounding box is empty
    domain = [[0.0, 2.0], [-np.pi, np.pi]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(spaces=[{}], fit_on=["derivatives"], domain=domain).fit(X)
    assert search.best_params_["hamiltonianregressor__domain"] == domain
    np.testing.assert_array_equal(search.best_estimator_[-1].domain_, domain)


def test_refine_none_keeps_the_least_squares_refit(pendulum, fitted):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConservationWarning)
        plain = small_search(refine=None).fit(pendulum)
    assert plain.refinement_ == {"status": "not asked"}
    assert plain.best_params_ == fitted.best_params_
    pipe = Pipeline([("derivativetransformer", DerivativeTransformer(dt=0.01)),
                     ("hamiltonianregressor", HamiltonianRegressor())])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConservationWarning)
        refit = pipe.set_params(**plain.best_params_).fit(pendulum)
    np.testing.assert_array_equal(refit[-1].coef_, plain.best_estimator_[-1].coef_)
