"""States given as (q, p) instead of (p_1..p_d, q_1..q_d) are named in a StateOrderWarning."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, StateOrderWarning
from sk_hamiltonian._state_order import SHARE, order_evidence
from sk_hamiltonian.datasets import (
    HamiltonianSystem,
    double_well,
    exponential,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)


def anharmonic_spring():
    """``H = p^2/2 + q^2/2 + q^4/4``."""

    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        return X[..., 0] ** 2 / 2 + X[..., 1] ** 2 / 2 + X[..., 1] ** 4 / 4

    def gradient(X):
        X = np.asarray(X, dtype=float)
        return np.stack([X[..., 0], X[..., 1] + X[..., 1] ** 3], axis=-1)

    return HamiltonianSystem("anharmonic_spring", hamiltonian, gradient,
                             domain=[[-1, 1], [-1, 1]], initial_state=[0.5, 0.5])


# (system, data, regressor's degree). The paper's pendulum (8 % noise) swings
# past a quarter turn, where -V'' = -9.8 cos q turns positive: exchanged, only
# the average near the momenta's median is negative; the double well's is
# positive there (its barrier), only the average over all states is negative.
SCENES = {
    "pendulum": (single_pendulum, dict(n_trajectories=60, noise=0.01), 4),
    "paper_pendulum": (single_pendulum, dict(n_trajectories=500, noise=0.08), 8),
    "spring": (anharmonic_spring, dict(n_trajectories=60, noise=0.01), 4),
    "henon_heiles": (henon_heiles, dict(n_trajectories=60, noise=0.01), 3),
    "double_well": (double_well, dict(n_trajectories=100, noise=0.02), 4),
}


def swapped(X):
    """``(q, p)`` from ``(p, q)`` (and back): the two halves of the last axis exchanged."""
    d = X.shape[-1] // 2
    return np.concatenate([X[..., d:], X[..., :d]], axis=-1)


def fit_caught(X, dt=0.01, method="polynomial", **params):
    """Fit on trajectories ``X``; the model, its training states and its StateOrderWarnings."""
    Xt = DerivativeTransformer(dt=dt, method=method).fit_transform(X)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = HamiltonianRegressor(**params).fit(Xt)
    states = Xt[..., 1 : 1 + X.shape[-1]].reshape(-1, X.shape[-1])
    return model, states, [w for w in caught if issubclass(w.category, StateOrderWarning)]


@pytest.fixture(scope="module", params=sorted(SCENES))
def scene(request):
    make, data, degree = SCENES[request.param]
    X = make_trajectories(make(), n_intervals=40, dt=0.01, random_state=0, **data)
    return X, degree


def test_states_in_q_p_order_warn_once_with_the_fix(scene):
    X, degree = scene
    model, states, caught = fit_caught(swapped(X), degree=degree)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "the states look ordered (q, p)" in message
    # The fix named is the parameter (tests/test_state_order_option.py checks
    # that it removes the warning and gives the (p, q) fit).
    assert "Fit with state_order='qp'" in message and "\n" not in message
    momenta, share, _ = order_evidence(model, states)
    assert np.all(momenta < 0, axis=1).any() and share >= SHARE


def test_states_in_p_q_order_do_not_warn(scene):
    X, degree = scene
    model, states, caught = fit_caught(X, degree=degree)
    assert caught == []
    # A kinetic energy: positive curvature in every momentum, on average.
    momenta, _, _ = order_evidence(model, states)
    assert np.all(momenta > 0)


def test_a_maximum_in_p_that_is_no_swap_does_not_warn():
    # The paper's Example 2, H = exp(-p^2 - 1.1 q^4), in the right order: it
    # curves down in p (on average), but not in q at every state, which a
    # negated kinetic energy would.
    X = make_trajectories(exponential(), 300, 2, dt=0.01, random_state=0)
    model, states, caught = fit_caught(X, method="finite_difference", degree=6)
    assert caught == []
    momenta, share, _ = order_evidence(model, states)
    assert np.all(momenta[0] < 0) and share < SHARE


def test_states_with_derivatives_in_q_p_order_warn():
    rng = np.random.default_rng(0)
    states = rng.uniform(-1, 1, size=(200, 2))                    # (p, q)
    derivatives = np.column_stack([-states[:, 1], states[:, 0]])  # H = (p^2 + q^2) / 2
    with warnings.catch_warnings():
        warnings.simplefilter("error", StateOrderWarning)
        HamiltonianRegressor(degree=2).fit(states, derivatives)
    with pytest.warns(StateOrderWarning, match=r"ordered \(q, p\)"):
        HamiltonianRegressor(degree=2).fit(states[:, ::-1], derivatives[:, ::-1])


def test_a_model_flat_in_the_momenta_does_not_warn():
    # momentum_degree=0: no term in p, so its Hessian in p is zero (round-off
    # included), which is no sign of a swapped order.
    X = make_trajectories(anharmonic_spring(), 20, 40, dt=0.01, random_state=1)
    model, states, caught = fit_caught(swapped(X), degree=4, momentum_degree=0)
    assert caught == []
    momenta, _, scale = order_evidence(model, states)
    assert scale > 0 and np.all(np.abs(momenta) <= 1e-8 * scale)
