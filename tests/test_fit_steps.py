"""The four steps of a fit (``sk_hamiltonian._fit_steps``) called without ``fit``.

A search that shares work between candidates builds the model space, the
normal equations of some trajectories, the support rule's solution and the
fitted estimator itself; each step must give what ``fit`` gives.
"""

import warnings

import numpy as np
import pytest
from sklearn.base import clone

from sk_hamiltonian import (
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian import _fit_steps as steps
from sk_hamiltonian.datasets import make_trajectories, single_pendulum

DT = 0.01
# Fitted attributes that fit sets, compared bit for bit.
ATTRIBUTES = ("coef_", "support_", "n_terms_", "n_iter_", "cond_", "rank_", "powers_",
              "periodic_", "domain_", "dt_", "state_scale_", "time_scale_", "solver_",
              "n_features_in_")


@pytest.fixture(scope="module")
def layout():
    damped = single_pendulum(damping=0.1)
    X = make_trajectories(damped, 60, 20, DT, noise=0.01, random_state=0)
    return DerivativeTransformer(dt=DT, degree=3).fit_transform(X)


CASES = [
    HamiltonianRegressor(degree=5, solver="normal"),
    HamiltonianRegressor(degree=5, periodic=[False, True], momentum_degree=2, threshold=0.01,
                         solver="normal"),
    HamiltonianRegressor(degree=4, damping=True, fit_on="steps", threshold=0.01, solver="normal"),
    HamiltonianRegressor(degree=4, separable=True, fit_on="simpson", solver="normal",
                         domain=[[-4.0, 4.0], [-3.5, 3.5]]),
    VectorFieldRegressor(degree=3, threshold=0.02, solver="normal"),
]


def _same(a, b):
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=np.asarray(a).dtype.kind == "f")


@pytest.mark.filterwarnings("ignore::sk_hamiltonian.ConservationWarning")
@pytest.mark.filterwarnings("ignore::sk_hamiltonian.DomainWarning")
@pytest.mark.parametrize("estimator", CASES, ids=lambda e: repr(e)[:60])
def test_the_four_steps_give_fit_bit_for_bit(layout, estimator):
    fitted = clone(estimator).fit(layout)
    model = clone(estimator)
    data = model._training_data(layout, None, None)
    space = steps.build_space(model, data)                          # (a)
    equations = steps.normal_equations(model, space, data)          # (b)
    residual = model._design(space).residual(data)
    solution = steps.solve_normal_equations(model, space, equations, residual)  # (c)
    assert steps.set_fitted(model, space, solution, data) is model  # (d)
    for name in ATTRIBUTES:
        assert _same(getattr(model, name), getattr(fitted, name)), name
    if isinstance(model, HamiltonianRegressor):
        for name in ("damping_", "energy_trend_", "energy_trend_z_"):
            assert _same(getattr(model, name), getattr(fitted, name)), name
    assert np.array_equal(model.predict(layout[:3]), fitted.predict(layout[:3]))


def test_normal_equations_of_some_trajectories_are_those_of_a_fit_on_them(layout):
    model = HamiltonianRegressor(degree=5, damping=True)
    data = model._training_data(layout, None, None)
    space = steps.build_space(model, data)
    some = np.array([7, 2, 40, 13])
    taken = steps.normal_equations(model, space, data.take_trajectories(some))
    direct = steps.normal_equations(model, space, clone(model)._training_data(layout[some], None, None))
    for a, b in zip(taken, direct):
        assert np.array_equal(a, b)
    # Disjoint pieces add up to the whole (to round-off: another order of sums).
    rest = np.setdiff1d(np.arange(layout.shape[0]), some)
    other = steps.normal_equations(model, space, data.take_trajectories(rest))
    whole = steps.normal_equations(model, space, data)
    for part, complement, total in zip(taken, other, whole):
        np.testing.assert_allclose(part + complement, total, rtol=1e-12,
                                   atol=1e-12 * np.abs(total).max())
    # Weights of the trajectories travel with them.
    weights = np.random.default_rng(1).uniform(0.5, 2.0, layout.shape[0])
    weighted = model._training_data(layout, None, weights, reset=False).take_trajectories(some)
    assert np.array_equal(weighted.trajectory_weight, weights[some])
    assert np.array_equal(weighted.sample_weight, np.repeat(weights[some], layout.shape[1]))


def test_taking_trajectories_needs_trajectories():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(50, 2))
    data = HamiltonianRegressor()._training_data(X, X[:, ::-1], None)
    with pytest.raises(ValueError, match="needs trajectories"):
        data.take_trajectories([0])


@pytest.mark.filterwarnings("ignore::sk_hamiltonian.DomainWarning")
@pytest.mark.parametrize("estimator", [
    HamiltonianRegressor(degree=5, damping=True),                # factored on a value basis
    HamiltonianRegressor(degree=4, separable=True, damping=True),  # grouped by variable
    VectorFieldRegressor(degree=3),                               # several targets
], ids=["factored", "grouped", "vector field"])
def test_btb_gives_the_residual_without_the_design(layout, estimator):
    model = clone(estimator)
    weights = np.random.default_rng(2).uniform(0.5, 2.0, layout.shape[0])
    data = model._training_data(layout, None, weights)
    space = steps.build_space(model, data)
    design = model._design(space)
    gram, rhs, btb = steps.normal_equations(model, space, data)
    blocks = list(design.blocks(data))
    A = np.vstack([np.array(a) for a, _ in blocks])
    b = np.concatenate([np.array(t) for _, t in blocks])
    coef = np.random.default_rng(3).normal(size=rhs.shape)
    residual = A @ coef - b
    if b.ndim == 1:
        expected, got = residual @ residual, coef @ gram @ coef - 2 * coef @ rhs + btb
    else:  # one residual per target, on the diagonal
        expected = np.sum(residual**2, axis=0)
        got = np.diag(coef.T @ gram @ coef - 2 * coef.T @ rhs + btb)
        assert btb.shape == (b.shape[1], b.shape[1])
    np.testing.assert_allclose(got, expected, rtol=1e-9)
    np.testing.assert_allclose(btb if b.ndim == 1 else np.diag(btb), np.sum(b**2, axis=0),
                               rtol=1e-12)


@pytest.mark.filterwarnings("ignore::sk_hamiltonian.ConservationWarning")
def test_one_box_shared_by_candidates(layout):
    box = [[-10.0, 10.0], [-5.0, 5.0]]
    model = HamiltonianRegressor(degree=4)
    data = model._training_data(layout, None, None)
    space = steps.build_space(model, data, domain=box)
    assert np.array_equal(space.domain, box)
    fitted = HamiltonianRegressor(degree=4, domain=box).fit(layout)
    assert np.array_equal(space.powers, fitted.powers_)
    # Nothing is set on the estimator by the first steps.
    assert not hasattr(model, "coef_") and not hasattr(model, "domain_")


def test_steps_check_the_parameters_as_fit_does(layout):
    model = HamiltonianRegressor(degree=4, domain=[[0.0, 1.0], [0.0, 1.0]])
    data = model._training_data(layout, None, None)
    with pytest.warns(DomainWarning, match="outside the domain"):
        steps.build_space(model, data)
    with pytest.raises(ValueError, match="couplings"):
        steps.build_space(HamiltonianRegressor(couplings=[(0, 7)]), data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        steps.build_space(HamiltonianRegressor(degree=4), data)
