"""HamiltonianSearchCV's scoring, refit and error_score, as GridSearchCV's."""

import warnings

import numpy as np
import pytest
from sklearn.metrics import r2_score

from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.model_selection import HamiltonianSearchCV

DT = 0.01
# A small search: one space, two layouts, two fit targets, one degree.
SMALL = dict(dt=DT, denoise_degrees=("finite_difference", 3), degrees=(4,),
             spaces=[{"periodic": [False, True], "momentum_degree": 2}],
             fit_on=("derivatives", "simpson"), thresholds=(0.0, 0.03), refine=None, cv=3)


@pytest.fixture(scope="module")
def X():
    return make_trajectories(single_pendulum(), 60, 30, dt=DT, noise=0.01, random_state=0)


def searched(X, **params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return HamiltonianSearchCV(**{**SMALL, **params}).fit(X)


def finalist_scores(search):
    results = search.cv_results_
    rows = np.flatnonzero(results["stage"] == "finalist")
    return rows, np.array([[results[f"split{k}_test_score"][i] for k in range(search.n_splits_)]
                           for i in rows])


def test_scoring_scores_the_finalists_with_the_users_scorer(X):
    calls = []

    def scorer(estimator, states, derivatives):
        calls.append((states.shape, derivatives.shape))
        return r2_score(derivatives, estimator.predict(states))

    by_rollout = searched(X)
    by_r2 = searched(X, scoring=scorer)
    rows, scores = finalist_scores(by_r2)
    # One call per finalist and fold, on 2-D states and derivatives of one shape.
    assert len(calls) == scores.size
    assert all(s == d and len(s) == 2 and s[1] == 2 for s, d in calls)
    # Against derivative estimates, which carry noise of their own (finite
    # differences of 1 % noise: r2 near 0.9; de-noised: near 0.999).
    assert np.all((scores > 0.8) & (scores <= 1.0))
    assert not np.allclose(scores, finalist_scores(by_rollout)[1])
    assert by_r2.best_score_ == pytest.approx(scores[list(rows).index(by_r2.best_index_)].mean())
    # The named scorer is the same score as the callable.
    by_name = searched(X, scoring="r2")
    np.testing.assert_allclose(finalist_scores(by_name)[1], scores)
    assert np.isfinite(by_name.score(X)) and by_name.score(X) <= 1.0


def test_refit_false_stops_after_the_choice(X):
    search = searched(X, refit=False)
    reference = searched(X)
    assert search.best_params_ == reference.best_params_
    assert not hasattr(search, "best_estimator_")
    assert search.refinement_["status"] == "not asked"
    for method, args in [("predict", (X,)), ("score", (X,)), ("hamiltonian", (X[0, :2],)),
                         ("simulate", (X[0, 0], [0.0, 1.0]))]:
        with pytest.raises(AttributeError, match="refit=False.*refit=True"):
            getattr(search, method)(*args)


def test_error_score_sets_or_raises_a_failed_score(X):
    def failing(estimator, states, derivatives):
        raise RuntimeError("this scorer fails")

    with pytest.raises(RuntimeError, match="this scorer fails"):
        searched(X, scoring=failing, error_score="raise")
    with pytest.raises(ValueError, match="score failed in some fold.*error_score='raise'"):
        searched(X, scoring=failing)
    search = searched(X, scoring=failing, error_score=-1.0)
    _, scores = finalist_scores(search)
    assert np.all(scores == -1.0)
    assert search.best_score_ == -1.0


def test_bad_scoring_and_error_score_are_refused_with_their_names(X):
    with pytest.raises(ValueError, match="scoring"):
        searched(X, scoring="no_such_score")
    with pytest.raises(ValueError, match="error_score"):
        searched(X, error_score="ignore")
