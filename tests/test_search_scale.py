"""HamiltonianSearchCV beyond two degrees of freedom: the automatic spaces and chains."""

import warnings

import numpy as np
import pytest
from sklearn.model_selection import KFold

from sk_hamiltonian import HamiltonianRegressor, SmoothingWarning
from sk_hamiltonian.datasets import HamiltonianSystem, fput_chain, make_trajectories
from sk_hamiltonian.inspection import hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV, angle_like, auto_spaces
from sk_hamiltonian.model_selection._screen import (
    GROSS_MISFIT,
    derivative_layouts,
    screen_layout,
)


def chain_law(n):
    """The monomials of an FPU-beta chain with fixed ends, from its bonds."""
    terms = {f"p{i}^2" for i in range(1, n + 1)}
    terms |= {f"q{i}^{k}" for i in range(1, n + 1) for k in (2, 4)}
    for i in range(1, n):
        a, b = f"q{i}", f"q{i + 1}"
        terms |= {f"{a}*{b}", f"{a}^3*{b}", f"{a}^2*{b}^2", f"{a}*{b}^3"}
    return terms


def quiet_fit(search, X):
    with warnings.catch_warnings():
        # The smoothing and conservation checks of the candidates are not
        # what is tested here.
        warnings.simplefilter("ignore")
        return search.fit(X)


def test_up_to_two_degrees_of_freedom_each_position_is_searched_on_its_own():
    # Angles are looked for in the data only beyond two degrees of freedom.
    for n_states in (2, 4):
        assert auto_spaces(n_states, angles=[True] * (n_states // 2)) == auto_spaces(n_states)
    assert not any("max_interaction" in space for space in auto_spaces(4))


@pytest.mark.parametrize("d", [3, 8])
def test_beyond_two_degrees_of_freedom_the_spaces_couple_variables_pairwise(d):
    spaces = auto_spaces(2 * d)
    assert spaces == [
        {"max_interaction": 2, "solver": "normal"},
        {"momentum_degree": 2, "max_interaction": 2, "solver": "normal"},
        {"momentum_degree": 2, "separable": True, "max_interaction": 2, "solver": "normal"},
    ]


def test_the_automatic_spaces_grow_like_the_square_of_the_degrees_of_freedom():
    def sizes(d):
        return np.array([HamiltonianRegressor(degree=4, **space)._n_terms(2 * d)
                         for space in auto_spaces(2 * d)])

    # Doubling d at most quadruples every space (pairs of variables), where a
    # total-degree space grows about ten times from 8 to 16 states.
    growth = max(np.max(sizes(8) / sizes(4)), np.max(sizes(16) / sizes(8)))
    assert growth <= 4.2
    total = HamiltonianRegressor(degree=4)
    assert total._n_terms(16) / total._n_terms(8) > 2 * growth


def test_angles_are_offered_as_periodic_then_mixed_on_those_positions_only():
    angles = [False, True, False, True]
    flags = [False] * 4 + angles
    spaces = auto_spaces(8, angles=np.array(angles))
    assert len(spaces) == 9
    assert spaces[:3] == auto_spaces(8)
    assert [s.get("periodic") for s in spaces[3:6]] == [flags] * 3
    assert [s.get("mixed") for s in spaces[6:]] == [flags] * 3
    assert not any("mixed" in s for s in spaces[3:6])
    assert not any("periodic" in s for s in spaces[6:])
    assert {s.get("separable", False) for s in spaces[3:]} == {False, True}


@pytest.mark.parametrize("angles, match", [
    ([True, False], "angles must be an array of 3 booleans"),
    ([1, 0, 0], "angles must be an array of 3 booleans"),
])
def test_bad_angles_name_the_argument(angles, match):
    with pytest.raises(ValueError, match=match):
        auto_spaces(6, angles=angles)


def test_angle_like_looks_at_the_span_of_each_position():
    rng = np.random.default_rng(0)
    n = 500
    p = rng.normal(size=(n, 3))
    wrapped = rng.uniform(-np.pi, np.pi, n)          # an angle wrapped into one turn
    librating = 2.5 * np.sin(np.linspace(0, 20, n))  # swings short of a turn
    rotating = np.linspace(0, 30, n)                  # turns round and round
    states = np.column_stack([p, wrapped, librating, rotating])
    np.testing.assert_array_equal(angle_like(states), [True, False, True])
    states[0, 5] = np.nan                             # a missing sample is no span
    np.testing.assert_array_equal(angle_like(states), [True, False, True])
    # Trajectories as a list or a 3-D array: the span over all of them.
    halves = [np.column_stack([p[:, :1], np.full(n, x)]) for x in (-2.5, 2.5)]
    np.testing.assert_array_equal(angle_like(halves), [False])
    np.testing.assert_array_equal(angle_like(np.stack(halves)), [False])
    halves[1][:, 1] = 3.2
    np.testing.assert_array_equal(angle_like(halves), [True])
    with pytest.raises(ValueError, match="states must hold an even number"):
        angle_like(states[:, 1:])


@pytest.fixture(scope="module")
def chain_data():
    chain = fput_chain(4)
    return chain, make_trajectories(chain, 100, 40, 0.05, noise=0.01, random_state=0)


def test_the_screen_passes_over_biased_layouts():
    denoise = ["finite_difference", 3, 5, 8]
    assert screen_layout(denoise) == 5
    assert screen_layout(denoise, {5}) == 8
    assert screen_layout(denoise, {3, 5, 8}) == "finite_difference"
    assert screen_layout([3, 5], {3, 5}) == 5


def test_derivative_layouts_name_those_whose_polynomials_cannot_follow(chain_data):
    # Over 41 samples the chain's fast oscillations outrun a cubic.
    _, X = chain_data
    with pytest.warns(SmoothingWarning, match="degree=3"):
        layouts, misfits = derivative_layouts(X, 0.05, ["finite_difference", 3], strict=True)
    assert misfits == {3}
    # Without ``strict``, only a layout beyond GROSS_MISFIT times the noise.
    with pytest.warns(SmoothingWarning, match="degree=3") as caught:
        unwatched, gross = derivative_layouts(X, 0.05, ["finite_difference", 3])
    ratio = max(w.message.ratio for w in caught if w.category is SmoothingWarning)
    assert ratio > 1
    assert gross == ({3} if ratio > GROSS_MISFIT else set())
    for key in layouts:
        np.testing.assert_array_equal(layouts[key], unwatched[key])


def test_the_search_finds_an_fput_chain_of_four_particles(chain_data):
    chain, X = chain_data
    search = HamiltonianSearchCV(
        dt=0.05, denoise_degrees=["finite_difference", 3], degrees=[4, 6],
        fit_on=["simpson"], refine=None, cv=KFold(3, shuffle=True, random_state=0))
    quiet_fit(search, X)
    assert search.spaces_ == auto_spaces(8)
    # The cubic's layout is biased: the spaces are screened on finite
    # differences, and the cubic is searched no further.
    results = search.cv_results_
    methods = results["param_derivativetransformer__method"]
    assert set(methods[results["stage"] == "screen"]) == {"finite_difference"}
    assert set(methods) == {"finite_difference"}
    model = search.best_estimator_[-1]
    assert {term.text for term in hamiltonian_terms(model)} == chain_law(4)
    states = np.random.default_rng(1).uniform(-1, 1, size=(200, 8))
    error = model.hamiltonian(states) - chain.hamiltonian(states)
    assert np.std(error) < 0.01 * np.std(chain.hamiltonian(states))


def test_the_search_offers_an_angle_of_the_data_as_one():
    # Two oscillators and a pendulum turning round and round, uncoupled.
    def hamiltonian(X):
        p, q = X[..., :3], X[..., 3:]
        return 0.5 * np.sum(p**2, axis=-1) + 0.5 * np.sum(q[..., :2] ** 2, axis=-1) \
            - np.cos(q[..., 2])

    def gradient(X):
        p, q = X[..., :3], X[..., 3:]
        return np.concatenate([p, q[..., :2], np.sin(q[..., 2:])], axis=-1)

    domain = [[-1, 1]] * 5 + [[-np.pi, np.pi]]
    system = HamiltonianSystem("oscillators_and_pendulum", hamiltonian, gradient, domain,
                               initial_state=np.zeros(6))
    X = make_trajectories(system, 60, 30, 0.02, noise=0.005, random_state=0)
    search = HamiltonianSearchCV(
        dt=0.02, denoise_degrees=["finite_difference"], degrees=[4], fit_on=["simpson"],
        refine=None, cv=KFold(3, shuffle=True, random_state=0))
    quiet_fit(search, X)
    assert search.spaces_ == auto_spaces(6, angles=[False, False, True])
    model = search.best_estimator_[-1]
    assert {term.text for term in hamiltonian_terms(model)} == {
        "p1^2", "p2^2", "p3^2", "q1^2", "q2^2", "cos(q3)"}


def test_a_chain_of_eight_particles_is_fitted_to_its_trajectories():
    # Its 52 kept terms are more than the 40 of two degrees of freedom, but
    # within ten per state variable: the trajectory fit runs, and removes the
    # finite differences' bias from the least-squares coefficients.
    from sklearn.pipeline import make_pipeline

    from sk_hamiltonian import DerivativeTransformer
    from sk_hamiltonian._trajectory_fit import MAX_TERMS, max_terms

    chain = fput_chain(8)
    X = make_trajectories(chain, 40, 40, 0.05, noise=0.01, random_state=0)
    states = np.random.default_rng(1).uniform(-1, 1, size=(400, 16))
    truth = chain.hamiltonian(states)
    space = dict(degree=4, momentum_degree=2, separable=True, max_interaction=2,
                 solver="normal", threshold=0.01)
    errors = {}
    for fit_on in ("derivatives", "trajectories"):
        pipeline = make_pipeline(DerivativeTransformer(dt=0.05, method="finite_difference"),
                                 HamiltonianRegressor(**space, fit_on=fit_on))
        model = quiet_fit(pipeline, X)[-1]
        assert {term.text for term in hamiltonian_terms(model)} == chain_law(8)
        error = model.hamiltonian(states) - truth
        errors[fit_on] = np.std(error) / np.std(truth)
    assert len(chain_law(8)) > MAX_TERMS and len(chain_law(8)) <= max_terms(16)
    assert model.trajectory_fit_status_ == "refined"
    # Measured: 0.0037 and 0.00029.
    assert errors["trajectories"] < errors["derivatives"] / 4, errors


def test_the_trajectory_fit_takes_at_most_forty_terms_up_to_two_degrees_of_freedom():
    from sk_hamiltonian._trajectory_fit import MAX_TERMS, TERMS_PER_STATE, max_terms

    assert [max_terms(n) for n in (2, 4)] == [MAX_TERMS, MAX_TERMS]
    assert max_terms(16) == 16 * TERMS_PER_STATE > MAX_TERMS
