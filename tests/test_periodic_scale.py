"""Periodic and mixed coordinates the trajectories cannot resolve are refused before the fit."""

import time

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
from sk_hamiltonian._angle_steps import LONGEST_ANGLE_STEP, check_angle_steps
from sk_hamiltonian.datasets import make_trajectories, single_pendulum

DT = 0.05


def _pendulum(scale=1.0, n_trajectories=60, n_intervals=40, domain=None):
    """Pendulum trajectories ``(p, q)`` with ``q`` multiplied by ``scale``, in the derivative layout."""
    X = make_trajectories(single_pendulum(), n_trajectories, n_intervals, dt=DT, domain=domain,
                          random_state=0)
    X[..., 1] *= scale
    return X, DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)


# The reported case: a position spanning +-5e6 (here the angle times about 8e5).
SCALE = 5e6 / (2 * np.pi)


@pytest.mark.parametrize("argument", ["periodic", "mixed"])
def test_a_coordinate_in_wrong_units_is_refused_with_the_argument_and_the_fix(argument):
    X, Xt = _pendulum(SCALE)
    assert np.abs(X[..., 1]).max() > 1e6
    model = HamiltonianRegressor(degree=4, **{argument: [False, True]})
    with pytest.raises(ValueError) as caught:
        model.fit(Xt)
    message = str(caught.value)
    assert f"{argument}=[False, True]" in message
    assert "state variable 1" in message and "median step" in message
    assert "radians" in message or "radian" in message
    assert f"set {argument} to False" in message


def test_the_message_names_the_column_in_the_users_order_and_its_name():
    _, Xt = _pendulum(SCALE)
    # (q, p) order: the angle is column 0, and is named.
    Xt_qp = Xt.copy()
    Xt_qp[..., [1, 2]] = Xt[..., [2, 1]]
    Xt_qp[..., [3, 4]] = Xt[..., [4, 3]]
    Xt_qp[..., [5, 6]] = Xt[..., [6, 5]]
    model = HamiltonianRegressor(degree=4, periodic=[True, False], state_order="qp",
                                 state_names=["theta", "p_theta"])
    with pytest.raises(ValueError, match=r"state variable 0 \('theta'\)"):
        model.fit(Xt_qp)


def test_the_check_itself_is_fast():
    # 2000 trajectories of 201 samples: 400 000 states.
    from sk_hamiltonian._space.space import ModelSpace
    from sk_hamiltonian._training_data import TrainingData

    rng = np.random.default_rng(0)
    states = rng.normal(size=(2000 * 201, 2)) * [1.0, 5e6]
    t = np.arange(201) * DT
    pieces = np.split(states, 2000)
    data = TrainingData(states, states, trajectories=[(t, S) for S in pieces])
    space = ModelSpace([[-1.0, 1.0], [-5e6, 5e6]], np.array([[1, 0], [0, -1]]),
                       mixed=[False, True])
    start = time.perf_counter()
    with pytest.raises(ValueError, match="mixed"):
        check_angle_steps(HamiltonianRegressor(mixed=[False, True]), space, data)
    assert time.perf_counter() - start < 0.5


@pytest.mark.parametrize("argument", ["periodic", "mixed"])
def test_a_normal_pendulum_still_fits(argument):
    _, Xt = _pendulum()
    model = HamiltonianRegressor(degree=4, **{argument: [False, True]}).fit(Xt)
    assert model.score(Xt[:10]) > 0.99


def test_a_pendulum_above_the_separatrix_over_many_turns_still_fits():
    # Rotating from p in (7, 9) (the separatrix is at p = 2 sqrt(g) ~ 6.3):
    # q grows over many periods, unwrapped, with steps of about 0.4 rad.
    X, Xt = _pendulum(n_trajectories=20, n_intervals=400, domain=[[7.0, 9.0], [-np.pi, np.pi]])
    assert np.ptp(X[..., 1], axis=1).min() > 10 * 2 * np.pi
    model = HamiltonianRegressor(degree=4, periodic=[False, True]).fit(Xt)
    assert model.score(Xt[:5]) > 0.99


def test_an_unwrapped_free_rotor_over_many_turns_still_fits():
    # H = p^2 / 2: q = q0 + p t, over 100 turns at steps of 0.3 to 0.5 rad.
    p = np.linspace(6.0, 10.0, 8)
    t = np.arange(2001) * DT
    X = np.stack([np.broadcast_to(p[:, None], (8, t.size)), p[:, None] * t], axis=-1)
    assert np.ptp(X[..., 1], axis=1).min() > 100 * np.pi
    Xt = DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=2, mixed=[False, True], threshold=1e-6).fit(Xt)
    np.testing.assert_allclose(model.predict(X[0, :5]), np.column_stack([np.zeros(5), p[[0] * 5]]),
                               atol=1e-6)


def test_the_limit_sits_between_resolved_and_aliased_steps():
    # Just under the limit passes, just over it is refused: the rule is the median step.
    from sk_hamiltonian._space.space import ModelSpace
    from sk_hamiltonian._training_data import TrainingData

    space = ModelSpace([[-1.0, 1.0], [-np.pi, np.pi]], np.array([[1, 0], [0, 1]]),
                       periodic=[False, True])
    t = np.arange(50) * DT
    model = HamiltonianRegressor(periodic=[False, True])
    for factor, refused in ((0.99, False), (1.01, True)):
        q = np.arange(50) * LONGEST_ANGLE_STEP * factor
        # A few long steps (wrapping back into the period) do not move the median.
        q[::7] += 2 * np.pi
        S = np.column_stack([np.ones(50), q])
        data = TrainingData(S, S, trajectories=[(t, S)])
        if refused:
            with pytest.raises(ValueError, match="periodic"):
                check_angle_steps(model, space, data)
        else:
            check_angle_steps(model, space, data)


def test_two_dimensional_states_are_not_checked():
    # Without trajectories there are no steps: the span alone cannot tell an
    # unwrapped rotor from wrong units, so the fit goes ahead.
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(200, 2)) * [2.0, 5e6]
    y = np.column_stack([-np.sin(X[:, 1]), X[:, 0]])
    HamiltonianRegressor(degree=2, mixed=[False, True]).fit(X, y)
