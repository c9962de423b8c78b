"""state_order="qp": data in (q, p) column order, read as such and answered in it."""

import warnings

import numpy as np
import pytest
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    StateOrderWarning,
    load,
    save,
)
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.inspection import hamiltonian_terms

SPACE = {"degree": 4, "periodic": [False, True], "momentum_degree": 2, "threshold": 0.03}
# The same space for columns (q, p): per-state parameters follow the columns.
SPACE_QP = dict(SPACE, periodic=[True, False], state_order="qp")


def qp(X):
    """Columns (p, q) of states (or of anything state-shaped) as (q, p), one degree of freedom."""
    return np.asarray(X)[..., ::-1]


def qp_layout(Xt):
    """A derivative layout [t | p q | dp dq | p q] with each block as (q, p)."""
    return np.asarray(Xt)[..., [0, 2, 1, 4, 3, 6, 5]]


@pytest.fixture(scope="module")
def data():
    X = make_trajectories(single_pendulum(), 40, 40, dt=0.01, noise=0.01, random_state=0)
    return X, DerivativeTransformer(dt=0.01).fit_transform(X)


def fit(X, y=None, **params):
    """Fit, and the StateOrderWarnings of the fit."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = HamiltonianRegressor(**params).fit(X, y)
    return model, [w for w in caught if issubclass(w.category, StateOrderWarning)]


@pytest.fixture(scope="module")
def fits(data):
    _, Xt = data
    pq, _ = fit(Xt, **SPACE)
    swapped, caught = fit(qp_layout(Xt), **SPACE_QP)
    return pq, swapped, caught


def test_qp_columns_give_the_pq_fit_without_a_warning(fits):
    pq, swapped, caught = fits
    assert caught == []
    np.testing.assert_array_equal(swapped.coef_, pq.coef_)
    np.testing.assert_array_equal(swapped.powers_, pq.powers_)
    # The fitted attributes are in the model's (p, q) order.
    np.testing.assert_array_equal(swapped.periodic_, [False, True])
    assert {t.text for t in hamiltonian_terms(swapped)} == {"p^2", "cos(q)"}
    assert swapped.equations() == pq.equations()


def test_outputs_come_back_in_the_columns_order(data, fits):
    X, Xt = data
    pq, swapped, _ = fits
    states = X[:3, 5]  # (p, q)
    np.testing.assert_allclose(swapped.predict(qp(states)), qp(pq.predict(states)))
    # The derivative layout: predicted at its states, in its shape.
    np.testing.assert_allclose(swapped.predict(qp_layout(Xt[:2])), qp(pq.predict(Xt[:2])))
    np.testing.assert_allclose(swapped.hamiltonian(qp(states)), pq.hamiltonian(states))
    np.testing.assert_allclose(swapped.gradient(qp(states)), qp(pq.gradient(states)))
    t = np.linspace(0.0, 2.0, 21)
    for x0 in (states[0], states):  # one initial state, and several
        np.testing.assert_allclose(swapped.simulate(qp(x0), t), qp(pq.simulate(x0, t)))
    # The rollout score reads the layout's observations in the columns' order.
    assert swapped.score(qp_layout(Xt[:4])) == pytest.approx(pq.score(Xt[:4]))


def test_states_with_derivatives_y_in_qp_order(data):
    _, Xt = data
    states, derivatives = Xt[..., 1:3].reshape(-1, 2), Xt[..., 3:5].reshape(-1, 2)
    pq, _ = fit(states, derivatives, **SPACE)
    swapped, caught = fit(qp(states), qp(derivatives), **SPACE_QP)
    assert caught == []
    np.testing.assert_allclose(swapped.coef_, pq.coef_)
    # R^2 of the derivatives, against y in the columns' order.
    assert swapped.score(qp(states[:50]), qp(derivatives[:50])) == pytest.approx(
        pq.score(states[:50], derivatives[:50]))


def test_qp_data_fitted_as_pq_warn_naming_the_parameter(data):
    _, Xt = data
    _, caught = fit(qp_layout(Xt), **dict(SPACE, periodic=[True, False]))
    assert len(caught) == 1 and "state_order='qp'" in str(caught[0].message)
    # And pq data declared qp (the angle still the second column): the
    # warning says to use "pq".
    _, caught = fit(Xt, **dict(SPACE, state_order="qp"))
    assert len(caught) == 1 and "state_order='pq'" in str(caught[0].message)


def test_names_and_domain_are_given_in_the_columns_order(data):
    _, Xt = data
    pq, _ = fit(Xt, **SPACE, domain=[[-8, 8], [-np.pi, np.pi]])
    swapped, _ = fit(qp_layout(Xt), **SPACE_QP, domain=[[-np.pi, np.pi], [-8, 8]],
                     state_names=["theta", "L"])
    np.testing.assert_array_equal(swapped.domain_, [[-8, 8], [-np.pi, np.pi]])
    np.testing.assert_allclose(swapped.coef_, pq.coef_)
    assert {t.text for t in hamiltonian_terms(swapped)} == {"L^2", "cos(theta)"}
    # Names given at the call are in the columns' order too.
    assert "cos(x)" in swapped.equations(state_names=["x", "P"])


def test_named_columns_keep_their_order(data):
    pd = pytest.importorskip("pandas")
    _, Xt = data
    states, derivatives = Xt[..., 1:3].reshape(-1, 2), Xt[..., 3:5].reshape(-1, 2)
    frame = pd.DataFrame(qp(states), columns=["theta", "L"])
    swapped, _ = fit(frame, qp(derivatives), **SPACE_QP)
    assert list(swapped.feature_names_in_) == ["theta", "L"]
    assert {t.text for t in hamiltonian_terms(swapped)} == {"L^2", "cos(theta)"}
    pq, _ = fit(states, derivatives, **SPACE)
    np.testing.assert_allclose(swapped.predict(frame.iloc[:3]), qp(pq.predict(states[:3])))


def test_in_a_pipeline_with_the_derivative_transformer(data, fits):
    X, _ = data
    pq, _, _ = fits
    with warnings.catch_warnings():
        warnings.simplefilter("error", StateOrderWarning)
        pipe = make_pipeline(DerivativeTransformer(dt=0.01),
                             HamiltonianRegressor(**SPACE_QP)).fit(qp(X))
    np.testing.assert_array_equal(pipe[-1].coef_, pq.coef_)
    np.testing.assert_allclose(pipe.predict(qp(X[:2])), qp(pq.predict(
        DerivativeTransformer(dt=0.01).fit_transform(X[:2]))))


def test_fit_on_trajectories_reads_the_observations_in_the_columns_order(data):
    X, _ = data
    Xt = DerivativeTransformer(dt=0.01).fit_transform(X[:12])
    pq, _ = fit(Xt, **SPACE, fit_on="trajectories")
    swapped, caught = fit(qp_layout(Xt), **SPACE_QP, fit_on="trajectories")
    assert caught == []
    assert swapped.trajectory_fit_status_ == pq.trajectory_fit_status_
    np.testing.assert_allclose(swapped.coef_, pq.coef_, rtol=1e-8)


def test_model_files_keep_the_order(fits, data, tmp_path):
    X, _ = data
    _, swapped, _ = fits
    save(swapped, tmp_path / "m.skh")
    loaded = load(tmp_path / "m.skh")
    assert loaded.state_order == "qp"
    states = qp(X[:3, 5])
    np.testing.assert_array_equal(loaded.predict(states), swapped.predict(states))


def test_a_bad_order_is_refused_naming_the_parameter(data):
    _, Xt = data
    with pytest.raises(ValueError, match="state_order.*'pq'.*'qp'|state_order.*'qp'.*'pq'"):
        HamiltonianRegressor(state_order="q,p").fit(Xt)


def test_couplings_are_indices_into_the_columns():
    # Two degrees of freedom, columns (q1, q2, p1, p2): the positions'
    # coupling is (0, 1) in the columns, (2, 3) in the model's order.
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(300, 4))  # (p1, p2, q1, q2)
    p, q = X[:, :2], X[:, 2:]
    # H = |p|^2 / 2 + |q|^2 / 2 + q1 q2
    y = np.column_stack([-(q[:, 0] + q[:, 1]), -(q[:, 1] + q[:, 0]), p[:, 0], p[:, 1]])
    params = {"degree": 2, "max_interaction": 2}
    pq, _ = fit(X, y, **params, couplings=[(2, 3)])
    swapped, _ = fit(np.roll(X, 2, axis=1), np.roll(y, 2, axis=1), **params,
                     couplings=[(0, 1)], state_order="qp")
    np.testing.assert_array_equal(swapped.powers_, pq.powers_)
    np.testing.assert_allclose(swapped.coef_, pq.coef_)
    assert any(t.text == "q1*q2" for t in hamiltonian_terms(swapped))


def test_the_prediction_band_and_the_offset_read_the_columns_order(data):
    from sk_hamiltonian.inspection import prediction_band
    from sk_hamiltonian.metrics import hamiltonian_offset

    _, Xt = data
    params = {"n_resamples": 10, "random_state": 0}
    pq, _ = fit(Xt[:20], **SPACE, **params)
    swapped, _ = fit(qp_layout(Xt[:20]), **SPACE_QP, **params)
    t = np.linspace(0.0, 1.0, 11)
    for a, b in zip(prediction_band(swapped, [1.0, 0.5], t), prediction_band(pq, [0.5, 1.0], t)):
        np.testing.assert_allclose(a, qp(b))

    def energy(X):  # the pendulum's, of (p, q) columns
        return X[:, 0] ** 2 / 2 - 9.8 * np.cos(X[:, 1])

    # The same box (drawn column by column, so another Monte Carlo sample:
    # 1e-3, where a box with the halves exchanged is off by about 100 %).
    assert hamiltonian_offset(swapped, lambda X: energy(qp(X))) == pytest.approx(
        hamiltonian_offset(pq, energy), rel=1e-3)


def test_the_search_runs_in_pq_order_and_answers_in_the_columns_order(data):
    from sk_hamiltonian.model_selection import HamiltonianSearchCV

    X, _ = data
    small = {"denoise_degrees": ("finite_difference",), "degrees": (4,),
             "fit_on": ("derivatives",), "thresholds": (0.03,), "cv": 3}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pq = HamiltonianSearchCV(dt=0.01, **small).fit(X)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StateOrderWarning)
        swapped = HamiltonianSearchCV(dt=0.01, state_order="qp", state_names=["theta", "L"],
                                      **small).fit(qp(X))
    chosen = swapped.best_estimator_[-1]
    assert chosen.state_order == "qp"
    np.testing.assert_allclose(chosen.coef_, pq.best_estimator_[-1].coef_)
    # The angle is found in the columns' first place, and reported there.
    assert pq.best_params_["hamiltonianregressor__periodic"] == [False, True]
    assert swapped.best_params_["hamiltonianregressor__periodic"] == [True, False]
    assert swapped.best_score_ == pytest.approx(pq.best_score_)
    # The refinement on the raw trajectories (model order) kept the same terms.
    assert swapped.refinement_["status"] == pq.refinement_["status"]
    assert {t.text for t in hamiltonian_terms(chosen)} == {"L^2", "cos(theta)"}
    t = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(swapped.simulate(qp(X[0, 0]), t), qp(pq.simulate(X[0, 0], t)))


def test_the_command_reads_qp_columns_with_order_qp(data, tmp_path, capsys):
    from sk_hamiltonian._cli import main

    X, _ = data
    path = tmp_path / "runs.npz"
    np.savez(path, trajectories=qp(X))  # columns (theta, L)
    out_dir = tmp_path / "out"
    args = [str(path), "--dt", "0.01", "--no-resample", "--degrees", "4", "--denoise-degrees",
            "fd", "--output", str(out_dir), "--names", "theta", "L"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", StateOrderWarning)
        warnings.filterwarnings("ignore", category=UserWarning,
                                message="(?!.*look ordered)")  # the fit's own notes
        assert main(args + ["--order", "qp"]) == 0
    out = capsys.readouterr().out
    assert "fitted and reported as L, theta" in out and "cos(theta)" in out
    model = load(out_dir / "model.skh")[-1]
    # Exchanged on loading: the angle is the model's position.
    np.testing.assert_array_equal(model.periodic_, [False, True])
    assert {t.text for t in hamiltonian_terms(model)} == {"L^2", "cos(theta)"}
    for bad in (["--order", "q,p"], ["--order", "qp", "--names", "a", "b", "c"]):
        with pytest.raises(SystemExit) as exit_info:
            main(args[:-3] + bad)
        assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "--order must be pq (momenta first) or qp (positions first); got 'q,p'" in err
    assert "--names must have one name per state variable" in err


def test_partial_fit_reads_each_chunk_in_the_columns_order(data):
    _, Xt = data
    states, derivatives = Xt[..., 1:3].reshape(-1, 2), Xt[..., 3:5].reshape(-1, 2)
    box = {"degree": 4, "periodic": [False, True], "domain": [[-8, 8], [-np.pi, np.pi]]}
    pq, _ = fit(states, derivatives, **box)
    swapped = HamiltonianRegressor(degree=4, periodic=[True, False],
                                   domain=[[-np.pi, np.pi], [-8, 8]], state_order="qp")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for chunk in np.array_split(np.arange(len(states)), 3):
            swapped.partial_fit(qp(states[chunk]), qp(derivatives[chunk]))
    np.testing.assert_allclose(swapped.coef_, pq.coef_, rtol=1e-6, atol=1e-9)
