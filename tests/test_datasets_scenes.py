"""Tests of the systems beyond the paper's five, and of the periodic flags."""

import re
from pathlib import Path

import numpy as np
import pytest

from sk_hamiltonian.datasets import (
    SCENES,
    SYSTEMS,
    HamiltonianSystem,
    coupled_pendula,
    double_well,
    damped_pendulum,
    double_pendulum,
    fput_chain,
    load_system,
    make_trajectories,
    single_pendulum,
    toda_lattice,
    torsion_pendulum,
)

BOUNDARIES = ["fixed", "periodic"]

# Non-default parameters catch formulas that only hold for the defaults; an
# odd n_particles catches index slips that an even one can hide.
CHAIN_CASES = [
    (fput_chain, dict()),
    (fput_chain, dict(alpha=0.3, beta=0.7)),
    (fput_chain, dict(alpha=-0.25, beta=0.0)),
    (toda_lattice, dict()),
]
CHAIN_IDS = ["fput", "fput-alpha-beta", "fput-alpha-only", "toda"]


def _points_in_domain(system, n, seed=0):
    rng = np.random.RandomState(seed)
    return rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(n, 2 * system.n_dof))


def _finite_difference_gradient(system, X, h=1e-5):
    fd = np.empty_like(X)
    for j in range(X.shape[-1]):
        step = np.zeros(X.shape[-1])
        step[j] = h
        fd[..., j] = (system.hamiltonian(X + step) - system.hamiltonian(X - step)) / (2 * h)
    return fd


def _bond_potential(factory, params):
    if factory is toda_lattice:
        return lambda r: np.exp(-r) + r - 1, lambda r: 1 - np.exp(-r)
    alpha, beta = params.get("alpha", 0.0), params.get("beta", 1.0)
    return (
        lambda r: r**2 / 2 + alpha * r**3 / 3 + beta * r**4 / 4,
        lambda r: r + alpha * r**2 + beta * r**3,
    )


def _padded(q, boundary):
    """``(q_0, q_1, ..., q_N, q_{N+1})`` of one state; on a ring ``q_0 = q_N``."""
    if boundary == "fixed":
        return [0.0, *q, 0.0]
    return [q[-1], *q, q[0]]


def _reference_energy(x, V, boundary):
    """``H`` of one chain state by an explicit sum over the bonds."""
    n = x.size // 2
    p, q = x[:n], x[n:]
    Q = _padded(q, boundary)
    # A ring's bond (q_0, q_1) is its bond (q_N, q_{N+1}): count it once.
    first = 0 if boundary == "fixed" else 1
    bonds = [Q[i + 1] - Q[i] for i in range(first, n + 1)]
    assert len(bonds) == (n + 1 if boundary == "fixed" else n)
    return sum(pi**2 / 2 for pi in p) + sum(V(r) for r in bonds)


def _reference_equations(x, dV, boundary):
    """Newton's equations of one chain state, particle by particle."""
    n = x.size // 2
    p, q = x[:n], x[n:]
    Q = _padded(q, boundary)
    dpdt = [dV(Q[i + 1] - Q[i]) - dV(Q[i] - Q[i - 1]) for i in range(1, n + 1)]
    return np.concatenate([dpdt, p])


@pytest.mark.parametrize("n_particles", [2, 3, 8, 33])
@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("factory, params", CHAIN_CASES, ids=CHAIN_IDS)
def test_chain_gradient_matches_finite_differences(factory, params, boundary, n_particles):
    system = factory(n_particles, boundary=boundary, **params)
    X = _points_in_domain(system, 6, seed=n_particles)
    np.testing.assert_allclose(
        system.gradient(X), _finite_difference_gradient(system, X), rtol=1e-6, atol=1e-7
    )


@pytest.mark.parametrize("n_particles", [2, 3, 8])
@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("factory, params", CHAIN_CASES, ids=CHAIN_IDS)
def test_chain_matches_definition(factory, params, boundary, n_particles):
    # H and Hamilton's equations against the sums in the docstrings, bond by
    # bond and particle by particle.
    system = factory(n_particles, boundary=boundary, **params)
    V, dV = _bond_potential(factory, params)
    X = _points_in_domain(system, 5, seed=1)
    np.testing.assert_allclose(
        system.hamiltonian(X), [_reference_energy(x, V, boundary) for x in X], rtol=1e-12
    )
    np.testing.assert_allclose(
        system.vector_field(X),
        [_reference_equations(x, dV, boundary) for x in X],
        rtol=1e-12,
        atol=1e-12,
    )


@pytest.mark.parametrize("boundary", BOUNDARIES)
def test_toda_linear_term_only_shifts_energy(boundary):
    # The stretches telescope to zero, so H is the classical Toda energy minus
    # the number of bonds.
    n = 5
    system = toda_lattice(n, boundary=boundary)
    X = _points_in_domain(system, 10, seed=2)
    p, q = X[:, :n], X[:, n:]
    if boundary == "fixed":
        r = np.diff(np.pad(q, ((0, 0), (1, 1))), axis=1)
    else:
        r = np.roll(q, -1, axis=1) - q
    classical = 0.5 * np.sum(p**2, axis=1) + np.sum(np.exp(-r), axis=1)
    np.testing.assert_allclose(system.hamiltonian(X), classical - r.shape[1], rtol=1e-12)


@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("factory", [fput_chain, toda_lattice])
def test_chain_evaluates_over_leading_axes(factory, boundary):
    system = factory(7, boundary=boundary)
    X = _points_in_domain(system, 12, seed=3).reshape(3, 4, 14)
    grad = system.gradient(X)
    H = system.hamiltonian(X)
    assert grad.shape == X.shape and H.shape == (3, 4)
    for index in np.ndindex(3, 4):
        np.testing.assert_array_equal(grad[index], system.gradient(X[index]))
        np.testing.assert_array_equal(H[index], system.hamiltonian(X[index]))


@pytest.mark.parametrize(
    "system",
    [
        fput_chain(4),
        fput_chain(5, alpha=0.3, boundary="periodic"),
        toda_lattice(4),
        toda_lattice(5, boundary="periodic"),
        double_pendulum(full_circle=True),
        double_pendulum(1.3, 0.7, 0.9, 1.2, 9.81, full_circle=True, momentum_bound=3.0),
        torsion_pendulum(), coupled_pendula(0.5, 3.0),
    ],
    ids=repr,
)
def test_vector_field_is_inverse_symplectic_gradient(system):
    X = _points_in_domain(system, 8, seed=4)
    d = system.n_dof
    grad = system.gradient(X)
    field = system.vector_field(X)
    np.testing.assert_array_equal(field[:, :d], -grad[:, d:])
    np.testing.assert_array_equal(field[:, d:], grad[:, :d])


@pytest.mark.parametrize(
    "system",
    [
        fput_chain(3),
        fput_chain(16, alpha=0.3, boundary="periodic"),
        toda_lattice(3, boundary="periodic"),
        toda_lattice(16),
        double_pendulum(full_circle=True),
        torsion_pendulum(),
        coupled_pendula(),
        double_well(),
    ],
    ids=repr,
)
def test_solve_conserves_energy(system):
    x0 = np.vstack([system.initial_state, _points_in_domain(system, 2, seed=5)])
    X = system.solve(x0, np.linspace(0.0, 2.0, 41))
    H = system.hamiltonian(X)
    drift = np.abs(H - H[:, :1]) / np.maximum(np.abs(H[:, :1]), 1.0)
    assert drift.max() < 1e-8
    # Guard against a trivially constant solution.
    assert np.abs(X[:, -1] - X[:, 0]).max(axis=1).min() > 1e-2


@pytest.mark.parametrize("n_particles", [2, 3, 8])
@pytest.mark.parametrize("boundary", BOUNDARIES)
@pytest.mark.parametrize("factory", [fput_chain, toda_lattice])
def test_chain_test_trajectory_stays_in_domain(factory, boundary, n_particles):
    system = factory(n_particles, boundary=boundary)
    X = system.solve(system.initial_state, np.linspace(0.0, 30.0, 301), max_step=0.01)
    assert np.all((X >= system.domain[:, 0]) & (X <= system.domain[:, 1]))
    # It does move: the momenta are zero only at the start.
    assert np.abs(X[:, :n_particles]).max() > 0.05


@pytest.mark.parametrize("boundary", BOUNDARIES)
def test_chain_initial_state_is_longest_standing_wave(boundary):
    n = 6
    system = fput_chain(n, boundary=boundary)
    p0, q0 = system.initial_state[:n], system.initial_state[n:]
    np.testing.assert_array_equal(p0, 0.0)
    i = np.arange(1, n + 1)
    if boundary == "fixed":
        expected = np.sin(np.pi * i / (n + 1))
    else:
        expected = np.cos(2 * np.pi * i / n)
    np.testing.assert_allclose(q0, 0.4 * expected, rtol=1e-15)
    toda = toda_lattice(n, boundary=boundary)
    np.testing.assert_array_equal(system.initial_state, toda.initial_state)


def test_ring_of_two_initial_state_is_not_at_rest():
    system = fput_chain(2, boundary="periodic")
    assert np.abs(system.vector_field(system.initial_state)).max() > 0.1


def test_chain_momentum_conservation_depends_on_boundary():
    # A ring's forces cancel (it is translation invariant); walls push back.
    X = _points_in_domain(fput_chain(6), 20, seed=6)
    ring = fput_chain(6, boundary="periodic").vector_field(X)[:, :6].sum(axis=1)
    walls = fput_chain(6).vector_field(X)[:, :6].sum(axis=1)
    np.testing.assert_allclose(ring, 0.0, atol=1e-12)
    assert np.abs(walls).min() > 1e-6


def test_double_pendulum_full_circle_is_the_same_physics():
    params = dict(m1=1.3, m2=0.7, l1=0.9, l2=1.2, g=9.81)
    full = double_pendulum(**params, full_circle=True, momentum_bound=2.0)
    paper = double_pendulum(**params)
    # Full-circle states and wider ones (outside the paper's domain).
    X = np.vstack(
        [_points_in_domain(full, 20, seed=7), 3 * _points_in_domain(paper, 20, seed=8)]
    )
    np.testing.assert_array_equal(full.hamiltonian(X), paper.hamiltonian(X))
    np.testing.assert_array_equal(full.gradient(X), paper.gradient(X))


def test_double_pendulum_full_circle_domain_and_flags():
    system = double_pendulum(full_circle=True, momentum_bound=2.5)
    assert system.name == "double_pendulum_full_circle"
    np.testing.assert_array_equal(
        system.domain, [[-2.5, 2.5], [-2.5, 2.5], [-np.pi, np.pi], [-np.pi, np.pi]]
    )
    np.testing.assert_array_equal(system.periodic, [False, False, True, True])
    assert np.all(system.domain[:, 0] < system.initial_state)
    assert np.all(system.initial_state < system.domain[:, 1])
    # Large swing: beyond the paper's angle domain (-1, 1).
    assert np.abs(system.initial_state[2:]).max() > 1.5
    assert system.paper_settings == {}
    assert system.params["momentum_bound"] == 2.5
    assert "momentum_bound=2.5" in repr(system)


def test_double_pendulum_default_is_unchanged():
    system = double_pendulum()
    assert repr(system) == (
        "HamiltonianSystem(name='double_pendulum', n_dof=2, m1=1.0, m2=1.0, l1=1.0, "
        "l2=1.0, g=9.8)"
    )
    np.testing.assert_array_equal(
        system.domain, [[-5.0, 5.0], [-4.0, 4.0], [-1.0, 1.0], [-1.0, 1.0]]
    )
    np.testing.assert_array_equal(system.initial_state, [0.0, 0.0, np.pi / 6, np.pi / 4])
    np.testing.assert_array_equal(system.periodic, False)
    # momentum_bound only shapes the full-circle domain.
    np.testing.assert_array_equal(double_pendulum(momentum_bound=3.0).domain, system.domain)


@pytest.mark.parametrize("angle", [2, 3])
def test_double_pendulum_full_circle_is_periodic_in_each_angle(angle):
    system = double_pendulum(1.3, 0.7, 0.9, 1.2, 9.81, full_circle=True)
    X = _points_in_domain(system, 30, seed=9)
    period = system.domain[angle, 1] - system.domain[angle, 0]
    np.testing.assert_allclose(period, 2 * np.pi, rtol=1e-15)
    for k in (-2, 1, 3):
        shifted = X.copy()
        shifted[:, angle] += k * period
        np.testing.assert_allclose(
            system.hamiltonian(shifted), system.hamiltonian(X), rtol=1e-12, atol=1e-12
        )
        np.testing.assert_allclose(
            system.gradient(shifted), system.gradient(X), rtol=1e-11, atol=1e-11
        )
    # Half a period is not a period, so the check above can tell.
    shifted = X.copy()
    shifted[:, angle] += np.pi
    assert np.abs(system.hamiltonian(shifted) - system.hamiltonian(X)).max() > 1.0


def test_double_pendulum_full_circle_test_state_is_regular():
    # A 1e-8 perturbation of u0* stays small over t = 30; from (0, 0, 2, -1),
    # a chaotic start, the same perturbation grows to order one.
    system = double_pendulum(full_circle=True)
    chaotic = np.array([0.0, 0.0, 2.0, -1.0])
    direction = np.array([0.5, -0.5, 0.5, 0.5]) * 1e-8
    u0 = system.initial_state
    x0 = np.vstack([u0, u0 + direction, chaotic, chaotic + direction])
    X = system.solve(x0, np.linspace(0.0, 30.0, 31), max_step=5e-3)
    regular_gap = np.abs(X[1] - X[0]).max()
    chaotic_gap = np.abs(X[3] - X[2]).max()
    assert regular_gap < 1e-5
    assert chaotic_gap > 1e-2


def test_periodic_defaults_to_none_marked():
    for name, factory in {**SYSTEMS, **SCENES}.items():
        system = factory()
        expected = name == "double_pendulum_full_circle"
        np.testing.assert_array_equal(system.periodic[system.n_dof:], expected, err_msg=name)
        np.testing.assert_array_equal(system.periodic[: system.n_dof], False, err_msg=name)
        assert system.periodic.dtype == bool and not system.periodic.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            system.periodic[0] = True


def _identity(X):
    return X[..., 0]


@pytest.mark.parametrize(
    "periodic, domain, match",
    [
        ([True], [[0, 1], [0, 1]], r"periodic must be a boolean array of shape \(2,\)"),
        ([1, 0], [[0, 1], [0, 1]], "periodic must be a boolean array.*int"),
        ([[True, False]], [[0, 1], [0, 1]], r"shape \(1, 2\)"),
        ([False, True], [[0, 1], [1, 1]], "one full period.*low < high"),
        ([False, True], [[0, 1], [0, np.inf]], "must be finite"),
    ],
)
def test_periodic_validation(periodic, domain, match):
    with pytest.raises(ValueError, match=match):
        HamiltonianSystem("x", _identity, _identity, domain, [0.5, 0.5], periodic=periodic)


def test_periodic_is_copied_and_a_degenerate_non_periodic_row_is_allowed():
    flags = np.array([True, False])
    system = HamiltonianSystem(
        "x", _identity, _identity, [[0, 1], [1, 1]], [0.5, 1.0], periodic=flags
    )
    flags[0] = False
    np.testing.assert_array_equal(system.periodic, [True, False])


@pytest.mark.parametrize(
    "factory, kwargs, match",
    [
        (fput_chain, dict(n_particles=1), "n_particles must be an integer >= 2"),
        (toda_lattice, dict(n_particles=1), "n_particles must be an integer >= 2"),
        (fput_chain, dict(n_particles=8.0), "n_particles must be an integer >= 2"),
        (toda_lattice, dict(n_particles=True), "n_particles must be an integer >= 2"),
        (fput_chain, dict(boundary="open"), "boundary must be 'fixed'.*or 'periodic'"),
        (toda_lattice, dict(boundary="Fixed"), "boundary must be 'fixed'.*or 'periodic'"),
        (toda_lattice, dict(boundary=None), "boundary must be 'fixed'.*got None"),
        (fput_chain, dict(alpha=np.nan), "alpha must be a finite number"),
        (fput_chain, dict(beta="1"), "beta must be a finite number"),
        (fput_chain, dict(beta=-0.5), "beta must be >= 0"),
        (double_pendulum, dict(full_circle="yes"), "full_circle must be True or False"),
        (double_pendulum, dict(full_circle=True, momentum_bound=0.0), "momentum_bound must"),
        (double_pendulum, dict(full_circle=True, momentum_bound=np.inf), "momentum_bound must"),
    ],
)
def test_factory_validation(factory, kwargs, match):
    with pytest.raises(ValueError, match=match):
        factory(**kwargs)


def test_scenes_registry():
    assert set(SYSTEMS) == {
        "single_pendulum", "exponential", "henon_heiles", "cherry", "double_pendulum"
    }
    assert set(SCENES) == {
        "anharmonic_spring", "coupled_pendula", "damped_pendulum",
        "double_pendulum_full_circle", "double_well", "fput_chain", "toda_lattice", "torsion_pendulum",
    }
    for name, factory in SCENES.items():
        system = factory()
        assert isinstance(system, HamiltonianSystem) and system.name == name
        assert system.paper_settings == {}
        assert np.all(system.domain[:, 0] < system.initial_state)
        assert np.all(system.initial_state < system.domain[:, 1])
        assert not system.domain.flags.writeable and not system.initial_state.flags.writeable
        # load_system reaches it, and its params rebuild it.
        assert repr(load_system(name)) == repr(system)
        assert repr(load_system(name, **system.params)) == repr(system)
    assert load_system("toda_lattice", n_particles=16, boundary="periodic").n_dof == 16
    assert load_system("double_pendulum_full_circle", g=1.0).params["g"] == 1.0


def test_damped_pendulum_is_the_pendulum_with_friction():
    system = damped_pendulum(0.2, length=1.5, g=9.0)
    reference = single_pendulum(1.5, 9.0, damping=0.2)
    assert repr(system) == repr(reference)
    np.testing.assert_array_equal(system.damping, [0.2])
    X = _points_in_domain(system, 6, seed=1)
    np.testing.assert_array_equal(system.vector_field(X), reference.vector_field(X))
    # Friction takes energy: dH/dt = -gamma (dq/dt)^2 = -gamma (p / l^2)^2 <= 0,
    # so H falls step by step and loses exactly that integral (trapezoid rule
    # on 2001 samples: relative error about 1e-6, so 1e-4 is the tolerance).
    t = np.linspace(0.0, 5.0, 2001)
    Y = system.solve(system.initial_state, t, max_step=1e-3)
    H = system.hamiltonian(Y)
    assert np.all(np.diff(H) < 0)
    power = 0.2 * (Y[:, 0] / 1.5**2) ** 2
    lost = np.sum((power[1:] + power[:-1]) / 2 * np.diff(t))
    assert H[0] - H[-1] == pytest.approx(lost, rel=1e-4)


@pytest.mark.parametrize(
    "system", [torsion_pendulum(1.5, 3.0), coupled_pendula(0.7, 5.0), double_well(0.5, 2.0)],
    ids=repr)
def test_mixed_scenes_gradient_matches_finite_differences(system):
    X = _points_in_domain(system, 5, seed=7)
    h = 1e-6
    numeric = np.stack([(system.hamiltonian(X + h * e) - system.hamiltonian(X - h * e)) / (2 * h)
                        for e in np.eye(X.shape[1])], axis=1)
    np.testing.assert_allclose(system.gradient(X), numeric, atol=1e-7)


def test_mixed_scenes_match_their_formulas():
    p, q = 0.7, -2.5
    assert torsion_pendulum(1.5, 3.0).hamiltonian([p, q]) == pytest.approx(
        p**2 / 2 + 1.5 * q**2 / 2 + 3.0 * (1 - np.cos(q)))
    p1, p2, q1, q2 = 0.3, -0.4, 1.1, -0.6
    assert coupled_pendula(0.7, 5.0).hamiltonian([p1, p2, q1, q2]) == pytest.approx(
        (p1**2 + p2**2) / 2 + 5.0 * (2 - np.cos(q1) - np.cos(q2)) + 0.7 * (q1 - q2) ** 2 / 2)


@pytest.mark.parametrize("damping", [0.0, -0.1, np.inf, "0.1"])
def test_damped_pendulum_needs_positive_friction(damping):
    with pytest.raises(ValueError, match="damping must be a positive finite number"):
        damped_pendulum(damping)


def test_readme_lists_the_scenes_the_datasets_export():
    # The README's feature list names the scenes beyond the paper: exactly the
    # keys of SCENES, each of which load_system builds under that name.
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    line = re.search(r"scenes beyond the paper \(`SCENES`: (.*?)\)\.\n", readme, re.S)
    assert line, "the README's datasets item no longer lists SCENES"
    listed = re.findall(r"`(\w+)`", line.group(1))
    assert sorted(listed) == sorted(SCENES)
    for name in listed:
        assert load_system(name).name == name


def test_chain_repr_and_params():
    system = fput_chain(5, alpha=0.1, boundary="periodic")
    assert repr(system) == (
        "HamiltonianSystem(name='fput_chain', n_dof=5, n_particles=5, alpha=0.1, "
        "beta=1.0, boundary='periodic')"
    )
    assert repr(toda_lattice()) == (
        "HamiltonianSystem(name='toda_lattice', n_dof=8, n_particles=8, boundary='fixed')"
    )


def test_load_system_lists_every_name():
    with pytest.raises(ValueError, match="valid names are") as info:
        load_system("fpu")
    for name in [*SYSTEMS, *SCENES]:
        assert repr(name) in str(info.value)


def test_make_trajectories_of_a_long_chain():
    system = fput_chain(32)
    X = make_trajectories(system, 50, 2, dt=0.01, random_state=0)
    assert X.shape == (50, 3, 64)
    assert np.all(np.isfinite(X))
    x0 = X[:, 0]
    assert np.all((x0 >= -1.0) & (x0 < 1.0))
    H = system.hamiltonian(X)
    np.testing.assert_allclose(H, np.broadcast_to(H[:, :1], H.shape), rtol=1e-9)
    assert np.abs(X[:, -1] - X[:, 0]).max() > 1e-3
    # By name too, with the chain's parameters.
    Y = make_trajectories("toda_lattice", 3, 1, dt=0.01, random_state=0)
    assert Y.shape == (3, 2, 16)
