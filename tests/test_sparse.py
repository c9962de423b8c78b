"""Sparse Hamiltonians: the ``threshold`` parameter (STLSQ in the readable basis)."""

import warnings

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import ConvergenceWarning
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from sk_hamiltonian import _least_squares
from sk_hamiltonian._space import ModelSpace, index_set
from sk_hamiltonian._space.readable import ReadableBasis
from sk_hamiltonian.model_selection._threshold_path import fit_along_path
from sk_hamiltonian.datasets import henon_heiles, make_trajectories, single_pendulum
from sk_hamiltonian.inspection import hamiltonian_terms

PENDULUM_SPACE = dict(periodic=[False, True], momentum_degree=2)


def readable_terms(model, atol=1e-9):
    """``{powers: coefficient}`` of the learned H~ in monomials and angles."""
    return {
        term.powers: term.coefficient
        for term in hamiltonian_terms(model, rtol=0)
        if abs(term.coefficient) > atol
    }


@pytest.fixture(scope="module")
def exact_henon_heiles():
    # States over the box with their exact time derivatives: a clean problem.
    system = henon_heiles()
    rng = np.random.default_rng(0)
    X = rng.uniform(-0.6, 0.6, size=(600, 4)) + [0.1, -0.05, 0.2, 0.1]
    return X, system.vector_field(X)


@pytest.fixture(scope="module")
def noisy_pendulum():
    # The paper's Example 1 data: 500 trajectories of 41 samples, 8 % noise.
    X = make_trajectories(single_pendulum(), 500, 40, dt=0.01, noise=0.08, random_state=0)
    return X, DerivativeTransformer(dt=0.01, degree=3).fit_transform(X)


# ------------------------------------------------------------ readable basis
@pytest.mark.parametrize(
    "periodic, constant",
    [([False, False], False), ([False, True], False), ([False, True], True),
     ([False, False, True, False], False)],
)
def test_readable_basis_spans_the_fitting_basis_both_ways(periodic, constant):
    periodic = np.array(periodic)
    powers = index_set(periodic.size, 4, periodic=periodic, include_constant=constant)
    rng = np.random.default_rng(1)
    domain = np.column_stack([rng.uniform(-2, 0, periodic.size), rng.uniform(0.5, 3, periodic.size)])
    # A period that does not start at -pi: the readable angles are rotated.
    domain[periodic] = [-1.0, 2 * np.pi - 1.0]
    X = np.column_stack([rng.uniform(low, high, 40) for low, high in domain])
    basis = ReadableBasis(powers, domain, periodic)

    def readable(beta):
        out = np.ones(X.shape[0])
        for i, b in enumerate(beta):
            if periodic[i] and b:
                omega = 2 * np.pi / (domain[i, 1] - domain[i, 0])
                out *= (np.cos if b > 0 else np.sin)(abs(b) * omega * X[:, i])
            elif not periodic[i]:
                out *= X[:, i] ** b
        return out

    direct = np.column_stack([readable(beta) for beta in powers])
    through = ModelSpace(domain, powers, periodic).values(X) @ basis.to_fitting.toarray()
    # Up to a constant per function when the space has none.
    difference = direct - through
    if not constant:
        difference -= difference.mean(axis=0)
    assert np.abs(difference).max() < 1e-11
    round_trip = basis.from_fitting.toarray() @ basis.to_fitting.toarray()
    assert np.abs(round_trip - np.eye(powers.shape[0])).max() < 1e-12


# ------------------------------------------------------------------ defaults
def test_threshold_zero_is_the_dense_fit(noisy_pendulum):
    _, Xt = noisy_pendulum
    model = HamiltonianRegressor(degree=6, **PENDULUM_SPACE).fit(Xt)
    assert model.threshold == 0.0
    assert model.support_.all() and model.support_.shape == (model.powers_.shape[0],)
    assert model.n_terms_ == model.powers_.shape[0] and model.n_iter_ == 1


# --------------------------------------------------------------- exact support
def test_clean_henon_heiles_gives_back_its_six_monomials(exact_henon_heiles):
    X, y = exact_henon_heiles
    model = HamiltonianRegressor(degree=5, threshold=0.01).fit(X, y)
    truth = {
        (2, 0, 0, 0): 0.5, (0, 2, 0, 0): 0.5, (0, 0, 2, 0): 0.5, (0, 0, 0, 2): 0.5,
        (0, 0, 2, 1): 1.0, (0, 0, 0, 3): -1 / 3,
    }
    terms = readable_terms(model)
    assert set(terms) == set(truth)
    for powers, value in truth.items():
        assert terms[powers] == pytest.approx(value, rel=1e-8)
    assert model.n_terms_ == 6
    # The dense fit of the same space has every term.
    assert HamiltonianRegressor(degree=5).fit(X, y).n_terms_ == model.powers_.shape[0]


def test_vector_field_threshold_is_stlsq_per_component():
    system = single_pendulum()
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-2, 2.5, 400), rng.uniform(-np.pi, np.pi, 400)])
    model = VectorFieldRegressor(degree=5, threshold=0.05, **PENDULUM_SPACE).fit(
        X, system.vector_field(X)
    )
    basis = ReadableBasis(model.powers_, model.domain_, model.periodic_)
    readable = basis.from_fitting @ model.coef_
    kept = [
        {tuple(model.powers_[j]): readable[j, k] for j in np.flatnonzero(np.abs(readable[:, k]) > 1e-9)}
        for k in range(2)
    ]
    # dp/dt = -g sin q and dq/dt = p: one term each, with the constant dropped.
    assert kept[0] == {(0, -1): pytest.approx(-9.8, rel=1e-9)}
    assert kept[1] == {(1, 0): pytest.approx(1.0, rel=1e-9)}
    assert model.support_.shape == model.coef_.shape and model.n_terms_ == 2


# ------------------------------------------------------------- noisy pendulum
def test_noisy_pendulum_reads_as_its_formula_and_rolls_out_better(noisy_pendulum):
    _, Xt = noisy_pendulum
    dense = HamiltonianRegressor(degree=8, **PENDULUM_SPACE).fit(Xt)
    sparse = HamiltonianRegressor(degree=8, threshold=0.03, **PENDULUM_SPACE).fit(Xt)
    terms = readable_terms(sparse)
    assert set(terms) == {(2, 0), (0, 1)}
    assert terms[(2, 0)] == pytest.approx(0.5, rel=0.01)
    assert terms[(0, 1)] == pytest.approx(-9.8, rel=0.01)
    assert sparse.n_terms_ == 2 < dense.n_terms_
    system = single_pendulum()
    t = np.arange(0, 20.0001, 0.01)
    # RK4 at dt / 10: within 5e-11 of solve's default dt / 100, ten times faster.
    truth = system.solve(system.initial_state, t, max_step=0.001)

    def error(model):
        Y = model.simulate(system.initial_state, t)
        return np.linalg.norm(Y[-1] - truth[-1]) / np.linalg.norm(truth[-1])

    assert error(sparse) < 0.5 * error(dense)


@pytest.mark.parametrize("solver", ["normal", "iterative", "sketch"])
def test_every_solver_gives_the_same_sparse_answer(noisy_pendulum, solver):
    _, Xt = noisy_pendulum
    reference = HamiltonianRegressor(degree=6, threshold=0.01, solver="lstsq", **PENDULUM_SPACE)
    reference.fit(Xt)
    model = clone(reference).set_params(solver=solver)
    with warnings.catch_warnings():
        # The closed-form preconditioner assumes samples over the whole box;
        # it may warn that it stopped early, and still be accurate.
        warnings.simplefilter("ignore", ConvergenceWarning)
        model.fit(Xt)
    assert np.array_equal(model.support_, reference.support_)
    assert model.n_terms_ == reference.n_terms_
    # The iterative solvers stop at a relative residual of 1e-11.
    assert np.allclose(model.coef_, reference.coef_, rtol=1e-6, atol=1e-8)


def test_partial_fit_thresholds_the_accumulated_equations(noisy_pendulum):
    X, Xt = noisy_pendulum
    domain = [[X[..., 0].min() - 0.5, X[..., 0].max() + 0.5], [-np.pi, np.pi]]
    params = dict(degree=6, threshold=0.01, domain=domain, **PENDULUM_SPACE)
    reference = HamiltonianRegressor(solver="normal", **params).fit(Xt)
    model = HamiltonianRegressor(**params)
    for chunk in np.array_split(Xt, 3):
        model.partial_fit(chunk)
    assert np.array_equal(model.support_, reference.support_)
    assert np.allclose(model.coef_, reference.coef_, rtol=1e-8, atol=1e-10)


def test_friction_is_never_dropped():
    system = single_pendulum(damping=0.15)
    X = make_trajectories(system, 100, 60, dt=0.02, random_state=0)
    Xt = DerivativeTransformer(dt=0.02, method="finite_difference").fit_transform(X)
    # A threshold large enough to drop a friction of this size if it counted.
    model = HamiltonianRegressor(degree=6, damping=True, threshold=0.05, **PENDULUM_SPACE)
    model.fit(Xt)
    assert model.damping_[0] == pytest.approx(0.15, rel=0.1)
    assert set(readable_terms(model)) == {(2, 0), (0, 1)}
    assert model.n_terms_ == 3


def test_sparse_steps_fit_simulates_with_avf_at_the_data_step(noisy_pendulum):
    X, _ = noisy_pendulum
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=6, fit_on="steps", threshold=0.03, **PENDULUM_SPACE)
    model.fit(Xt)
    assert model.n_terms_ < model.powers_.shape[0]
    Y = model.simulate(model.domain_.mean(axis=1), np.arange(0, 2.0001, 0.01))
    H = model.hamiltonian(Y)
    assert np.ptp(H) < 1e-10 * np.abs(H).max()


def test_evaluation_of_a_sparse_model_is_its_formula(exact_henon_heiles):
    X, y = exact_henon_heiles
    model = HamiltonianRegressor(degree=5, threshold=0.01).fit(X, y)
    terms = readable_terms(model, atol=0)
    values = sum(c * np.prod(X ** np.array(p), axis=1) for p, c in terms.items())
    H = model.hamiltonian(X)
    # H~ has zero mean over the domain, the formula does not: compare up to a constant.
    assert np.ptp(H - values) < 1e-9
    assert np.allclose(model.predict(X), y, atol=1e-9)


def test_the_iteration_cap_warns(monkeypatch, noisy_pendulum):
    _, Xt = noisy_pendulum
    monkeypatch.setattr(_least_squares.fit_support, "__kwdefaults__",
                        {**_least_squares.fit_support.__kwdefaults__, "max_iter": 1})
    with pytest.warns(ConvergenceWarning, match="still dropping terms after 1 solves"):
        model = HamiltonianRegressor(degree=6, threshold=0.03, **PENDULUM_SPACE).fit(Xt)
    assert model.n_iter_ == 1 and model.support_.all()


def test_a_zero_target_keeps_its_support():
    X = np.random.default_rng(0).uniform(-1, 1, size=(50, 2))
    model = HamiltonianRegressor(degree=3, threshold=0.1).fit(X, np.zeros_like(X))
    assert np.all(model.coef_ == 0) and model.support_.all()


def test_negative_threshold_is_refused():
    X = np.random.default_rng(0).uniform(-1, 1, size=(50, 2))
    with pytest.raises(ValueError, match="threshold"):
        HamiltonianRegressor(threshold=-0.1).fit(X, X)


# ------------------------------------------------------------ model selection
def test_grid_search_over_threshold_in_a_pipeline(noisy_pendulum):
    X, _ = noisy_pendulum
    pipe = make_pipeline(
        DerivativeTransformer(dt=0.01, degree=3), HamiltonianRegressor(degree=6, **PENDULUM_SPACE)
    )
    grid = {"hamiltonianregressor__threshold": [0.0, 0.03]}
    search = GridSearchCV(pipe, grid, cv=KFold(3, shuffle=True, random_state=0)).fit(X[:150])
    assert np.isfinite(search.cv_results_["mean_test_score"]).all()
    best = search.best_estimator_[-1]
    assert best.threshold == search.best_params_["hamiltonianregressor__threshold"]
    # The two candidates are different models, and the search sees it.
    scores = search.cv_results_["split0_test_score"]
    assert scores[0] != scores[1]


def test_threshold_path_reports_sizes_scores_and_ties(noisy_pendulum):
    from sk_hamiltonian.model_selection import count_terms, threshold_path

    X, _ = noisy_pendulum
    pipe = make_pipeline(
        DerivativeTransformer(dt=0.01, degree=3), HamiltonianRegressor(degree=6, **PENDULUM_SPACE)
    )
    cv = KFold(3, shuffle=True, random_state=0)
    path = threshold_path(pipe, X[:150], [0.03, 0.0, 1e-3], cv=cv)
    assert path.thresholds.tolist() == [0.0, 1e-3, 0.03]
    # Sizes shrink along the path; the largest threshold gives the formula.
    assert path.n_terms[0] == count_terms(pipe, n_states=2) and path.n_terms[-1] == 2
    assert np.all(np.diff(path.n_terms) <= 0)
    search = GridSearchCV(pipe, {"hamiltonianregressor__threshold": [0.0, 1e-3, 0.03]}, cv=cv)
    search.fit(X[:150])
    assert np.allclose(path.mean_score, search.cv_results_["mean_test_score"])
    best = path.best_index
    assert best == int(np.argmax(path.mean_score))
    assert np.array_equal(path.tied, path.mean_score >= path.mean_score[best] - path.std_error[best])
    assert path.tied[best] and path.tied[path.smallest_tied_index]
    assert path.n_terms[path.smallest_tied_index] == path.n_terms[path.tied].min()


def test_threshold_path_refuses_bad_input(noisy_pendulum):
    from sk_hamiltonian.model_selection import threshold_path

    X, Xt = noisy_pendulum
    with pytest.raises(ValueError, match="thresholds must be"):
        threshold_path(HamiltonianRegressor(), Xt, [-1.0])
    with pytest.raises(ValueError, match="thresholds must be"):
        threshold_path(HamiltonianRegressor(), Xt, [])
    with pytest.raises(ValueError, match="Pipeline ending in one"):
        threshold_path(DerivativeTransformer(dt=0.01), X, [0.0])


def test_plot_threshold_path_draws_every_threshold():
    pytest.importorskip("matplotlib")
    import matplotlib

    matplotlib.use("Agg")
    from sklearn.utils import Bunch

    from sk_hamiltonian.plotting import plot_threshold_path

    path = Bunch(thresholds=np.array([0.0, 0.01, 0.1]), n_terms=np.array([44, 5, 2]),
                 mean_score=np.array([0.90, 0.93, 0.94]), std_error=np.array([0.01] * 3),
                 tied=np.array([False, True, True]))
    ax = plot_threshold_path(path)
    assert ax.get_xscale() == "log"
    assert [t.get_text() for t in ax.texts] == ["0", "0.01", "0.1"]
    with pytest.raises(ValueError, match="lacks tied"):
        plot_threshold_path(Bunch(thresholds=[], n_terms=[], mean_score=[], std_error=[]))


def test_to_sympy_gives_the_formula():
    sympy = pytest.importorskip("sympy")
    from sk_hamiltonian.inspection import to_sympy

    system = single_pendulum()
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-2, 2.5, 300), rng.uniform(-np.pi, np.pi, 300)])
    model = HamiltonianRegressor(degree=5, threshold=0.01, **PENDULUM_SPACE)
    model.fit(X, system.vector_field(X))
    p, q = sympy.symbols("p q", real=True)
    difference = to_sympy(model) - (p**2 / 2 - 9.8 * sympy.cos(q))
    assert all(abs(c) < 1e-9 for c in sympy.Poly(difference, p, sympy.cos(q)).coeffs())
    named = to_sympy(model, state_names=["momentum", "angle"])
    assert {s.name for s in named.free_symbols} == {"momentum", "angle"}


@pytest.mark.parametrize("solver", ["lstsq", "normal", "iterative", "sketch"])
@pytest.mark.parametrize("cls", [HamiltonianRegressor, VectorFieldRegressor])
def test_one_assembly_path_equals_separate_fits(noisy_pendulum, cls, solver):
    # A fifth of the trajectories: the two ways must agree at any size, and
    # these still give three supports per path (HamiltonianRegressor: 32, 30
    # and 2 terms), in an eighth of the time of all 500.
    Xt = noisy_pendulum[1][:100]
    estimator = cls(degree=6, solver=solver, **PENDULUM_SPACE)
    thresholds = [0.0, 1e-3, 0.03]
    models = fit_along_path(clone(estimator), Xt, thresholds)
    assert len({model.n_terms_ for model in models}) == 3
    for threshold, model in zip(thresholds, models):
        alone = clone(estimator).set_params(threshold=threshold).fit(Xt)
        assert model.threshold == threshold
        assert np.array_equal(model.support_, alone.support_)
        assert model.n_terms_ == alone.n_terms_
        assert np.allclose(model.coef_, alone.coef_, rtol=1e-8, atol=1e-10)
        assert model.time_scale_ == pytest.approx(alone.time_scale_, rel=1e-8)
        assert np.allclose(model.predict(Xt[:2]), alone.predict(Xt[:2]), rtol=1e-8,
                           atol=1e-10)
