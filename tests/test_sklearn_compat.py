"""scikit-learn conformance: the common checks, plus our own on trajectory data.

``HamiltonianRegressor`` learns a Hamiltonian, so its target is the time
derivative of every state variable (``y`` has the shape of ``X``) and the number
of state variables is even. The common checks generate data without that
structure; the checks that fail for that reason alone are listed below with the
reason, and run in strict mode, so a check that starts passing must be removed
from the list. The same properties are then checked on valid data in this file.

``DerivativeTransformer`` and ``HamiltonianSearchCV`` take 3-D trajectory
arrays, so they declare ``two_d_array=False`` and scikit-learn skips their
common checks; the transformer's conformance tests on trajectories are below,
the search's in tests/test_search.py.
"""

import pickle

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.utils.estimator_checks import check_estimator, parametrize_with_checks

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from sk_hamiltonian.model_selection import HamiltonianSearchCV

ODD = "the generated X has an odd number of features; Hamiltonian states come in (p, q) pairs"
Y_SHAPE = "the generated y does not have the shape of X; the target is dX/dt of every state"

HAMILTONIAN_EXPECTED_FAILURES = {
    "check_fit_score_takes_y": ODD,
    "check_dont_overwrite_parameters": ODD,
    "check_estimators_dtypes": ODD,
    "check_pipeline_consistency": ODD,
    "check_estimators_nan_inf": ODD,
    "check_estimators_pickle": ODD,
    "check_f_contiguous_array_estimator": ODD,
    "check_methods_sample_order_invariance": ODD,
    "check_methods_subset_invariance": ODD,
    "check_dict_unchanged": ODD,
    "check_fit2d_predict1d": ODD,
    "check_estimators_overwrite_params": Y_SHAPE,
    "check_estimators_fit_returns_self": Y_SHAPE,
    "check_readonly_memmap_input": Y_SHAPE,
    "check_n_features_in_after_fitting": Y_SHAPE,
    "check_positive_only_tag_during_fit": Y_SHAPE,
    "check_dtype_object": Y_SHAPE,
    "check_regressors_train": Y_SHAPE,
    "check_regressor_data_not_an_array": Y_SHAPE,
    "check_regressor_multioutput": Y_SHAPE,
    "check_regressors_no_decision_function": Y_SHAPE,
    "check_regressors_int": Y_SHAPE,
    "check_fit_idempotent": Y_SHAPE,
    "check_fit_check_is_fitted": Y_SHAPE,
    "check_n_features_in": Y_SHAPE,
    "check_sample_weights_pandas_series": Y_SHAPE,
    "check_sample_weights_not_an_array": Y_SHAPE,
    "check_sample_weights_list": ODD,
    "check_sample_weights_shape": Y_SHAPE,
    "check_sample_weights_not_overwritten": Y_SHAPE,
    "check_sample_weight_equivalence_on_dense_data": Y_SHAPE,
    "check_fit2d_1sample": Y_SHAPE,
}


# What each reason says the failing fit must have complained about.
REASON_MESSAGES = {ODD: "must be even", Y_SHAPE: "same shape as X"}


def expected_failed_checks(estimator):
    if isinstance(estimator, HamiltonianRegressor):
        return HAMILTONIAN_EXPECTED_FAILURES
    return {}


def is_slow(estimator, check):
    """The one common check that takes seconds (20 s on two busy cores), not milliseconds.

    The weighted sparse fit on the generated data (hundreds of unknowns per
    component) runs its thresholding iterations many times;
    test_sparse_fit_weights_equal_repeated_samples checks the same property
    on a small problem in the default run.
    """
    return (isinstance(estimator, VectorFieldRegressor) and estimator.threshold > 0
            and getattr(check, "func", check).__name__
            == "check_sample_weight_equivalence_on_dense_data")


def with_slow_marks(parametrize):
    """``parametrize`` with the cases that ``is_slow`` picks marked slow."""
    argnames, cases = parametrize.args
    marked = []
    for case in cases:
        # Expected failures come as pytest.param(..., marks=xfail), the rest as tuples.
        values, marks = (case.values, list(case.marks)) if hasattr(case, "marks") else (case, [])
        if is_slow(*values):
            marks.append(pytest.mark.slow)
        marked.append(pytest.param(*values, marks=marks))
    return pytest.mark.parametrize(argnames, marked, **parametrize.kwargs)


# VectorFieldRegressor is a general polynomial regressor; at its default degree
# the generated problems (up to 10 features, a few samples) are underdetermined,
# and it returns the minimum-norm least-squares solution (with a warning).
@with_slow_marks(parametrize_with_checks(
    [
        HamiltonianRegressor(), VectorFieldRegressor(), DerivativeTransformer(dt=0.1),
        HamiltonianSearchCV(dt=0.1),
        # Sparse fits take the same paths through validation and fitting.
        HamiltonianRegressor(threshold=0.05), VectorFieldRegressor(threshold=0.05),
        # Columns (q, p): exchanged on the way in and out of every method.
        HamiltonianRegressor(state_order="qp"),
    ],
    expected_failed_checks=expected_failed_checks,
    xfail_strict=True,
))
def test_sklearn_common_checks(estimator, check):
    check(estimator)


@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
def test_sparse_fit_weights_equal_repeated_samples(Regressor):
    """check_sample_weight_equivalence_on_dense_data's property, on a small sparse fit."""
    X, y = hamiltonian_data(n_samples=40)
    weights = np.random.default_rng(2).integers(0, 4, size=X.shape[0])
    model = Regressor(degree=4, threshold=0.05)
    weighted = clone(model).fit(X, y, sample_weight=weights)
    repeated = clone(model).fit(np.repeat(X, weights, axis=0), np.repeat(y, weights, axis=0))
    assert 0 < np.count_nonzero(weighted.coef_) < weighted.coef_.size  # the threshold acted
    assert np.allclose(weighted.coef_, repeated.coef_, rtol=1e-7, atol=1e-9)
    assert np.allclose(weighted.predict(X), repeated.predict(X), rtol=1e-7, atol=1e-9)


def _messages(error):
    """The message of an error and of every error it was raised from."""
    while error is not None:
        yield str(error)
        error = error.__cause__ or error.__context__


def test_expected_failures_fail_for_the_stated_reason():
    # A strict xfail only says that a check fails; this says why.
    results = check_estimator(HamiltonianRegressor(), on_fail=None)
    seen = set()
    for result in results:
        name = result["check_name"]
        if name not in HAMILTONIAN_EXPECTED_FAILURES or result["status"] != "failed":
            continue
        expected = REASON_MESSAGES[HAMILTONIAN_EXPECTED_FAILURES[name]]
        assert any(expected in m for m in _messages(result["exception"])), name
        seen.add(name)
    assert seen == set(HAMILTONIAN_EXPECTED_FAILURES)


def hamiltonian_data(n_samples=60, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1, 1, size=(n_samples, 2))
    y = np.column_stack([-np.sin(X[:, 1]), X[:, 0]])  # pendulum, H = p^2/2 - cos q
    return X, y


def trajectories(n=6, n_times=12, seed=0):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, n_times, 2)).cumsum(axis=1) * 0.1


def test_hamiltonian_regressor_api_on_valid_data():
    X, y = hamiltonian_data()
    model = HamiltonianRegressor(degree=4)
    with pytest.raises(NotFittedError):
        model.predict(X)
    assert model.fit(X, y) is model
    assert model.n_features_in_ == 2
    prediction = model.predict(X)
    # Pickle round trip, idempotent refit, sample-order and subset invariance,
    # float32 and read-only input.
    assert np.array_equal(pickle.loads(pickle.dumps(model)).predict(X), prediction)
    assert np.allclose(clone(model).fit(X, y).predict(X), prediction)
    order = np.random.default_rng(1).permutation(X.shape[0])
    assert np.allclose(model.predict(X[order]), prediction[order])
    assert np.allclose(model.predict(X[:7]), prediction[:7])
    assert np.allclose(HamiltonianRegressor(degree=4).fit(X[order], y[order]).coef_, model.coef_)
    assert np.allclose(model.predict(X.astype(np.float32)), prediction, atol=1e-5)
    X_ro, y_ro = X.copy(), y.copy()
    X_ro.flags.writeable = y_ro.flags.writeable = False
    assert np.allclose(HamiltonianRegressor(degree=4).fit(X_ro, y_ro).coef_, model.coef_)
    # Fitting leaves the parameters and the input alone.
    assert model.get_params() == HamiltonianRegressor(degree=4).get_params()
    assert np.array_equal(X, hamiltonian_data()[0])


def test_feature_names_are_checked():
    pd = pytest.importorskip("pandas")
    X, y = hamiltonian_data()
    frame = pd.DataFrame(X, columns=["p", "q"])
    model = HamiltonianRegressor(degree=3).fit(frame, y)
    assert list(model.feature_names_in_) == ["p", "q"]
    with pytest.warns(UserWarning, match="feature names"):
        model.predict(X)


def test_derivative_transformer_api_on_trajectories():
    X = trajectories()
    transformer = DerivativeTransformer(dt=0.1, degree=3)
    with pytest.raises(NotFittedError):
        transformer.transform(X)
    assert transformer.fit(X) is transformer
    out = transformer.transform(X)
    assert out.shape == (6, 12, 7)
    assert np.array_equal(transformer.fit_transform(X), out)
    assert np.array_equal(pickle.loads(pickle.dumps(transformer)).transform(X), out)
    order = np.random.default_rng(1).permutation(6)
    assert np.array_equal(transformer.transform(X[order]), out[order])
    assert transformer.get_params() == {
        "dt": 0.1, "method": "polynomial", "degree": 3, "window": "auto", "smooth_states": True
    }
    assert np.array_equal(X, trajectories())
    tags = transformer.__sklearn_tags__()
    assert tags.input_tags.three_d_array and not tags.input_tags.two_d_array
