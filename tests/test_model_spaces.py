"""Model spaces that fit the scene: angles, mechanical and separable Hamiltonians, lattices.

Each test fits a scene with the space its physics suggests and checks the
claim that space is for: accuracy per term (angles), a chain the total-degree
basis cannot reach (lattices), and the integrators a separable model allows.
"""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import (
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    VectorFieldRegressor,
    config_context,
)
from sk_hamiltonian._numba import numba_available
from sk_hamiltonian.datasets import double_pendulum, fput_chain, henon_heiles, make_trajectories
from sk_hamiltonian.inspection import hamiltonian_terms
from sk_hamiltonian.model_selection import count_terms

needs_numba = pytest.mark.skipif(
    not numba_available(), reason="numba is not installed (pip install sk_hamiltonian[fast])"
)


def relative_h_error(model, system, X):
    """RMS error of H~ against H (up to the free constant), over the spread of H."""
    error = model.hamiltonian(X) - system.hamiltonian(X)
    return np.std(error) / np.std(system.hamiltonian(X))


def test_angles_and_momentum_degree_beat_total_degree_on_the_full_circle_pendulum():
    # Both angles over the whole circle: H is periodic in them and quadratic in
    # the momenta. Exact gradients at uniform states isolate the model space.
    system = double_pendulum(g=1.0, full_circle=True)
    rng = np.random.default_rng(0)
    X = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(3000, 4))
    y = system.vector_field(X)
    test = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(2000, 4))
    fourier = HamiltonianRegressor(
        degree=8, domain=system.domain, periodic=system.periodic, momentum_degree=2
    ).fit(X, y)
    total = HamiltonianRegressor(degree=9, domain=system.domain).fit(X, y)
    # Measured: 8.7e-3 with 625 terms against 6.0e-2 with 714 (total degree 9).
    assert fourier.n_terms_ < total.n_terms_
    assert relative_h_error(fourier, system, test) < 1.5e-2
    assert relative_h_error(total, system, test) > 3e-2
    assert fourier.cond_ < 10


@pytest.fixture(scope="module")
def chain_model():
    chain = fput_chain(8)
    # Training bursts drawn where the smooth test state's trajectory lives
    # (|q| <= 0.4, |p| <= 0.14): half the chain's default box.
    X = make_trajectories(chain, 3000, 2, 0.01, domain=chain.domain / 2, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=4, separable=True, max_interaction=2).fit(Xt)
    return chain, model


def test_pairwise_separable_space_follows_the_fput_chain(chain_model):
    chain, model = chain_model
    # 400 of the 4 844 total-degree-4 functions in 16 variables.
    assert model.n_terms_ == 400
    assert count_terms(model, n_states=16) == 400
    t = np.arange(0, 10 + 1e-9, 0.01)
    # RK4 at dt / 10: within 1e-14 of solve's default dt / 100, ten times faster.
    truth = chain.solve(chain.initial_state, t, max_step=0.001)
    for method in ("rk4", "leapfrog", "yoshida4"):
        Y = model.simulate(chain.initial_state, t, method=method)
        error = np.linalg.norm(Y - truth, axis=1) / np.linalg.norm(truth, axis=1)
        # Measured: 1.9e-4 for each method (the model's error, not the integrator's).
        assert error.max() < 1e-3, method


def test_nearest_neighbour_couplings_hold_the_chain_with_a_fraction_of_the_terms():
    # The chain's H couples only neighbouring positions: restricted to those
    # bonds, the space still holds it exactly. Exact gradients isolate the space.
    chain = fput_chain(8)
    rng = np.random.default_rng(0)
    X = rng.uniform(chain.domain[:, 0], chain.domain[:, 1], size=(600, 16)) / 2
    y = chain.vector_field(X)
    bonds = [(8 + i, 9 + i) for i in range(7)]
    box = chain.domain / 2
    model = HamiltonianRegressor(
        degree=4, domain=box, separable=True, couplings=bonds).fit(X, y)
    pairs = HamiltonianRegressor(degree=4, separable=True, max_interaction=2)
    # 16 x 4 functions of one variable and 7 bonds x 6 degree pairs, of 400.
    assert model.n_terms_ == 16 * 4 + 7 * 6 < count_terms(pairs, n_states=16) == 400
    test = rng.uniform(chain.domain[:, 0], chain.domain[:, 1], size=(200, 16)) / 2
    assert relative_h_error(model, chain, test) < 1e-10
    # Without the bond (q_4, q_5) the chain's H is outside the space.
    broken = HamiltonianRegressor(
        degree=4, domain=box, separable=True, couplings=bonds[:3] + bonds[4:]).fit(X, y)
    assert relative_h_error(broken, chain, test) > 1e-3


@pytest.mark.parametrize("couplings, match", [
    ([(0,)], "at least two distinct"),
    ([(0, 0)], "at least two distinct"),
    ([(0, 16)], r"in \[0, 16\)"),
    ([0, 1], "got the group 0"),
    ([(0.5, 1)], "got the group"),
    ([(True, 1)], "got the group"),
])
def test_bad_couplings_name_the_parameter_and_the_fix(couplings, match):
    X = np.random.default_rng(0).standard_normal((200, 16))
    model = HamiltonianRegressor(degree=2, couplings=couplings)
    with pytest.raises(ValueError, match=match) as error:
        model.fit(X, X)
    assert "couplings" in str(error.value) and "range(d - 1)" in str(error.value)


@pytest.fixture(scope="module")
def separable_henon_heiles():
    system = henon_heiles()
    X = make_trajectories(system, 500, 2, 0.01, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)
        model = HamiltonianRegressor(degree=3, separable=True, domain=system.domain).fit(Xt)
    return system, model


# 1e5 steps cost ten times 1e4: the default run takes 1e4, where RK4's drift
# below is already tenfold (measured: leapfrog's last tenth 1.008x its first
# over 1e4 steps, 1.0009x over 1e5).
@pytest.mark.parametrize("n_steps", [10_000, pytest.param(100_000, marks=pytest.mark.slow)])
def test_leapfrog_energy_error_stays_bounded_over_long_runs(separable_henon_heiles, n_steps):
    system, model = separable_henon_heiles
    t = 0.05 * np.arange(n_steps + 1)
    Y = model.simulate(system.initial_state, t, method="leapfrog", max_step=np.inf)
    deviation = np.abs(model.hamiltonian(Y) - model.hamiltonian(Y[:1]))
    first, last = deviation[:n_steps // 10].max(), deviation[-(n_steps // 10):].max()
    # Symplectic: the error oscillates at O(h^2) and does not drift.
    assert 0 < last < 2 * first
    spread = np.ptp(model.hamiltonian(system.domain.T * 0.5))
    assert deviation.max() < 1e-3 * spread
    # RK4 at the same step drifts (its error grows with time).
    Z = model.simulate(system.initial_state, t[:10_001], method="rk4", max_step=np.inf)
    drift = np.abs(model.hamiltonian(Z) - model.hamiltonian(Z[:1]))
    assert drift[-1000:].max() > 5 * drift[:1000].max()


def test_yoshida4_converges_with_fourth_order(separable_henon_heiles):
    system, model = separable_henon_heiles
    t = np.linspace(0, 5, 11)
    reference = model.simulate(system.initial_state, t, method="rk4", max_step=1e-3)
    errors = [
        np.abs(model.simulate(system.initial_state, t, method="yoshida4", max_step=h)
               - reference).max()
        for h in (0.1, 0.05, 0.025)
    ]
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all((orders > 3.6) & (orders < 4.4)), orders
    leapfrog = [
        np.abs(model.simulate(system.initial_state, t, method="leapfrog", max_step=h)
               - reference).max()
        for h in (0.1, 0.05)
    ]
    assert 1.8 < np.log2(leapfrog[0] / leapfrog[1]) < 2.2


def test_explicit_symplectic_methods_need_a_separable_conservative_model(cubic_data):
    X, y = cubic_data
    model = HamiltonianRegressor(degree=3).fit(X, y)
    for method in ("leapfrog", "yoshida4"):
        with pytest.raises(ValueError, match="not separable.*'avf'.*'rk4'"):
            model.simulate(X[0], [0, 1], method=method)


@pytest.fixture
def cubic_data():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(300, 4))
    p1, p2, q1, q2 = X.T
    grad = np.column_stack([p1 + 0.3 * q2, p2, q1 + 2 * q1 * q2, q2 + q1**2 - q2**2 + 0.3 * p1])
    return X, np.concatenate([-grad[:, 2:], grad[:, :2]], axis=1)


def test_separable_space_has_no_mixed_terms(separable_henon_heiles):
    _, model = separable_henon_heiles
    on_p = model.powers_[:, :2].any(axis=1)
    on_q = model.powers_[:, 2:].any(axis=1)
    assert not np.any(on_p & on_q)
    assert on_p.any() and on_q.any()


def test_angles_are_wrapped_everywhere_and_never_outside():
    # A pendulum H = p^2 / 2 - cos q with q periodic on [-pi, pi).
    rng = np.random.default_rng(1)
    X = rng.uniform([-3, -np.pi], [3, np.pi], size=(400, 2))
    y = np.column_stack([-np.sin(X[:, 1]), X[:, 0]])
    model = HamiltonianRegressor(degree=4, periodic=[False, True], momentum_degree=2).fit(X, y)
    assert np.allclose(model.domain_[1], [-np.pi, np.pi])
    # The same states given with angles shifted by whole turns fit the same model.
    shifted = X + [0.0, 2 * np.pi] * rng.integers(-3, 4, size=(400, 1))
    again = HamiltonianRegressor(
        degree=4, periodic=[False, True], momentum_degree=2, domain=model.domain_
    ).fit(shifted, y)
    assert np.allclose(again.coef_, model.coef_, atol=1e-10)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DomainWarning)  # angles are never "outside"
        assert np.allclose(model.predict(shifted), model.predict(X), atol=1e-10)
        Y = model.simulate([0.0, 2.5], np.linspace(0, 20, 201), method="avf")
    assert np.all((Y[:, 1] >= -np.pi) & (Y[:, 1] < np.pi))
    # A rotation (energy above the separatrix) comes back wrapped into the period.
    R = model.simulate([2.5, 0.0], np.linspace(0, 20, 201), method="avf", max_step=0.02)
    assert np.all((R[:, 1] >= -np.pi) & (R[:, 1] < np.pi)) and np.any(np.diff(R[:, 1]) < -np.pi)
    H = model.hamiltonian(Y)
    assert np.ptp(H) < 1e-12 * np.abs(H).max()
    terms = {term.text: term.coefficient for term in hamiltonian_terms(model)}
    assert terms["p^2"] == pytest.approx(0.5, abs=1e-8)
    assert terms["cos(q)"] == pytest.approx(-1.0, abs=1e-8)


@pytest.mark.parametrize("kernels", ["numpy", pytest.param("numba", marks=needs_numba)])
def test_avf_conserves_an_angle_model_over_long_steps(kernels):
    # A pendulum H = p^2 / 2 - cos q + 0.1 cos 5q learned exactly, stepped
    # with steps that turn the fastest factor through up to 8 radians. The
    # 4 extra nodes of short segments left 2e-8 of drift (5e-9 of the
    # coefficients' sum); each step now takes the nodes its segment needs.
    rng = np.random.default_rng(2)
    X = rng.uniform([-3, -np.pi], [3, np.pi], size=(600, 2))
    y = np.column_stack([-np.sin(X[:, 1]) - 0.5 * np.sin(5 * X[:, 1]), X[:, 0]])
    model = HamiltonianRegressor(degree=5, periodic=[False, True], momentum_degree=2).fit(X, y)
    x0 = np.array([[2.5, 0.0], [0.0, 2.0], [-1.5, 1.0]])
    with config_context(kernels=kernels), warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)  # the fast rotation leaves |p| <= 3
        Y = model.simulate(x0, 0.6 * np.arange(21), method="avf", max_step=np.inf)
    H = model.hamiltonian(Y)
    assert np.isfinite(Y).all()
    assert np.abs(H - H[:, :1]).max() <= 1e-13 * np.abs(model.coef_).sum()


def test_baseline_takes_the_same_model_spaces():
    system = double_pendulum(g=1.0, full_circle=True)
    rng = np.random.default_rng(2)
    X = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(800, 4))
    y = system.vector_field(X)
    params = dict(degree=6, domain=system.domain, periodic=system.periodic, momentum_degree=2)
    sp = HamiltonianRegressor(**params).fit(X, y)
    vf = VectorFieldRegressor(**params).fit(X, y)
    # Same functions (the baseline keeps the constant), one set per component.
    assert np.array_equal(vf.powers_[1:], sp.powers_)
    assert vf.n_terms_ == 4 * (sp.n_terms_ + 1) == count_terms(vf, n_states=4)
    with pytest.raises(ValueError, match="even number"):
        VectorFieldRegressor(momentum_degree=2).fit(X[:, :3], y[:, :3])


@pytest.mark.parametrize("n_samples", [1, 3, 200])
def test_count_outside_agrees_with_outside_domain(n_samples):
    # A few states are compared as Python floats, many as arrays: same count.
    from sk_hamiltonian._space.space import count_outside, outside_domain

    domain = np.array([[-1.0, 1.0], [0.0, 2.0], [-np.pi, np.pi]])
    periodic = np.array([False, False, True])
    X = np.random.default_rng(0).uniform(-1.3, 2.3, size=(n_samples, 3))
    X[0] = [1.04, 2.0, 9.0]  # inside the 5 % slack; the periodic variable never counts
    expected = int(outside_domain(X, domain, periodic, slack=0.05).sum())
    assert count_outside(X, domain, periodic, slack=0.05) == expected
    assert count_outside(X[:1], domain, periodic, slack=0.05) == 0
    assert count_outside(X[:1], domain, periodic) == 1
