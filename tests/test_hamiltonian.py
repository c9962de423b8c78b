"""HamiltonianRegressor and VectorFieldRegressor: accuracy, conservation, errors."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import (
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    SimulationError,
    VectorFieldRegressor,
    unpack_derivatives,
)
from sk_hamiltonian.datasets import cherry, exponential, henon_heiles, make_trajectories

DT = 0.01


def cubic_hamiltonian(X):
    p1, p2, q1, q2 = X.T
    return 0.5 * (p1**2 + p2**2) + 0.5 * (q1**2 + q2**2) + q1**2 * q2 - q2**3 / 3 + 0.3 * p1 * q2


def cubic_gradient(X):
    p1, p2, q1, q2 = X.T
    return np.column_stack(
        [p1 + 0.3 * q2, p2, q1 + 2 * q1 * q2, q2 + q1**2 - q2**2 + 0.3 * p1]
    )


def time_derivative(grad):
    d = grad.shape[1] // 2
    return np.concatenate([-grad[:, d:], grad[:, :d]], axis=1)


@pytest.fixture(scope="module")
def cubic_model():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(300, 4))
    y = time_derivative(cubic_gradient(X))
    return HamiltonianRegressor(degree=3, domain=[[-1, 1]] * 4).fit(X, y)


def test_recovers_cubic_hamiltonian_exactly(cubic_model):
    X = np.random.default_rng(1).uniform(-1, 1, size=(50, 4))
    offset = cubic_model.hamiltonian(X) - cubic_hamiltonian(X)
    # Equal up to the free additive constant.
    assert np.ptp(offset) < 1e-8
    assert np.allclose(cubic_model.gradient(X), cubic_gradient(X), atol=1e-8)
    assert np.allclose(cubic_model.predict(X), time_derivative(cubic_gradient(X)), atol=1e-8)
    assert cubic_model.n_terms_ == cubic_model.coef_.size == 34
    assert cubic_model.cond_ < 10 and cubic_model.rank_ == 34


def test_constant_rule_zero_mean_over_domain(cubic_model):
    # Gauss-Legendre tensor rule, exact for this cubic: the mean of H~ over D is 0.
    nodes, weights = np.polynomial.legendre.leggauss(3)
    grid = np.stack(np.meshgrid(*[nodes] * 4, indexing="ij"), axis=-1).reshape(-1, 4)
    w = np.einsum("i,j,k,l->ijkl", *[weights] * 4).ravel() / 16
    assert abs(w @ cubic_model.hamiltonian(grid)) < 1e-12
    assert abs(w @ cubic_hamiltonian(grid)) > 1e-2  # the truth's constant differs


def test_hamiltonian_accepts_any_leading_shape(cubic_model):
    X = np.random.default_rng(2).uniform(-1, 1, size=(3, 5, 4))
    H = cubic_model.hamiltonian(X)
    assert H.shape == (3, 5)
    assert np.allclose(H[1], cubic_model.hamiltonian(X[1]))
    assert cubic_model.gradient(X).shape == (3, 5, 4)


def paper_example(system, method="finite_difference"):
    settings = system.paper_settings
    X = make_trajectories(
        system, settings["n_trajectories"], settings["n_intervals"], DT, random_state=0
    )
    Xt = DerivativeTransformer(dt=DT, method=method).fit_transform(X)
    with warnings.catch_warnings():
        # Short trajectories started near the box edge leave it slightly.
        warnings.simplefilter("ignore", DomainWarning)
        sp = HamiltonianRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)
        vf = VectorFieldRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)
    return sp, vf


def relative_errors(model, system, t):
    # RK4 at DT / 10 is accurate to ~1e-12 here, far below the model errors.
    truth = system.solve(system.initial_state, t, max_step=DT / 10)
    learned = model.simulate(system.initial_state, t, max_step=DT)
    return np.linalg.norm(learned - truth, axis=1) / np.linalg.norm(truth, axis=1)


@pytest.mark.parametrize("make_system", [henon_heiles, cherry])
def test_paper_examples_3_and_4_within_one_percent(make_system):
    system = make_system()
    sp, _ = paper_example(system)
    t = np.arange(0, 20 + DT / 2, DT)
    assert relative_errors(sp, system, t).max() < 1e-2


def test_paper_example_2_sp_beats_non_sp_long_term():
    system = exponential()
    sp, vf = paper_example(system)
    t = np.arange(0, 20 + DT / 2, DT)
    sp_err, vf_err = relative_errors(sp, system, t), relative_errors(vf, system, t)
    assert sp_err[-1] < 0.5 * vf_err[-1]
    H = sp.hamiltonian(sp.simulate(system.initial_state, t, method="avf", max_step=0.05))
    assert np.ptp(H) < 1e-12 * np.abs(H).max()


@pytest.fixture(scope="module")
def degree6_model():
    system = henon_heiles()
    X = make_trajectories(system, 600, 2, DT, random_state=3)
    Xt = DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)
        return HamiltonianRegressor(degree=6, domain=system.domain).fit(Xt), system


# 1e4 AVF steps cost five times 2e3; the default run takes 2e3 (measured
# relative deviation of H~: 1.0e-15 after 2e3 steps, 2.0e-15 after 1e4).
@pytest.mark.parametrize("n_steps", [2_000, pytest.param(10_000, marks=pytest.mark.slow)])
def test_avf_conserves_learned_energy_to_round_off(degree6_model, n_steps):
    model, system = degree6_model
    t = 0.05 * np.arange(n_steps + 1)
    X = model.simulate(system.initial_state, t, method="avf", max_step=np.inf)
    H = model.hamiltonian(X)
    assert np.abs(H - H[0]).max() < 1e-12 * abs(H[0])
    # It is a real trajectory, not a frozen state: it follows RK4 at small steps.
    reference = model.simulate(system.initial_state, t[:201], max_step=0.005)
    assert np.abs(X[:201] - reference).max() < 1e-3
    assert np.ptp(X[:, 2]) > 0.3


def test_rk4_energy_deviation_converges_with_fourth_order(degree6_model):
    model, system = degree6_model
    deviations = []
    for h in (0.08, 0.04, 0.02):
        X = model.simulate(system.initial_state, np.arange(0, 10 + h / 2, h), max_step=np.inf)
        H = model.hamiltonian(X)
        deviations.append(np.abs(H - H[0]).max())
    orders = np.log2(np.array(deviations[:-1]) / deviations[1:])
    assert np.all((orders > 3.5) & (orders < 5.5)), orders


def test_simulate_shapes_and_batch_consistency(cubic_model):
    t = np.linspace(0, 1, 11)
    x0 = np.array([[0.1, 0.2, -0.1, 0.0], [0.0, -0.3, 0.2, 0.1]])
    batch = cubic_model.simulate(x0, t)
    assert batch.shape == (2, 11, 4)
    single = cubic_model.simulate(x0[1], t)
    assert single.shape == (11, 4)
    assert np.allclose(batch[1], single)
    assert np.allclose(batch[:, 0], x0)


def test_simulation_blow_up_raises_with_time():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(100, 2))
    y = np.column_stack([X[:, 1] ** 2, X[:, 0] ** 2])  # H = p^3/3 - q^3/3: escapes
    model = HamiltonianRegressor(degree=3, domain=[[-1, 1], [-1, 1]]).fit(X, y)
    t = np.linspace(0, 50, 501)
    with pytest.raises(SimulationError, match="between t=") as info:
        model.simulate([[0.9, -0.9], [0.0, 0.0]], t)
    # The equilibrium at the origin survives; only the first state fails.
    assert info.value.failed_at[1] == t.size and info.value.failed_at[0] < t.size
    assert info.value.t_failed == t[info.value.failed_at[0]]
    assert info.value.t_reached == t[info.value.failed_at[0] - 1]


def test_vector_field_regressor_is_not_hamiltonian_but_fits_linear_field():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(100, 2))
    y = np.column_stack([-2 * X[:, 1] + 0.5, X[:, 0] + X[:, 1]])  # has a divergence
    vf = VectorFieldRegressor(degree=1).fit(X, y)
    assert np.allclose(vf.predict(X), y)
    assert vf.coef_.shape == (3, 2) and vf.n_terms_ == 6
    # No Hamiltonian, so no separable split for the explicit symplectic methods.
    with pytest.raises(ValueError, match="not separable.*'avf'.*'rk4'"):
        vf.simulate(X[0], [0.0, 1.0], method="leapfrog")
    assert not hasattr(vf, "hamiltonian")
    # The averaged-vector-field map exists for any field; for this linear one it
    # is the implicit midpoint rule, whose step agrees with RK4 to O(h^3).
    x0 = np.array([0.3, -0.2])
    avf = vf.simulate(x0, [0.0, 0.1], method="avf", max_step=np.inf)[1]
    rk4 = vf.simulate(x0, [0.0, 0.1], method="rk4", max_step=1e-3)[1]
    assert np.abs(avf - rk4).max() < 1e-3
    A = np.array([[0.0, -2.0], [1.0, 1.0]])
    midpoint = np.linalg.solve(np.eye(2) - 0.05 * A, (np.eye(2) + 0.05 * A) @ x0 + 0.1 * np.array([0.5, 0.0]))
    assert np.allclose(avf, midpoint, atol=1e-13)


def test_fit_on_layout_equals_fit_on_stacked_arrays():
    system = henon_heiles()
    X = make_trajectories(system, 40, 4, DT, random_state=0)
    Xt = DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)
    data = unpack_derivatives(Xt)
    a = HamiltonianRegressor(degree=3).fit(Xt)
    b = HamiltonianRegressor(degree=3).fit(data.states.reshape(-1, 4), data.derivatives.reshape(-1, 4))
    assert np.allclose(a.coef_, b.coef_)
    assert a.predict(Xt).shape == (40, 5, 4)
    as_list = HamiltonianRegressor(degree=3).fit(list(Xt))
    assert np.allclose(as_list.coef_, a.coef_)


@pytest.mark.parametrize("Model", [HamiltonianRegressor, VectorFieldRegressor])
def test_streaming_solver_matches_dense(Model):
    system = henon_heiles()
    X = make_trajectories(system, 100, 2, DT, random_state=0)
    Xt = DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)
    dense = Model(degree=4, solver="lstsq").fit(Xt)
    streamed = Model(degree=4, solver="normal").fit(Xt)
    assert dense.solver_ == "lstsq" and streamed.solver_ == "normal"
    assert np.allclose(dense.coef_, streamed.coef_, rtol=1e-7, atol=1e-9)
    assert dense.cond_ == pytest.approx(streamed.cond_, rel=1e-4)


def test_score_is_rollout_accuracy_against_observations():
    system = henon_heiles()
    X = make_trajectories(system, 60, 30, 0.05, random_state=0)
    Xt = DerivativeTransformer(dt=0.05, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=3).fit(Xt[:40])
    good = model.score(Xt[40:])
    assert 0.99 < good <= 1.0
    # Corrupting the observations (not the derivatives) lowers the score.
    corrupted = Xt[40:].copy()
    corrupted[:, 1:, 9:] += 0.2
    assert model.score(corrupted) < good - 0.1
    # Changing only the derivatives and smoothed states leaves it unchanged.
    tampered = Xt[40:].copy()
    tampered[:, :, 1:9] = 0.0
    assert model.score(tampered) == pytest.approx(good, abs=1e-15)


def test_domain_warnings():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(100, 2))
    y = np.column_stack([-X[:, 1], X[:, 0]])
    with pytest.warns(DomainWarning, match="training states"):
        HamiltonianRegressor(degree=2, domain=[[-0.5, 0.5], [-1, 1]]).fit(X, y)
    model = HamiltonianRegressor(degree=2).fit(X, y)
    with pytest.warns(DomainWarning, match="50.0%"):
        model.predict([[0.0, 0.0], [3.0, 0.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.predict(X)  # training points on the bounding box do not warn


@pytest.mark.parametrize(
    "X, y, params, match",
    [
        (np.zeros((10, 3)), np.zeros((10, 3)), {}, "must be even"),
        (np.ones((2, 2)), np.ones((2, 2)), {"degree": 3}, "underdetermined"),
        (np.random.rand(50, 2), np.zeros(50), {}, "same shape as X"),
        (np.full((50, 2), np.nan), np.zeros((50, 2)), {}, "NaN"),
        (np.random.rand(50, 2), np.zeros((50, 2)), {"domain": [[0, 1]]}, "domain must have shape"),
        (np.random.rand(50, 2), np.zeros((50, 2)), {"domain": [[1, 0], [0, 1]]}, "low < high"),
        (np.column_stack([np.ones(50), np.random.rand(50)]), np.zeros((50, 2)), {}, "constant"),
        # Not constant to round-off, but the map onto the window would overflow
        # (2.2e-308 wide: hypothesis found LAPACK errors from the fit before).
        (np.column_stack([np.r_[2.2e-308, np.zeros(49)], np.random.rand(50)]),
         np.zeros((50, 2)), {"degree": 2}, "span less than 1e-100.*Rescale"),
        (np.random.rand(50, 2), np.zeros((50, 2)), {"domain": [[0, 1e-120], [0, 1]]},
         "domain rows \\[0\\].*narrower than 1e-100"),
        (np.zeros((4, 10, 4)), np.zeros((4, 10, 4)), {}, "y must be None"),
        (np.zeros((4, 10, 4)), None, {}, "DerivativeTransformer first"),
    ],
)
def test_fit_errors_name_the_problem(X, y, params, match):
    with pytest.raises(ValueError, match=match):
        HamiltonianRegressor(**params).fit(X, y)


def test_predict_and_simulate_errors(cubic_model):
    with pytest.raises(ValueError, match="4 features"):
        cubic_model.predict(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="x0 must have shape"):
        cubic_model.simulate(np.zeros(3), [0, 1])
    with pytest.raises(ValueError, match="strictly increasing"):
        cubic_model.simulate(np.zeros(4), [0, 1, 1])
    with pytest.raises(ValueError, match="method must be one of"):
        cubic_model.simulate(np.zeros(4), [0, 1], method="euler")
    with pytest.raises(ValueError, match="max_step"):
        cubic_model.simulate(np.zeros(4), [0, 1], max_step=0)
    with pytest.raises(ValueError, match="NaN"):
        cubic_model.simulate(np.array([np.nan, 0, 0, 0]), [0, 1])


def test_simulate_on_failure_nan_marks_only_the_failed_trajectory(cubic_model):
    t = np.linspace(0, 50, 501)
    x0 = np.array([[0.1, 0.0, 0.0, 0.1], [3.0, 3.0, 3.0, 3.0]])  # the second escapes
    with pytest.raises(SimulationError) as info:
        cubic_model.simulate(x0, t, max_step=0.1)
    failed = info.value.failed_at
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)
        Y = cubic_model.simulate(x0, t, max_step=0.1, on_failure="nan")
    assert np.isfinite(Y[0]).all()
    assert np.isfinite(Y[1, : failed[1]]).all() and np.isnan(Y[1, failed[1] :]).all()
    assert np.allclose(Y[0], cubic_model.simulate(x0[0], t, max_step=0.1))
    with pytest.raises(ValueError, match="on_failure"):
        cubic_model.simulate(x0[0], t, on_failure="ignore")


def test_equations_print_the_learned_formula_and_repr_stays_the_parameters():
    import re

    from sklearn.exceptions import NotFittedError

    from sk_hamiltonian.datasets import single_pendulum
    from sk_hamiltonian.inspection import format_hamiltonian

    X = make_trajectories(single_pendulum(), 40, 20, 0.05, noise=0.01, random_state=0)
    Xt = DerivativeTransformer(dt=0.05).fit_transform(X)
    model = HamiltonianRegressor(4, periodic=[False, True], momentum_degree=2, threshold=0.03,
                                 n_resamples=20, random_state=0)
    with pytest.raises(NotFittedError):
        model.equations()
    model.fit(Xt)
    formula = model.equations()
    assert formula == format_hamiltonian(model)
    # The pendulum's law, H = p^2 / 2 - 9.8 cos q, from 1 % noise.
    found = re.fullmatch(r"H~ = -(\S+) cos\(q\) \+ (\S+) p\^2 \+ const", formula)
    assert found and abs(float(found.group(1)) - 9.8) < 0.1, formula
    assert abs(float(found.group(2)) - 0.5) < 0.01, formula
    assert model.equations(state_names=["P", "Q"]).endswith("cos(Q) + " + found.group(2)
                                                             + " P^2 + const")
    assert "(±" in model.equations(intervals=True)
    assert model.equations(max_terms=1).startswith(
        "H~ = -" + found.group(1) + " cos(q) + ... (1 smaller term")
    # scikit-learn's representation, the parameters, fitted or not (and print
    # shows it, as for any estimator).
    expected = ("HamiltonianRegressor(degree=4, momentum_degree=2, n_resamples=20, "
                "periodic=[False, True], random_state=0, threshold=0.03)")
    assert repr(model) == str(model)
    assert " ".join(repr(model).split()) == expected  # pprint breaks long lines
    assert repr(HamiltonianRegressor(degree=4)) == "HamiltonianRegressor(degree=4)"


def test_a_fit_whose_kept_terms_split_into_t_and_v_takes_the_symplectic_methods():
    # The search fits p^2/2 + V(q) in general or mechanical spaces, never with
    # separable=True: such a model integrates with leapfrog all the same,
    # close to RK4 at this step; one whose kept terms mix p and q does not.
    from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    from sk_hamiltonian.datasets import single_pendulum

    X = make_trajectories(single_pendulum(), 60, 40, dt=0.01, noise=0.01, random_state=0)
    Xt = DerivativeTransformer(dt=0.01).fit_transform(X)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        split = HamiltonianRegressor(degree=4, periodic=[False, True], momentum_degree=2,
                                     threshold=0.03).fit(Xt)
        mixed = HamiltonianRegressor(degree=4, threshold=0.0).fit(Xt)
    t = np.arange(0, 5, 0.01)
    np.testing.assert_allclose(split.simulate([0.5, 1.0], t, method="leapfrog"),
                               split.simulate([0.5, 1.0], t, method="rk4"), atol=2e-3)
    with pytest.raises(ValueError, match="a kept term holds both momenta and positions"):
        mixed.simulate([0.5, 1.0], t, method="leapfrog")
