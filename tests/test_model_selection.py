"""Cross-validated selection on trajectories: honest scores and the 1-SE rule."""

import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.metrics import check_scoring, r2_score
from sklearn.model_selection import GridSearchCV, GroupKFold, KFold, cross_val_score
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    VectorFieldRegressor,
    unpack_derivatives,
)
from sk_hamiltonian._integrate import RK4, integrate
from sk_hamiltonian._scoring import (
    _own_grids,
    integrate_own_grids,
    integrate_prefixes,
    shared_grids,
)
from sk_hamiltonian.datasets import (
    HamiltonianSystem,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian._scoring import multistep_errors
from sk_hamiltonian.model_selection import (
    count_terms,
    multistep_scorer,
    one_standard_error_rule,
    segment_trajectories,
)

QN = ("derivativetransformer__degree", "hamiltonianregressor__degree")


def morse_oscillator(depth=1.0, width=1.0):
    """``H = p**2 / 2 + depth (1 - exp(-width q))**2``; the domain keeps orbits bound."""

    def hamiltonian(X):
        return 0.5 * X[..., 0] ** 2 + depth * (1.0 - np.exp(-width * X[..., 1])) ** 2

    def gradient(X):
        e = np.exp(-width * X[..., 1:])
        return np.concatenate([X[..., :1], 2.0 * depth * width * e * (1.0 - e)], axis=-1)

    return HamiltonianSystem(
        "morse", hamiltonian, gradient, domain=[[-0.8, 0.8], [-0.4, 1.0]],
        initial_state=[0.3, 0.2],
    )


def derivative_r2(estimator, X, y=None):
    """What PySINDy scores: R² against the held-out derivatives of the same smoother."""
    data = unpack_derivatives(estimator[:-1].transform(X))
    states = data.states.reshape(-1, data.states.shape[-1])
    return r2_score(data.derivatives.reshape(states.shape), estimator[-1].predict(states))


# --------------------------------------------------------------------------
# GridSearchCV on raw trajectories with the default score


@pytest.fixture(scope="module")
def noisy_pendulum():
    return make_trajectories(single_pendulum(), 40, 20, dt=0.05, noise=0.03, random_state=0)


@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
def test_grid_search_scores_rollouts_against_held_out_observations(noisy_pendulum, Regressor):
    X, dt = noisy_pendulum, 0.05
    pipe = make_pipeline(DerivativeTransformer(dt=dt), Regressor())
    grid = {
        "derivativetransformer__degree": [3, 6],
        f"{Regressor.__name__.lower()}__degree": [2, 4],
    }
    cv = KFold(5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # rollouts of the degree-2 models leave the domain
        search = GridSearchCV(pipe, grid, cv=cv).fit(X)
    # The pendulum's q**4 term needs degree 4 in H (degree 3 in the field; 4 here).
    assert search.best_params_[f"{Regressor.__name__.lower()}__degree"] == 4
    assert search.best_estimator_[-1].n_features_in_ == 2

    # Recompute one fold by hand: whole trajectories held out; each one's
    # initial state fitted to its raw observations by converged least squares,
    # and a noise floor from polynomial fits in time, chosen by BIC,
    # subtracted (means over the trajectories). The score takes
    # one Gauss-Newton step from the first observation: exact for the linear
    # flow of a quadratic H~ (Q=3, n=2 is candidate 0), while on nonlinear
    # flows it stops short of the optimum (measured with the mean over
    # trajectories: by 4e-3 to 5e-3 in the score for the n=4 candidates here,
    # whose errors are 0.1-0.4).
    i = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        train, test = next(iter(cv.split(X)))
        model = clone(pipe).set_params(**search.cv_results_["params"][i]).fit(X[train])
        expected, first = reference_score(model[-1], X[test], dt)
    linear = Regressor is HamiltonianRegressor
    got = search.cv_results_["split0_test_score"][i]
    # The degree-2 vector field is quadratic, its flow nonlinear: see above.
    assert got == pytest.approx(expected, rel=1e-9 if linear else 1e-2)
    assert got <= expected + 1e-9  # the converged fit is never worse
    # Rolled out from the first observations instead (the score before
    # shooting), or compared with the smoothed states, it would differ by far
    # more than the tolerance above: the check tells them apart.
    assert abs(first - expected) > 1e-2
    smoothed = unpack_derivatives(model[:-1].transform(X[test])).states
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        against_smoothed, _ = reference_score(model[-1], smoothed, dt)
    assert abs(against_smoothed - expected) > 1e-3


def reference_score(model, observed, dt):
    """The default score recomputed with scipy and numpy, trajectory by trajectory."""
    from scipy.optimize import least_squares

    t = dt * np.arange(observed.shape[1])
    step = min(0.1 * model.time_scale_, dt)  # the score's RK4 step
    shot, first, floor = [], [], []
    for O in observed:
        def residual(x0, O=O):
            Y = model.simulate(x0, t, max_step=step)
            return ((Y - O) / model.state_scale_).ravel()

        r0 = residual(O[0])
        fit = least_squares(residual, O[0], x_scale=model.state_scale_)
        shot.append(np.sqrt(np.mean(min(fit.fun @ fit.fun, r0 @ r0) / r0.size)))
        first.append(np.sqrt(np.mean(r0**2)))
        # Floor: polynomial fits in (normalized) time, degree by BIC.
        Z = (O - O[0]) / model.state_scale_
        s = 2 * t / t[-1] - 1
        N = Z.size
        best = None
        for d in range(0, min(12, len(t) // 2 - 1) + 1):
            V = np.polynomial.legendre.legvander(s, d)
            rss = np.sum((Z - V @ np.linalg.lstsq(V, Z, rcond=None)[0]) ** 2)
            p = Z.shape[1] * (d + 1)
            bic = N * np.log(rss / N) + p * np.log(N)
            if best is None or bic < best[0]:
                best = (bic, rss, p)
        _, rss, p = best
        floor.append(np.sqrt(rss / (N - p) * (N - Z.shape[1]) / N))
    shot, first, floor = map(np.array, (shot, first, floor))
    return (
        1.0 - np.mean(np.minimum(shot, 1.0) - floor),
        1.0 - np.mean(np.minimum(first, 1.0) - floor),
    )


def test_grid_search_accepts_a_list_of_trajectories(noisy_pendulum):
    # Unequal lengths: one sample per trajectory still, whatever its length.
    X = [T[: 12 + k % 9] for k, T in enumerate(noisy_pendulum)]
    pipe = make_pipeline(DerivativeTransformer(dt=0.05), HamiltonianRegressor())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = GridSearchCV(pipe, {"hamiltonianregressor__degree": [2, 4]}, cv=4).fit(X)
    assert np.isfinite(search.cv_results_["mean_test_score"]).all()
    assert search.best_params_ == {"hamiltonianregressor__degree": 4}


# --------------------------------------------------------------------------
# The honest score against PySINDy's derivative R², judged by the true system

MORSE = dict(dt=0.1, n_intervals=40, noise=0.10, n_trajectories=500)
# Coarse grid from the planned Q in 1..12, n in 3..7 (every other value), to
# keep the test near 20 s; benchmarks/cv_scoring_study.py runs the full grid.
MORSE_GRID = {QN[0]: [2, 4, 6, 8, 10, 12], QN[1]: [3, 5, 7]}
# Fresh initial states: many, because the error of a pick is measured against
# the best on the grid, and 20 states left that ratio noisy (1.5 vs 2.1 for the
# same pick, depending on the draw).
HORIZON, N_FRESH = 20.0, 100
# RK4 steps of dt / 2 are within 5e-6 (relative) of the exact Morse flow up to
# T = 20, far below the learning errors (3e-2 and up).
TRUTH_STEP = MORSE["dt"] / 2


def true_error(model, system, x0, t, reference):
    """Mean relative error of the learned system from fresh states; failures count 1."""
    Y, failed_at = integrate(model._integrator("rk4"), x0, t, TRUTH_STEP)
    Y = np.swapaxes(Y, 0, 1)
    errors = np.linalg.norm(Y - reference, axis=(1, 2)) / np.linalg.norm(reference, axis=(1, 2))
    errors[failed_at < t.shape[0]] = 1.0
    return float(np.mean(np.minimum(errors, 1.0)))


# 18 GridSearchCV candidates x 5 folds, then 18 refits rolled out from 100
# states: 18 s on two idle cores. The default score's definition is
# checked in the default run by
# test_grid_search_scores_rollouts_against_held_out_observations above.
@pytest.mark.slow
def test_default_score_selects_near_best_where_derivative_r2_does_not():
    """Noisy Morse oscillator, windows of about one period: honest vs derivative R².

    Measured (data seed 0, this grid, T=20, these 100 fresh states; the same
    with the origin-free score as with the earlier relative-norm one): the
    default score picks Q=8, n=5, the best pair on the grid (1.00x);
    derivative R² picks Q=8, n=7, 1.86x the best. The planned "at least 2x"
    is not a robust fact: with shuffled folds over data seeds 0-4
    (``benchmarks/cv_scoring_study.py --quick --seeds 5``) the derivative-R²
    pick was 1.15-2.98x the best at T=20 (geometric mean 1.79), the default
    pick 1.00-2.32x (geometric mean 1.24, within 1.5x in 4 of 5 seeds); see
    docs/cross_validation.rst. So the test asserts the 1.5x bound on the
    default pick and, for this seed, a derivative-R² pick at least 1.3x worse
    than it, not the planned 2x.
    """
    system, dt = morse_oscillator(), MORSE["dt"]
    X = make_trajectories(
        system, MORSE["n_trajectories"], MORSE["n_intervals"], dt,
        noise=MORSE["noise"], random_state=0,
    )
    pipe = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())
    # check_scoring(pipe) is GridSearchCV's default scoring (the pipeline's own
    # score, whose meaning the first test of this module pins down); both
    # scores come from the same fits, and refit="default" picks like the default.
    scoring = {"default": check_scoring(pipe), "derivative_r2": derivative_r2}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # domain warnings of poor candidates
        search = GridSearchCV(pipe, MORSE_GRID, cv=5, scoring=scoring, refit="default").fit(X)
    results = search.cv_results_
    assert search.best_index_ == int(np.argmax(results["mean_test_default"]))

    rng = np.random.default_rng(1)
    x0 = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(N_FRESH, 2))
    t = dt * np.arange(int(HORIZON / dt) + 1)
    reference = system.solve(x0, t, max_step=dt / 20)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        errors = np.array([
            true_error(clone(pipe).set_params(**p).fit(X)[-1], system, x0, t, reference)
            for p in results["params"]
        ])
    r2_index = int(np.argmax(results["mean_test_derivative_r2"]))
    best = errors.min()
    searched, r2_pick = errors[search.best_index_] / best, errors[r2_index] / best
    report = (
        f"default pick {search.best_params_}: {searched:.2f}x best; derivative-R2 pick "
        f"{results['params'][r2_index]}: {r2_pick:.2f}x best; best "
        f"{results['params'][int(errors.argmin())]} ({best:.3g})"
    )
    assert searched <= 1.5, report
    assert r2_pick >= 1.3 * searched, report


# --------------------------------------------------------------------------
# The one-standard-error rule


def fake_results(degrees, means, stds, n_splits=5, metric="score"):
    means, stds = np.asarray(means, dtype=float), np.asarray(stds, dtype=float)
    results = {
        "params": [{"hamiltonianregressor__degree": n} for n in degrees],
        f"mean_test_{metric}": means,
        f"std_test_{metric}": stds,
    }
    for k in range(n_splits):
        results[f"split{k}_test_{metric}"] = means.copy()
    return results


@pytest.fixture
def pipe4():
    return make_pipeline(DerivativeTransformer(dt=0.1), HamiltonianRegressor())


def test_one_standard_error_rule_picks_fewest_terms_within_one_se(pipe4):
    rule = one_standard_error_rule(pipe4, n_states=4)
    # best 0.90 +- 0.05 / sqrt(4) = 0.025: threshold 0.875.
    results = fake_results([2, 3, 4, 5], [0.80, 0.876, 0.88, 0.90], [0.01, 0.01, 0.01, 0.05],
                           n_splits=4)
    assert rule(results) == 1
    # Just below the threshold, degree 3 is out; with 5 splits the SE shrinks.
    results = fake_results([2, 3, 4, 5], [0.80, 0.874, 0.88, 0.90], [0.01, 0.01, 0.01, 0.05],
                           n_splits=4)
    assert rule(results) == 2
    results = fake_results([2, 3, 4, 5], [0.80, 0.876, 0.88, 0.90], [0.01, 0.01, 0.01, 0.05],
                           n_splits=5)  # threshold 0.90 - 0.0224 = 0.8776
    assert rule(results) == 2


def test_one_standard_error_rule_skips_failed_candidates(pipe4):
    rule = one_standard_error_rule(pipe4, n_states=4)
    # Degree 1 failed (NaN), degree 2 had a failed rollout (-inf); a NaN score
    # must not become the best either.
    results = fake_results(
        [1, 2, 3, 9, 4], [np.nan, -np.inf, 0.89, np.nan, 0.90], [np.nan, np.inf, 0.0, 0.0, 0.03]
    )
    assert rule(results) == 2
    results = fake_results([2, 3], [np.nan, -np.inf], [np.nan, np.nan])
    with pytest.raises(ValueError, match="No candidate has a finite mean 'score'"):
        rule(results)


def test_one_standard_error_rule_breaks_ties_by_score_and_counts_all_params():
    pipe = make_pipeline(DerivativeTransformer(dt=0.1), HamiltonianRegressor())
    rule = one_standard_error_rule(pipe, n_states=2)
    # Same n (same number of terms), different Q: the higher mean score wins.
    results = {
        "params": [{QN[0]: 3, QN[1]: 4}, {QN[0]: 5, QN[1]: 4}, {QN[0]: 5, QN[1]: 6}],
        "mean_test_score": np.array([0.90, 0.91, 0.92]),
        "std_test_score": np.array([0.0, 0.0, 0.05]),
        "split0_test_score": np.zeros(3),
    }
    assert rule(results) == 1
    # VectorFieldRegressor counts 2d * C(n + 2d, 2d): degree 1 has 6 terms in 2-D.
    vf = make_pipeline(DerivativeTransformer(dt=0.1), VectorFieldRegressor())
    results = fake_results([1, 2], [0.5, 0.9], [0.0, 0.0])
    results["params"] = [{"vectorfieldregressor__degree": n} for n in (1, 2)]
    assert one_standard_error_rule(vf, n_states=2)(results) == 1


def test_one_standard_error_rule_errors(pipe4):
    for bad in (3, 0, 2.0, True):
        with pytest.raises(ValueError, match="n_states must be the number of state variables"):
            one_standard_error_rule(pipe4, n_states=bad)
    with pytest.raises(ValueError, match="HamiltonianRegressor or VectorFieldRegressor"):
        one_standard_error_rule(DerivativeTransformer(dt=0.1), n_states=2)
    with pytest.raises(ValueError, match="metric must be the name"):
        one_standard_error_rule(pipe4, n_states=4, metric=None)
    rule = one_standard_error_rule(pipe4, n_states=4, metric="rollout")
    with pytest.raises(ValueError, match="no 'mean_test_rollout'"):
        rule(fake_results([2], [0.9], [0.0]))
    assert rule(fake_results([2, 3], [0.9, 0.95], [0.0, 0.0], metric="rollout")) == 1


@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
@pytest.mark.parametrize("n_states,degree", [(2, 5), (4, 3)])
def test_count_terms_matches_the_fitted_model(Regressor, n_states, degree):
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(400, n_states))
    model = Regressor(degree=degree).fit(X, rng.normal(size=X.shape))
    pipe = make_pipeline(DerivativeTransformer(dt=0.1), Regressor())
    params = {f"{Regressor.__name__.lower()}__degree": degree}
    assert count_terms(pipe, n_states, params) == model.n_terms_
    assert count_terms(Regressor(degree=degree), n_states) == model.n_terms_


def test_one_standard_error_rule_in_a_search_with_a_failing_candidate():
    # Degree 12 has 90 unknowns for 2 * 3 * 12 = 72 equations per training
    # fold: its fits fail (NaN score), and the rule must still return.
    X = make_trajectories("single_pendulum", 15, 2, dt=0.01, random_state=0)
    pipe = make_pipeline(
        DerivativeTransformer(dt=0.01, method="finite_difference"), HamiltonianRegressor()
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = GridSearchCV(
            pipe, {QN[1]: [2, 4, 12]}, cv=5, refit=one_standard_error_rule(pipe, n_states=2)
        ).fit(X)
    assert np.isnan(search.cv_results_["mean_test_score"][2])
    assert search.best_params_[QN[1]] in (2, 4)


# 8 degrees x 5 folds of the default (rollout) score, then two rollouts to
# T = 20: 12 s measured on a busy two-core machine. The rule itself is
# checked in the default run on made-up search results above.
@pytest.mark.slow
def test_one_standard_error_rule_on_henon_heiles():
    """Clean Hénon-Heiles, finite differences, M=500, J=2, dt=0.01, n up to 8.

    Measured (data seed 0, the origin-free score): the rule picks n=4, not the
    true degree 3. n=4's 1 - score is about 3 % smaller (5.48e-7 against
    5.66e-7, 1.4 SE; 6 % and 2 SE with the earlier relative-norm score), and
    n=4 is also about 2x closer to the true system at T=20 from u0*: the
    O(dt**2) bias of finite differences has a degree-4 part that a cubic H~
    aliases into its low-order coefficients (docs/cross_validation.rst). With
    data seed 1 the rule picks n=3 (best mean n=4): the assertions hold for
    seed 0 only.
    """
    system = henon_heiles()
    X = make_trajectories(system, 500, 2, 0.01, random_state=0)
    pipe = make_pipeline(
        DerivativeTransformer(dt=0.01, method="finite_difference"), HamiltonianRegressor()
    )
    search = GridSearchCV(
        pipe, {QN[1]: list(range(1, 9))}, cv=5, refit=one_standard_error_rule(pipe, n_states=4)
    ).fit(X)
    results = search.cv_results_
    means, se = results["mean_test_score"], results["std_test_score"] / np.sqrt(5)
    best = int(np.argmax(means))
    assert search.best_params_ == {QN[1]: 4}
    assert means[2] < means[best] - se[best]  # n=3 falls outside one SE
    assert np.all(means[4:] < means[3])  # n = 5..8 are not better than 4
    t = np.arange(0, 20.0 + 1e-9, 0.01)
    truth = system.solve(system.initial_state, t, max_step=1e-3)[-1]
    errors = [
        np.linalg.norm(
            clone(pipe).set_params(**{QN[1]: n}).fit(X)[-1].simulate(system.initial_state, t)[-1]
            - truth
        ) / np.linalg.norm(truth)
        for n in (3, 4)
    ]
    assert errors[1] < 0.7 * errors[0], errors


# --------------------------------------------------------------------------
# multistep_scorer


@pytest.fixture(scope="module")
def clean_pendulum_fit():
    X = make_trajectories("single_pendulum", 60, 20, dt=0.05, random_state=1)
    pipe = make_pipeline(
        DerivativeTransformer(dt=0.05, method="finite_difference"), HamiltonianRegressor(degree=8)
    )
    return X, pipe.fit(X[:40])


def test_multistep_with_the_whole_window_is_one_rollout_from_the_first_observation(clean_pendulum_fit):
    X, pipe = clean_pendulum_fit
    Xt = pipe[:-1].transform(X[40:])
    np.testing.assert_allclose(
        multistep_errors(pipe[-1], Xt, n_steps=20), multistep_errors(pipe[-1], Xt), rtol=1e-12
    )
    # The scorer over the whole window is the rollout from the first observation
    # (the default score before it fitted initial states and a noise floor).
    whole = 1.0 - np.mean(np.minimum(multistep_errors(pipe[-1], Xt), 1.0))
    assert multistep_scorer(20)(pipe, X[40:]) == pytest.approx(whole, rel=1e-12)


def test_multistep_scorer_compares_with_observations(clean_pendulum_fit):
    X, pipe = clean_pendulum_fit
    score = multistep_scorer(3)
    clean = score(pipe, X[40:])
    # About 2 % error: finite differences at dt=0.05 bias the fitted field.
    assert 0.95 < clean <= 1.0
    # Noise on the held-out observations lowers the score (the predictions do
    # not move much: only their starting states are noisy).
    noisy = X[40:] * (1 + np.random.default_rng(0).uniform(-0.05, 0.05, X[40:].shape))
    assert score(pipe, noisy) < clean - 0.01
    # One-step errors by hand from every observation, for one trajectory.
    T = X[40]
    ahead = pipe[-1].simulate(T[:-1], [0.0, 0.05], max_step=0.05 / 4)[:, 1]
    # Each segment (start, one step) is compared whole, as the default score does,
    # in units of each variable's spread over the training states.
    scaled = (ahead - T[1:]) / pipe[-1].state_scale_
    expected = np.sqrt(np.sum(scaled**2) / (2 * T[1:].size))
    Xt = pipe[:-1].transform(X[40:41])
    assert multistep_errors(pipe[-1], Xt, n_steps=1)[0] == pytest.approx(expected, rel=1e-10)
    # The bare regressor takes the layout.
    assert score(pipe[-1], pipe[:-1].transform(X[40:])) == pytest.approx(clean, rel=1e-12)


def test_multistep_scorer_gives_zero_for_a_blown_up_model(clean_pendulum_fit):
    X, pipe = clean_pendulum_fit
    broken = clone(pipe).fit(X[:40])
    broken[-1].coef_ = broken[-1].coef_ * 1e6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert np.isinf(multistep_errors(broken[-1], broken[:-1].transform(X[40:]), 5)).all()
        assert multistep_scorer(5)(broken, X[40:]) == 0.0


@pytest.mark.parametrize("kwargs", [dict(n_steps=0), dict(n_steps=2.5), dict(stride=0)])
def test_multistep_scorer_validates(kwargs):
    with pytest.raises(ValueError, match="must be a positive integer"):
        multistep_scorer(**kwargs)


def test_multistep_scorer_needs_trajectories(clean_pendulum_fit):
    _, pipe = clean_pendulum_fit
    with pytest.raises(ValueError, match="needs trajectories"):
        multistep_scorer(3)(pipe[-1], np.zeros((5, 2)))


# --------------------------------------------------------------------------
# Ragged held-out data: one batch per time grid, whatever the lengths


def test_ragged_rollouts_share_one_batch_and_match_rollouts_one_by_one(clean_pendulum_fit):
    X, pipe = clean_pendulum_fit
    ragged = [T[: 8 + k % 13] for k, T in enumerate(X[40:])]
    Xt = pipe[:-1].transform(ragged)
    rel = [t - t[0] for t in unpack_derivatives(Xt).times]
    assert len(shared_grids(rel)) == 1  # 13 lengths, one step: one batch
    together = multistep_errors(pipe[-1], Xt)
    alone = np.concatenate([multistep_errors(pipe[-1], [T]) for T in Xt])
    np.testing.assert_allclose(together, alone, rtol=1e-12)
    # Short predictions from every observation too.
    together = multistep_errors(pipe[-1], Xt, n_steps=6)
    alone = np.concatenate([multistep_errors(pipe[-1], [T], n_steps=6) for T in Xt])
    np.testing.assert_allclose(together, alone, rtol=1e-12)


@pytest.mark.parametrize("method", ["rk4", "avf"])
def test_irregular_stamps_integrate_side_by_side_as_each_would_alone(clean_pendulum_fit,
                                                                     method):
    # A lab clock's stamps: no two records share them. Side by side, each
    # takes the steps it would take alone (a step fit's AVF included, whose
    # map is the step it was fitted at).
    _, pipe = clean_pendulum_fit
    integrator = pipe[-1]._integrator(method)
    rng = np.random.default_rng(0)
    grids = np.cumsum(0.05 * (1 + 0.4 * rng.uniform(-1, 1, (6, 12))), axis=1)
    grids -= grids[:, :1]
    y0 = rng.uniform(-1, 1, (6, 2))
    max_steps = np.full(6, 0.02)
    grids[0, 8:] = grids[0, 7]  # a member that ends at its eighth time waits there
    Y, failed = integrate_own_grids(integrator, y0, grids, max_steps)
    assert not failed.any()
    for row in range(6):
        n = 8 if row == 0 else 12
        alone, _ = integrate(integrator, y0[row:row + 1], grids[row, :n], 0.02)
        np.testing.assert_allclose(Y[row, :n], alone[:, 0], rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(Y[0, 8:], np.broadcast_to(Y[0, 7], (4, 2)))


def test_rollouts_on_irregular_stamps_share_a_batch_and_match_rollouts_one_by_one(
        clean_pendulum_fit):
    X, pipe = clean_pendulum_fit
    rng = np.random.default_rng(1)
    t = np.cumsum(0.05 * (1 + 0.3 * rng.uniform(-1, 1, (20, X.shape[1]))), axis=1)
    # Ragged too: records of 12 to 21 samples.
    stamped = [np.column_stack([tk - tk[0], T])[: 12 + k % 10]
               for k, (tk, T) in enumerate(zip(t, X[40:]))]
    Xt = DerivativeTransformer(method="finite_difference").fit_transform(stamped)
    rel = [tk - tk[0] for tk in unpack_derivatives(Xt).times]
    batches, own = _own_grids(shared_grids(rel), rel)
    assert batches == [] and own == [list(range(20))]
    together = multistep_errors(pipe[-1], Xt)
    alone = np.concatenate([multistep_errors(pipe[-1], [T]) for T in Xt])
    np.testing.assert_allclose(together, alone, rtol=1e-10)


def test_different_steps_or_irregular_stamps_do_not_share_a_batch():
    t = 0.1 * np.arange(11)
    bumped = t.copy()
    bumped[5] += 0.03
    groups = shared_grids([t, t[:6], 2 * t, bumped, bumped.copy(), t[:1]])
    # Same step (any length) together; twice the step apart; identical
    # irregular stamps together; a single sample predicts nothing.
    assert groups == [[0, 1], [2], [3, 4]]


def test_a_failure_after_a_members_end_does_not_count_against_it():
    # dy/dt = y**2 from y = 1 blows up at t = 1.
    integrator = RK4(lambda y: y**2)
    grid = 0.1 * np.arange(21)
    y0 = np.ones((3, 1))
    Y, failed = integrate_prefixes(integrator, y0, grid, np.array([5, 21, 9]), 0.01)
    assert failed.tolist() == [False, True, False]
    # Each member as if integrated alone over its own times.
    for member, length in ((0, 5), (2, 9)):
        alone, failed_at = integrate(integrator, y0[:1], grid[:length], 0.01)
        assert failed_at[0] == length
        np.testing.assert_array_equal(Y[member, :length], alone[:, 0])
        assert np.isnan(Y[member, length:]).all()
    np.testing.assert_allclose(Y[0, :5, 0], 1 / (1 - grid[:5]), rtol=1e-6)


# --------------------------------------------------------------------------
# Long records: segments and blocked cross-validation


def test_segments_keep_every_sample_once_and_in_order():
    rng = np.random.default_rng(0)
    X = [rng.normal(size=(n, 3)) for n in (103, 40, 19)]
    for tail in ("merge", "keep"):
        segments, groups = segment_trajectories(X, 20, tail=tail)
        assert isinstance(segments, list) and len(segments) == groups.shape[0]
        np.testing.assert_array_equal(np.concatenate(segments), np.concatenate(X))
        lengths = [S.shape[0] for S in segments]
        if tail == "merge":  # 103 = 20 * 4 + 23; 40 = 2 * 20; 19 stays whole
            assert lengths == [20, 20, 20, 20, 23, 20, 20, 19]
        else:
            assert lengths == [20, 20, 20, 20, 20, 3, 20, 20, 19]
        np.testing.assert_array_equal(groups, np.arange(len(segments)))


def test_segments_of_equal_length_stay_an_array_with_contiguous_groups():
    X = np.arange(2 * 100 * 3, dtype=float).reshape(2, 100, 3)
    segments, groups = segment_trajectories(X, 10, n_groups=3)
    assert segments.shape == (20, 10, 3)
    np.testing.assert_array_equal(segments.reshape(-1, 3), X.reshape(-1, 3))
    assert groups.tolist() == [0] * 7 + [1] * 7 + [2] * 6
    # GroupKFold holds out one contiguous stretch per fold.
    for _, test in GroupKFold(3).split(segments, groups=groups):
        assert np.all(np.diff(test) == 1)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(segment_length=1), "segment_length must be an integer of at least 2"),
        (dict(segment_length=2.5), "segment_length must be an integer"),
        (dict(segment_length=10, tail="drop"), "tail must be 'merge'"),
        (dict(segment_length=10, n_groups=11), r"n_groups must be .* \(10 of 10 samples"),
        (dict(segment_length=10, n_groups=0), "n_groups must be"),
    ],
)
def test_segment_errors_name_the_argument(kwargs, match):
    with pytest.raises(ValueError, match=match):
        segment_trajectories(np.zeros((1, 100, 2)), **kwargs)


def test_blocked_cross_validation_of_one_long_noisy_record():
    """One pendulum record, 2 001 samples at dt = 0.01, +-2 % noise, cut in 41s.

    Default transformer settings (one degree-5 polynomial per segment, as for
    the paper's bursts), HamiltonianRegressor(6), 5 contiguous blocks.
    Measured: fold scores 0.980-0.985 (noise seeds 0, 1 and 2).
    """
    system, dt = single_pendulum(), 0.01
    t = dt * np.arange(2001)
    clean = system.solve(system.initial_state, t, max_step=dt / 10)
    record = clean * (1 + np.random.default_rng(0).uniform(-0.02, 0.02, clean.shape))
    # Time stamps ride along as the first column.
    segments, groups = segment_trajectories(np.column_stack([t, record])[None], 41, n_groups=5)
    assert len(segments) == 48 and segments[-1].shape == (74, 3)  # 2001 = 47 * 41 + 74
    pipe = make_pipeline(DerivativeTransformer(), HamiltonianRegressor(6))
    scores = cross_val_score(pipe, segments, groups=groups, cv=GroupKFold(5))
    assert scores.min() >= 0.9, scores
