"""Smoke test of ``benchmarks/sindy_anchor.py``, the cross-validated PySINDy anchor.

Tiny data and grids: the outputs' shapes, the pieces that replace PySINDy's own
loops (batched smoothing, the weak matrices, the QR-reduced STLSQ) checked
against PySINDy, and the honesty of the cross-validation (no system, no truth:
the system's solver and vector field raise while it runs). Skipped when
pysindy is not importable.
"""

import inspect
import sys
from pathlib import Path

import numpy as np
import pytest

ps = pytest.importorskip("pysindy")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import sindy_anchor as S  # noqa: E402

from sk_hamiltonian.datasets import (  # noqa: E402
    HamiltonianSystem,
    make_trajectories,
    single_pendulum,
)

PENDULUM_LIBRARY = dict(poly_degree=2, fourier=1, angles=[1])
SMALL = dict(thresholds=(0.0, 0.1, 1.0), windows=(11, 21),
             weak_grid=dict(K=(20,), width=(0.125, 0.25)), n_models=5)


@pytest.fixture(scope="module")
def pendulum():
    X = make_trajectories(single_pendulum(), 40, 20, dt=0.01, noise=0.02, random_state=0)
    # Four folds: with two, the paired one-standard-error rule makes any
    # candidate eligible that beats the best in one fold (mean <= se whenever
    # one of two differences is <= 0), and it chose the sparsest such one,
    # which drops dq/dt = p at the threshold 1.0.
    folds = np.array_split(np.arange(40), 4)
    return X, folds


def refuse(*args, **kwargs):
    raise AssertionError("the cross-validation read the true system")


def without_truth(mp):
    """Make the systems' solver and vector field raise: the CV must not need them."""
    for name in ("solve", "vector_field", "hamiltonian", "_field"):
        mp.setattr(HamiltonianSystem, name, refuse)


@pytest.fixture(scope="module")
def anchors(pendulum):
    X, folds = pendulum
    with pytest.MonkeyPatch.context() as mp:
        without_truth(mp)
        return {weak: S.fit_sindy_cv(X, 0.01, library=PENDULUM_LIBRARY, folds=folds,
                                     weak=weak, seed=0, **SMALL)
                for weak in (False, True)}


def test_signature_takes_no_system():
    names = set(inspect.signature(S.fit_sindy_cv).parameters)
    assert names == {"X", "dt", "library", "folds", "weak", "seed", "thresholds", "windows",
                     "weak_grid", "n_models", "rule"}


@pytest.mark.parametrize("weak", [False, True])
def test_anchor_outputs(anchors, pendulum, weak):
    X, _ = pendulum
    anchor = anchors[weak]
    assert anchor.weak is weak
    n_features = len(anchor.feature_names)
    assert n_features == 9  # p-quadratic times (1, sin q, cos q)
    assert anchor.coef.shape == (2, n_features)
    assert anchor.n_terms == np.count_nonzero(anchor.coef) and 1 <= anchor.n_terms < 2 * 9
    states = X[:3, :5].reshape(-1, 2)
    dX = anchor.rhs(states)
    assert dX.shape == states.shape and np.isfinite(dX).all()
    np.testing.assert_allclose(
        dX, np.asarray(anchor.library.transform(states)) @ anchor.coef.T, rtol=1e-10, atol=1e-10)
    if not weak:
        np.testing.assert_allclose(dX, np.asarray(anchor.model.predict(states)),
                                   rtol=1e-10, atol=1e-10)
    t = np.linspace(0.0, 0.5, 11)
    Y = anchor.simulate(X[:4, 0], t)
    assert Y.shape == (4, 11, 2) and np.isfinite(Y).all()
    np.testing.assert_array_equal(Y[:, 0], X[:4, 0])
    assert anchor.simulate(X[0, 0], t).shape == (11, 2)
    # The grid and the table: every candidate once, one chosen, its params reported.
    n_settings = 2  # windows (11, 21), or K=20 x widths (0.125, 0.25)
    assert len(anchor.cv_table) == n_settings * 3
    chosen = [row for row in anchor.cv_table if row["chosen"]]
    assert len(chosen) == 1 and chosen[0]["eligible"]
    keys = {"K", "width", "threshold"} if weak else {"window", "threshold"}
    assert set(anchor.params) == keys
    assert all(anchor.params[k] == chosen[0][k] for k in keys)
    for row in anchor.cv_table:
        assert len(row["fold_scores"]) == 4
        assert all(0 <= s <= 1 for s in row["fold_scores"])
    best = min(row["mean_score"] for row in anchor.cv_table)
    assert chosen[0]["mean_score"] <= best + chosen[0]["se"] + 1e-15
    assert anchor.fit_time > 0
    # The pendulum's own two terms, from 2 % noise: dq/dt = p, dp/dt = -9.8 sin q.
    names = anchor.library.get_feature_names(["p", "q"])
    assert anchor.coef[1, names.index("p")] == pytest.approx(1.0, rel=0.05)
    assert anchor.coef[0, names.index("1 sin(1 q)")] == pytest.approx(-9.8, rel=0.05)


def test_score_is_zero_for_the_truth_and_the_noise_on_noisy_data():
    """Exact field on clean data scores ~0; the same data with noise scores the noise."""
    system = single_pendulum()
    X, clean = make_trajectories(system, 6, 20, dt=0.01, noise=0.05, random_state=1,
                                 return_clean=True)
    scale = clean.reshape(-1, 2).std(axis=0)
    exact = S.shooting_errors(system.vector_field, clean, 0.01, scale, np.array([1]))
    assert exact.max() < 1e-6
    noisy = S.shooting_errors(system.vector_field, X, 0.01, scale, np.array([1]))
    assert 0.005 < np.median(noisy) < 0.2


def test_batched_smoothing_equals_pysindy_per_trajectory(pendulum):
    X, _ = pendulum
    states, derivatives = S.smooth(ps, X[:5], 0.01, 11)
    for k in range(5):
        method = ps.SmoothedFiniteDifference(smoother_kws=dict(window_length=11, polyorder=3))
        d = np.asarray(method(X[k], t=0.01))
        np.testing.assert_allclose(derivatives[k], d, rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(states[k], np.asarray(method.smoothed_x_), atol=1e-12)


# PySINDy's own transform warns about its axes labels; not ours to fix.
@pytest.mark.filterwarnings("ignore:2 axes labeled")
def test_weak_matrices_equal_weak_pde_library(pendulum):
    """Our weak system is PySINDy's on a library WeakPDELibrary can take."""
    X, _ = pendulum
    X = X[:3]
    n_times = X.shape[1]
    function_library = ps.PolynomialLibrary(degree=3)
    weak_lib = S.weak_library(ps, function_library, n_times, 0.01, 15, 0.25, seed=3)
    W0, Wt = S.weak_weights(weak_lib, n_times)
    spec = S.LibrarySpec.parse(dict(poly_degree=3), 2)
    features = S.LibraryFeatures(spec, ps.PolynomialLibrary(degree=3).fit(X[0]), X[0])
    Theta = features(X.reshape(-1, 2)).reshape(3, n_times, -1)
    A, B = S.weak_system(W0, Wt, Theta, X)
    theirs = weak_lib.fit(list(X)).transform(list(X))
    for k in range(3):
        np.testing.assert_allclose(A[k], np.asarray(theirs[k]), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(B[k], weak_lib.convert_u_dot_integral(X[k]),
                                   rtol=1e-10, atol=1e-12)


def test_reduced_stlsq_equals_full(pendulum):
    X, _ = pendulum
    states, derivatives = S.smooth(ps, X, 0.01, 11)
    spec = S.LibrarySpec.parse(PENDULUM_LIBRARY, 2)
    library = spec.pysindy(ps, 2).fit(X[0])
    features = S.LibraryFeatures(spec, library, X[0])
    A, B = features(states.reshape(-1, 2)), derivatives.reshape(-1, 2)
    R, QB = S._reduced(A, B)
    for threshold in (0.0, 0.1, 1.0):
        full = S._coefficients(ps, A, B, threshold)
        reduced = S._coefficients(ps, R, QB, threshold)
        np.testing.assert_array_equal(full != 0, reduced != 0)
        np.testing.assert_allclose(reduced, full, rtol=1e-8, atol=1e-8)


@pytest.mark.parametrize("library, n_features", [
    (dict(poly_degree=4), 15),
    (dict(poly_degree=2, fourier=1, angles=[1], mixed=True), 12),
    (dict(poly_degree=1, fourier=2, angles=[2, 3]), 3 * 25),  # (1, p1, p2) x 5 x 5
])
def test_library_features_match_pysindy(library, n_features):
    n_states = 4 if 3 in library.get("angles", []) else 2
    spec = S.LibrarySpec.parse(library, n_states)
    states = np.random.default_rng(0).uniform(-2, 2, size=(50, n_states))
    pysindy_library = spec.pysindy(ps, n_states).fit(states)
    features = S.LibraryFeatures(spec, pysindy_library, states)  # raises if no match
    assert features.n_features == n_features
    np.testing.assert_allclose(features(states), np.asarray(pysindy_library.transform(states)),
                               rtol=1e-12, atol=1e-12)
    columns = np.array([0, n_features - 1])
    np.testing.assert_allclose(features(states, columns), features(states)[:, columns])


def test_duffing_polynomial_scene(monkeypatch):
    X = make_trajectories(S.duffing(), 40, 20, dt=0.05, noise=0.01, random_state=0)
    without_truth(monkeypatch)
    anchor = S.fit_sindy_cv(X, 0.05, library=dict(poly_degree=4),
                            folds=[np.arange(20), np.arange(20, 40)], **SMALL)
    names = anchor.library.get_feature_names(["p", "q"])
    kept = {(i, names[j]) for i, j in zip(*np.nonzero(anchor.coef))}
    assert {(0, "q"), (0, "q^3"), (1, "p")} <= kept
    assert anchor.coef[0, names.index("q^3")] == pytest.approx(-1.0, rel=0.1)
    # A cubic field blows up from a huge state: NaN from there on, no exception.
    Y = anchor.simulate(np.array([[1e100, 1e100], [0.1, 0.2]]), np.linspace(0, 1, 5))
    assert np.isnan(Y[0, -1]).all()
    assert np.isfinite(Y[1]).all()


@pytest.mark.parametrize("library, message", [
    ("poly", "must be a dict"),
    (dict(degree=2), "unknown keys"),
    (dict(poly_degree=0), "poly_degree"),
    (dict(poly_degree=2, fourier=1), "both 'fourier' and 'angles'"),
    (dict(poly_degree=2, fourier=1, angles=[5]), "distinct indices"),
    (dict(poly_degree=2, mixed=True), "needs 'fourier'"),
])
def test_bad_library_is_named(pendulum, library, message):
    X, folds = pendulum
    with pytest.raises(ValueError, match=message):
        S.fit_sindy_cv(X, 0.01, library=library, folds=folds)


@pytest.mark.parametrize("folds, message", [
    ([np.arange(10)], "at least 2"),
    ([np.arange(40), np.arange(5)], "between 1 and n_traj - 1"),
    ([np.array([], dtype=int), np.arange(5)], "between 1 and n_traj - 1"),
])
def test_bad_folds_are_named(pendulum, folds, message):
    X, _ = pendulum
    with pytest.raises(ValueError, match=message):
        S.fit_sindy_cv(X, 0.01, library=PENDULUM_LIBRARY, folds=folds)


def test_window_one_is_pysindy_finite_difference(pendulum):
    X, _ = pendulum
    states, derivatives = S.smooth(ps, X[:2], 0.01, 1)
    np.testing.assert_array_equal(states, X[:2])
    for k in range(2):
        np.testing.assert_allclose(derivatives[k], np.asarray(ps.FiniteDifference()(X[k], t=0.01)),
                                   rtol=1e-12, atol=1e-10)
