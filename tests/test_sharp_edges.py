"""Sharp edges a new user met, each turned into a clear error or warning.

Each test is named after what it protects.
"""

import re
import warnings

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    VectorFieldRegressor,
)


@pytest.fixture(scope="module")
def pendulum():
    rng = np.random.default_rng(0)
    X = rng.uniform([-2, -1.5], [2, 1.5], size=(200, 2))
    y = np.column_stack([-np.sin(X[:, 1]), X[:, 0]])
    return X, y, HamiltonianRegressor(degree=6).fit(X, y)


def test_state_constant_up_to_round_off_is_refused_not_fitted():
    # After smoothing, a constant variable can differ from itself by 1e-15: a
    # bounding box that thin makes predictions explode just outside it.
    X = np.column_stack([np.linspace(-1, 1, 50), 1.0 - 1e-15 * np.arange(50) % 2])
    with pytest.raises(ValueError, match=r"\[1\] are constant.*explicit `domain`"):
        HamiltonianRegressor(degree=2).fit(X, X)


@pytest.mark.parametrize("name", ["degree", "momentum_degree", "max_interaction"])
@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
def test_boolean_integer_parameters_are_refused(pendulum, Regressor, name):
    X, y, _ = pendulum
    with pytest.raises(ValueError, match=f"'{name}' parameter.*not a boolean"):
        Regressor(**{name: True}).fit(X, y)


def test_one_dimensional_domain_names_the_expected_shape(pendulum):
    X, y, _ = pendulum
    with pytest.raises(ValueError, match=r"domain must have shape \(2, 2\)"):
        HamiltonianRegressor(domain=[-1, 1]).fit(X, y)


def test_complex_states_are_refused_not_truncated(pendulum):
    _, _, model = pendulum
    Z = np.ones((2, 3, 2)) * (1 + 1j)
    for method in (model.hamiltonian, model.gradient):
        with pytest.raises(ValueError, match="[Cc]omplex"):
            method(Z)


def test_hamiltonian_and_gradient_warn_outside_the_domain_like_predict(pendulum):
    _, _, model = pendulum
    outside = np.array([[5.0, 0.0]])
    for method in (model.predict, model.hamiltonian, model.gradient):
        with pytest.warns(DomainWarning, match="outside the domain"):
            method(outside)


def test_single_state_needs_a_leading_axis_everywhere(pendulum):
    _, _, model = pendulum
    for method in (model.predict, model.hamiltonian, model.gradient):
        with pytest.raises(ValueError, match="2D array|x\\[None\\]"):
            method(np.array([0.1, 0.2]))
    # Leading axes are fine for hamiltonian and gradient (e.g. simulate output).
    assert model.hamiltonian(np.zeros((3, 4, 2))).shape == (3, 4)


def test_score_on_states_without_derivatives_says_what_it_needs(pendulum):
    X, _, model = pendulum
    with pytest.raises(ValueError, match="score needs y.*derivative layout"):
        model.score(X)


def test_zero_weight_samples_do_not_stretch_the_domain(pendulum):
    X, y, _ = pendulum
    far = np.vstack([X, [[50.0, 50.0]]])
    weights = np.r_[np.ones(len(X)), 0.0]
    model = HamiltonianRegressor(degree=6).fit(far, np.vstack([y, [[0.0, 0.0]]]), weights)
    assert np.allclose(model.domain_, HamiltonianRegressor(degree=6).fit(X, y).domain_)


def test_sample_weight_per_trajectory_through_a_pipeline():
    rng = np.random.default_rng(1)
    t = 0.05 * np.arange(30)
    phases = rng.uniform(0, 2 * np.pi, size=12)
    amplitudes = rng.uniform(0.5, 1.5, size=12)
    X = np.stack([a * np.column_stack([-np.sin(t + s), np.cos(t + s)])
                  for a, s in zip(amplitudes, phases)])
    pipe = make_pipeline(DerivativeTransformer(dt=0.05, degree=6), HamiltonianRegressor(degree=2))
    weights = rng.integers(1, 4, size=12)
    weighted = pipe.fit(X, hamiltonianregressor__sample_weight=weights)[-1].coef_.copy()
    repeated = pipe.fit(np.repeat(X, weights, axis=0))[-1].coef_
    # Integer weights are repetitions of whole trajectories.
    assert np.allclose(weighted, repeated, rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match=r"one weight per trajectory, shape \(12,\)"):
        pipe.fit(X, hamiltonianregressor__sample_weight=np.ones(5))


def test_underdetermined_baseline_gives_minimum_norm_fit_with_a_warning():
    from sk_hamiltonian import IllConditionedWarning

    rng = np.random.default_rng(2)
    X = rng.uniform(-1, 1, size=(8, 4))
    y = rng.normal(size=(8, 4))
    with pytest.warns(IllConditionedWarning, match="rank 8 of 35"):
        model = VectorFieldRegressor(degree=3).fit(X, y)
    # It interpolates the data.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)
        assert np.allclose(model.predict(X), y, atol=1e-8)


def test_pipeline_predict_on_states_points_to_the_regressor():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(6, 20, 2)).cumsum(axis=1) * 0.1
    pipe = make_pipeline(DerivativeTransformer(dt=0.1, degree=3), HamiltonianRegressor(degree=2))
    pipe.fit(X)
    states = X[0]
    with pytest.raises(ValueError, match=r"pipe\[-1\]\.predict\(states\)"):
        pipe.predict(states)
    assert pipe[-1].predict(states).shape == states.shape


@pytest.mark.parametrize("make", [
    lambda X: X.transpose(0, 2, 1),
    lambda X: [T.T for T in X],
    lambda X: [X[0].T, X[1, :30].T],
], ids=["array", "list", "list_of_lengths"])
@pytest.mark.parametrize("method", ["finite_difference", "polynomial"])
def test_transposed_trajectories_are_named_as_such_in_one_line(make, method):
    from sk_hamiltonian.datasets import make_trajectories, single_pendulum

    X = make_trajectories(single_pendulum(), 100, 40, dt=0.01, random_state=0)
    with pytest.raises(ValueError) as error:
        DerivativeTransformer(dt=0.01, method=method).fit(make(X))
    message = str(error.value)
    assert "looks transposed" in message and "\n" not in message
    assert "sample(s)" not in message  # not "has 2 sample(s)"
    if isinstance(make(X), np.ndarray):
        assert "X has shape (100, 2, 41)" in message
        assert "pass X.transpose(0, 2, 1), of shape (100, 41, 2)" in message
    else:
        assert "pass [T.T for T in X]" in message
    # The code the message gives turns the input back into trajectories.
    fix = re.search(r"pass (.*?)(?:, of shape|\.$)", message).group(1)
    fixed = eval(fix, {"X": make(X)})  # noqa: S307 (the message's own code)
    DerivativeTransformer(dt=0.01, method=method).fit(fixed)


def test_short_trajectories_are_not_called_transposed():
    # Two samples of two variables: too short, not transposed (the long axis
    # is neither); the message keeps to the samples.
    X = np.random.default_rng(0).normal(size=(5, 2, 2))
    with pytest.raises(ValueError, match=r"has 2 sample\(s\); at least 3") as error:
        DerivativeTransformer(dt=0.1, method="finite_difference").fit(X)
    assert "transposed" not in str(error.value)


@pytest.mark.parametrize("x0", ["a", ["a", "b"], [[1.0, 2.0], [3.0]], {"p": 1.0}])
def test_initial_states_that_are_not_numbers_name_x0(pendulum, x0):
    *_, model = pendulum
    with pytest.raises(ValueError, match=r"^x0 must be numbers: one initial state of 2 values "
                                         r"\(p_1\.\.p_d, q_1\.\.q_d\), or several as the rows"):
        model.simulate(x0, np.linspace(0, 1, 5))


@pytest.mark.parametrize("x0", ["a", [[1.0, 2.0], [3.0]]])
def test_a_systems_initial_states_that_are_not_numbers_name_x0(x0):
    from sk_hamiltonian.datasets import single_pendulum

    with pytest.raises(ValueError, match=r"^x0 must be numbers: one initial state of 2 values"):
        single_pendulum().solve(x0, np.linspace(0, 1, 5))
    with pytest.raises(ValueError, match=r"^t must be a 1-D array of numbers"):
        single_pendulum().solve([0.1, 0.2], "soon")


def test_output_times_that_are_not_numbers_name_t(pendulum):
    *_, model = pendulum
    with pytest.raises(ValueError, match=r"^t must be a 1-D array of numbers, the output times; "
                                         r"got 'soon'\.$"):
        model.simulate([0.1, 0.2], "soon")


@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
def test_negative_sample_weight_names_the_argument(pendulum, Regressor):
    X, y, _ = pendulum
    weight = np.ones(len(X))
    weight[[3, 7]] = -1.0
    with pytest.raises(ValueError, match=r"^sample_weight must be non-negative \(one weight per "
                                         r"state; 0 leaves it out\); got -1 at index 3 and 1 "
                                         r"more negative\. Drop the sign"):
        Regressor(degree=3).fit(X, y, sample_weight=weight)


def test_negative_trajectory_weight_names_the_argument():
    from sk_hamiltonian.datasets import make_trajectories, single_pendulum

    X = make_trajectories(single_pendulum(), 20, 40, dt=0.01, random_state=0)
    pipe = make_pipeline(DerivativeTransformer(dt=0.01), HamiltonianRegressor(degree=4))
    weight = np.ones(20)
    weight[5] = -0.5
    with pytest.raises(ValueError, match=r"^sample_weight must be non-negative \(one weight per "
                                         r"trajectory; 0 leaves it out\); got -0\.5 at index 5\."):
        pipe.fit(X, hamiltonianregressor__sample_weight=weight)


@pytest.mark.parametrize("Regressor", [HamiltonianRegressor, VectorFieldRegressor])
def test_states_that_overflow_the_field_say_nan_was_returned(pendulum, Regressor):
    # Second contact: predict at 1e300 returned NaN with only the domain
    # warning (which says "not trusted", not "NaN").
    X, y, _ = pendulum
    model = Regressor(degree=6).fit(X, y)
    states = np.array([[0.1, 0.2], [1e300, 1e300], [0.3, -0.1]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dXdt = model.predict(states)
    assert not np.isfinite(dXdt[1]).all() and np.isfinite(dXdt[[0, 2]]).all()
    said = [w for w in caught if "returned NaN or inf" in str(w.message)]
    assert len(said) == 1 and issubclass(said[0].category, DomainWarning)
    assert str(said[0].message).startswith(
        "predict returned NaN or inf for 1 of 3 states of X (rows [1]): the learned field "
        "overflows float64 there (largest |X| there 1e+300")
    assert said[0].filename == __file__
    # numpy's own "invalid value encountered" names neither X nor the cause.
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]


def test_hamiltonian_at_states_that_overflow_says_nan_was_returned(pendulum):
    *_, model = pendulum
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        H = model.hamiltonian(np.array([[0.1, 0.2], [1e300, 1e300]]))
    assert np.isfinite(H[0]) and not np.isfinite(H[1])
    (said,) = [w for w in caught if "returned NaN or inf" in str(w.message)]
    assert str(said.message).startswith("hamiltonian returned NaN or inf for 1 of 2 states of X")
