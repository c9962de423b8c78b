"""Tests of the paper's systems and of the trajectory generator."""

import numpy as np
import pytest

from sk_hamiltonian._integrate import SimulationError
from sk_hamiltonian.datasets import (
    SYSTEMS,
    HamiltonianSystem,
    cherry,
    double_pendulum,
    load_system,
    make_trajectories,
)

# Non-default parameters catch formulas that only hold when they are all 1.
NON_DEFAULT = {
    "single_pendulum": dict(length=1.7, g=9.81),
    "exponential": dict(alpha1=0.8, alpha2=1.3),
    "double_pendulum": dict(m1=1.3, m2=0.7, l1=0.9, l2=1.2, g=9.81),
}
CASES = [(name, {}) for name in SYSTEMS] + list(NON_DEFAULT.items())
CASE_IDS = [name + ("-params" if params else "") for name, params in CASES]


def _points_in_domain(system, n, seed=0):
    rng = np.random.RandomState(seed)
    return rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(n, 2 * system.n_dof))


@pytest.mark.parametrize("name, params", CASES, ids=CASE_IDS)
def test_gradient_matches_finite_differences(name, params):
    system = load_system(name, **params)
    X = _points_in_domain(system, 20)
    h = 1e-5
    fd = np.empty_like(X)
    for j in range(X.shape[1]):
        step = np.zeros(X.shape[1])
        step[j] = h
        fd[:, j] = (system.hamiltonian(X + step) - system.hamiltonian(X - step)) / (2 * h)
    np.testing.assert_allclose(system.gradient(X), fd, rtol=1e-6, atol=1e-7)


def _paper_rhs(name, X, params):
    """Right-hand sides as printed in the paper's eqs. (example1)-(example5)."""
    if name == "single_pendulum":
        l, g = params.get("length", 1.0), params.get("g", 9.8)
        p, q = X.T
        return np.stack([-g * l * np.sin(q), p / l**2], axis=1)
    if name == "exponential":
        a1, a2 = params.get("alpha1", 1.0), params.get("alpha2", 1.1)
        p, q = X.T
        e = np.exp(-a1 * p**2 - a2 * q**4)
        return np.stack([4 * a2 * q**3 * e, -2 * a1 * p * e], axis=1)
    p1, p2, q1, q2 = X.T
    if name == "henon_heiles":
        return np.stack([-q1 - 2 * q1 * q2, -q2 - q1**2 + q2**2, p1, p2], axis=1)
    if name == "cherry":
        return np.stack(
            [
                -q1 + p2 * q1 + q2 * p1,
                2 * q2 + q1 * p1,
                p1 + p2 * p1 - q1 * q2,
                -2 * p2 + 0.5 * (p1**2 - q1**2),
            ],
            axis=1,
        )
    return _paper_double_pendulum(X, **{**dict(m1=1.0, m2=1.0, l1=1.0, l2=1.0, g=9.8), **params})


def _paper_double_pendulum(X, m1, m2, l1, l2, g, c2_power=2):
    # The paper prints C2 with [m1 + m2 sin^2]^1 in the denominator, but
    # differentiating its H gives the square (c2_power=2); see the next test.
    p1, p2, q1, q2 = X.T
    s = q1 - q2
    D = m1 + m2 * np.sin(s) ** 2
    C1 = p1 * p2 * np.sin(s) / (l1 * l2 * D)
    C2 = (
        m2 * l2**2 * p1**2 + (m1 + m2) * l1**2 * p2**2
        - 2 * m2 * l1 * l2 * p1 * p2 * np.cos(s)
    ) / (2 * l1**2 * l2**2 * D**c2_power)
    return np.stack(
        [
            -(m1 + m2) * g * l1 * np.sin(q1) - C1 + C2 * np.sin(2 * s),
            -m2 * g * l2 * np.sin(q2) + C1 - C2 * np.sin(2 * s),
            (l2 * p1 - l1 * p2 * np.cos(s)) / (l1**2 * l2 * D),
            (-m2 * l2 * p1 * np.cos(s) + (m1 + m2) * l1 * p2) / (m2 * l1 * l2**2 * D),
        ],
        axis=1,
    )


@pytest.mark.parametrize("name, params", CASES, ids=CASE_IDS)
def test_vector_field_matches_paper_equations(name, params):
    system = load_system(name, **params)
    X = _points_in_domain(system, 50, seed=1)
    np.testing.assert_allclose(
        system.vector_field(X), _paper_rhs(name, X, params), rtol=1e-12, atol=1e-12
    )


def test_double_pendulum_c2_as_printed_contradicts_hamiltonian():
    # Documents the typo worked around above: the literal C2 is not -dH/dq.
    system = double_pendulum()
    X = _points_in_domain(system, 50, seed=2)
    literal = _paper_double_pendulum(X, 1.0, 1.0, 1.0, 1.0, 9.8, c2_power=1)
    assert np.max(np.abs(literal[:, :2] - system.vector_field(X)[:, :2])) > 1e-2


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_solve_conserves_energy(name):
    system = load_system(name)
    x0 = np.vstack([system.initial_state, 0.5 * _points_in_domain(system, 2, seed=3)])
    X = system.solve(x0, np.linspace(0.0, 1.0, 101))
    H = system.hamiltonian(X)
    drift = np.abs(H - H[:, :1]) / np.abs(H[:, :1])
    assert drift.max() < 1e-8
    # Guard against a trivially constant solution.
    assert np.abs(X[:, -1] - X[:, 0]).max() > 1e-2


def test_solve_shapes_single_and_batch():
    system = load_system("henon_heiles")
    t = np.linspace(0.0, 0.5, 6)
    x0 = _points_in_domain(system, 3, seed=4)
    batch = system.solve(x0, t)
    single = system.solve(x0[1], t)
    assert batch.shape == (3, 6, 4)
    assert single.shape == (6, 4)
    np.testing.assert_array_equal(single, batch[1])
    np.testing.assert_array_equal(batch[:, 0], x0)


def test_solve_matches_exact_linear_solution():
    # Near the origin Henon-Heiles is two unit oscillators: q = A cos t here.
    system = load_system("henon_heiles")
    x0 = np.array([0.0, 0.0, 1e-4, 0.0])
    t = np.linspace(0.0, 2.0, 5)
    X = system.solve(x0, t)
    np.testing.assert_allclose(X[:, 2], 1e-4 * np.cos(t), rtol=1e-6)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(t=np.zeros((2, 2))), "t must be a non-empty 1-D"),
        (dict(t=[0.0, np.nan]), "t must be a non-empty 1-D"),
        (dict(t=[0.0, 0.2, 0.1]), "t must be strictly increasing"),
        (dict(x0=np.zeros(3)), "x0 must have shape"),
        (dict(x0=np.zeros((2, 2, 4))), "x0 must have shape"),
        (dict(x0=[np.nan, 0, 0, 0]), "x0 must be finite"),
        (dict(max_step=0.0), "max_step must be a positive"),
    ],
)
def test_solve_validation(kwargs, match):
    system = load_system("cherry")
    args = dict(x0=system.initial_state, t=[0.0, 0.1])
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        system.solve(**args)


def test_hamiltonian_rejects_wrong_width():
    with pytest.raises(ValueError, match=r"X must have shape \(\.\.\., 4\)"):
        load_system("cherry").hamiltonian(np.zeros((3, 2)))


def test_cherry_blows_up_before_t30_but_not_t20():
    system = cherry()
    t = np.arange(0.0, 30.0 + 1e-9, 0.01)
    with pytest.raises(SimulationError, match="between t=28"):
        system.solve(system.initial_state, t, max_step=2e-3)
    X = system.solve(system.initial_state, t[t <= 20.0], max_step=2e-3)
    assert np.all(np.isfinite(X))


def test_systems_registry_and_paper_data():
    for name, factory in SYSTEMS.items():
        system = factory()
        assert isinstance(system, HamiltonianSystem) and system.name == name
        d2 = 2 * system.n_dof
        assert system.domain.shape == (d2, 2) and system.initial_state.shape == (d2,)
        assert np.all(system.domain[:, 0] < system.initial_state)
        assert np.all(system.initial_state < system.domain[:, 1])
        assert {"degree", "n_trajectories", "n_intervals", "noise"} <= set(
            system.paper_settings
        )
        assert not system.domain.flags.writeable
    assert double_pendulum().paper_settings["t_final"] == 20.0
    assert load_system("single_pendulum").paper_settings["noise"] == 0.08
    assert load_system("exponential", alpha2=2.0).params["alpha2"] == 2.0


def test_load_system_unknown_name():
    with pytest.raises(ValueError, match="valid names are.*cherry"):
        load_system("pendulum")


def test_make_trajectories_shapes_domain_and_dynamics():
    domain = np.array([[-0.5, 0.0], [0.1, 0.3], [-0.2, 0.2], [0.4, 0.9]])
    X, X_clean = make_trajectories(
        "henon_heiles", 40, 3, dt=0.05, domain=domain, random_state=0, return_clean=True
    )
    assert X.shape == X_clean.shape == (40, 4, 4)
    x0 = X_clean[:, 0]
    assert np.all((x0 >= domain[:, 0]) & (x0 < domain[:, 1]))
    # Each component spreads over most of its interval, i.e. the draw is uniform
    # over the requested domain rather than the default one.
    assert np.all(x0.max(axis=0) - x0.min(axis=0) > 0.7 * (domain[:, 1] - domain[:, 0]))
    system = load_system("henon_heiles")
    np.testing.assert_array_equal(X_clean, system.solve(x0, 0.05 * np.arange(4)))


def test_make_trajectories_default_domain():
    system = load_system("cherry")
    X = make_trajectories(system, 200, 1, dt=0.01, random_state=1)
    assert X.shape == (200, 2, 4)
    x0 = X[:, 0]
    assert np.all((x0 >= system.domain[:, 0]) & (x0 < system.domain[:, 1]))


def test_make_trajectories_noise_is_multiplicative_and_bounded():
    noise = 0.08
    X, X_clean = make_trajectories(
        "single_pendulum", 30, 5, dt=0.1, noise=noise, random_state=0, return_clean=True
    )
    ratio = X / X_clean - 1.0
    assert np.all(np.abs(ratio) <= noise + 1e-12)
    # The factor fills [-noise, noise] and differs per entry.
    assert ratio.min() < -0.9 * noise and ratio.max() > 0.9 * noise
    assert np.unique(np.round(ratio, 12)).size > 0.9 * ratio.size


def test_make_trajectories_zero_noise_is_exact():
    X, X_clean = make_trajectories(
        "exponential", 10, 2, dt=0.1, random_state=0, return_clean=True
    )
    np.testing.assert_array_equal(X, X_clean)
    assert X is not X_clean


def test_make_trajectories_random_state():
    kwargs = dict(system="exponential", n_trajectories=5, n_intervals=2, dt=0.1, noise=0.05)
    a = make_trajectories(**kwargs, random_state=42)
    b = make_trajectories(**kwargs, random_state=np.random.RandomState(42))
    c = make_trajectories(**kwargs, random_state=43)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(system=object()), "system must be a HamiltonianSystem"),
        (dict(system="pendulum"), "valid names are"),
        (dict(n_trajectories=0), "n_trajectories must be an integer >= 1"),
        (dict(n_trajectories=2.0), "n_trajectories must be an integer >= 1"),
        (dict(n_intervals=0), "n_intervals must be an integer >= 1"),
        (dict(dt=0.0), "dt must be a positive finite"),
        (dict(dt=np.inf), "dt must be a positive finite"),
        (dict(noise=-0.1), r"noise must be a relative level in \[0, 1\)"),
        (dict(noise=1.0), r"noise must be a relative level in \[0, 1\)"),
        (dict(domain=np.zeros((2, 2))), r"domain must have shape \(4, 2\)"),
        (dict(domain=[[0, 1], [0, 1], [1, 0], [0, 1]]), "low < high"),
    ],
)
def test_make_trajectories_validation(kwargs, match):
    args = dict(system="cherry", n_trajectories=2, n_intervals=1, dt=0.1)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        make_trajectories(**args)


def test_make_trajectories_propagates_blow_up():
    domain = np.column_stack([cherry().initial_state - 1e-3, cherry().initial_state + 1e-3])
    with pytest.raises(SimulationError, match="cherry"):
        make_trajectories("cherry", 3, 30, dt=1.0, domain=domain, random_state=0)
