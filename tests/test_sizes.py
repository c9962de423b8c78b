"""Sizes checked before allocating: model spaces counted, fits and simulations refused in words.

Issue 32: ``HamiltonianRegressor(degree=10**6).fit`` ran 22 s to a bare
MemoryError, degree 60 in four variables asked numpy for 2.94 TiB,
``simulate(x0, [0, 1e12])`` and ``max_step=1e-12`` ran on without end, and
data scaled by 1e300 gave inf/NaN coefficients with only numpy's overflow
warning.
"""

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sk_hamiltonian
from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    VectorFieldRegressor,
    config_context,
)
from sk_hamiltonian._memory import fit_memory, physical_memory
from sk_hamiltonian._space import count_index_set, index_set
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.model_selection import count_terms


@st.composite
def space_parameters(draw):
    n_states = draw(st.integers(1, 6))
    degree = draw(st.integers(1, 6 if n_states < 5 else 4))
    params = {}
    if draw(st.booleans()):
        params["periodic"] = np.array(draw(st.lists(st.booleans(), min_size=n_states,
                                                    max_size=n_states)))
    if draw(st.booleans()):
        # Mixed variables (polynomials beside cosines and sines): never periodic ones.
        periodic = params.get("periodic", np.zeros(n_states, dtype=bool))
        flags = np.array(draw(st.lists(st.booleans(), min_size=n_states, max_size=n_states)))
        params["mixed"] = flags & ~periodic
    if n_states % 2 == 0:
        if draw(st.booleans()):
            params["momentum_degree"] = draw(st.integers(0, degree + 1))
        params["separable"] = draw(st.booleans())
    if draw(st.booleans()):
        params["max_interaction"] = draw(st.integers(1, n_states))
    if n_states >= 2 and draw(st.booleans()):
        groups = draw(st.lists(st.sets(st.integers(0, n_states - 1), min_size=2),
                               min_size=1, max_size=4))
        params["couplings"] = [tuple(sorted(g)) for g in groups]
    params["include_constant"] = draw(st.booleans())
    return n_states, degree, params


@settings(max_examples=300, deadline=None)
@given(space_parameters())
def test_counting_a_space_matches_building_it(case):
    n_states, degree, params = case
    assert count_index_set(n_states, degree, **params) == index_set(
        n_states, degree, **params).shape[0]


def test_huge_spaces_are_counted_in_closed_form():
    # Total degree n in m variables: C(n + m, m) - 1 functions; with pairs
    # only on a chain of 64, 64 * n + 63 * C(n, 2).
    assert count_index_set(2, 10**6) == math.comb(10**6 + 2, 2) - 1
    assert count_index_set(4, 60) == math.comb(64, 4) - 1 == 635_375
    chain = [(i, i + 1) for i in range(63)]
    assert count_index_set(64, 10**6, max_interaction=2, couplings=chain) == (
        64 * 10**6 + 63 * math.comb(10**6, 2))
    assert count_terms(HamiltonianRegressor(degree=10**6), n_states=2) == math.comb(
        10**6 + 2, 2) - 1


@pytest.fixture(scope="module")
def many_states():
    # Enough equations for degree 60 in four variables (635 375 unknowns):
    # only the memory can refuse it.
    rng = np.random.default_rng(0)
    S = rng.uniform(-1, 1, size=(200_000, 4))
    return S, np.column_stack([S[:, 2:], -S[:, :2]])


def test_a_degree_of_a_million_is_refused_by_name():
    rng = np.random.default_rng(0)
    S = rng.uniform(-1, 1, size=(200, 2))
    Y = np.column_stack([-S[:, 1], S[:, 0]])
    # The count, not the index set (which alone took 22 s and 3.6 GB).
    with pytest.raises(ValueError, match=r"for 500001500000 unknowns at degree=1000000"):
        HamiltonianRegressor(degree=10**6).fit(S, Y)
    with pytest.raises(ValueError, match=r"VectorFieldRegressor\(degree=1000000\) has "
                                         r"500,001,500,001 unknowns .* lower `degree`"):
        VectorFieldRegressor(degree=10**6).fit(S, Y)


def test_degree_60_in_four_variables_names_the_memory_and_the_remedies(many_states):
    S, Y = many_states
    with pytest.raises(ValueError) as error:
        HamiltonianRegressor(degree=60).fit(S, Y)
    message = str(error.value)
    assert "HamiltonianRegressor(degree=60) has 635,375 unknowns for 4 state variables" in message
    assert " TB, beyond the memory limit of " in message
    assert "set_config(memory_limit=...)" in message
    # The largest degree within the limit is named, and the restrictions.
    largest = int(message.split("at most ")[1].split(" ")[0])
    assert 1 <= largest < 60
    assert "max_interaction" in message and "momentum_degree" in message
    # partial_fit counts the same way before its first chunk.
    with pytest.raises(ValueError, match="635,375 unknowns"):
        HamiltonianRegressor(degree=60, domain=[[-1, 1]] * 4).partial_fit(S, Y)


def test_the_largest_degree_named_fits(many_states):
    S, Y = many_states
    limit = 2e9
    with config_context(memory_limit=limit):
        with pytest.raises(ValueError, match="at most") as error:
            HamiltonianRegressor(degree=40).fit(S, Y)
    largest = int(str(error.value).split("at most ")[1].split(" ")[0])
    n_ok = count_terms(HamiltonianRegressor(degree=largest), 4)
    n_over = count_terms(HamiltonianRegressor(degree=largest + 1), 4)
    # The least any fit holds (three n x n matrices of float64, and the
    # index tables): within the limit at the named degree, not one beyond.
    assert fit_memory(None, n_ok, n_states=4) <= limit < fit_memory(None, n_over, n_states=4)
    assert 3 * 8 * n_ok**2 < limit < 3 * 8 * (n_over + 1) ** 2


def test_a_solver_too_large_for_the_limit_names_one_that_fits(many_states):
    S, Y = many_states
    # "lstsq" holds the whole design: 800 000 rows x 1 819 columns, twice.
    with config_context(memory_limit=5e9):
        with pytest.raises(ValueError) as error:
            HamiltonianRegressor(degree=12, solver="lstsq").fit(S, Y)
    message = str(error.value)
    assert "solver='lstsq' on 800,000 rows and 1,819 unknowns" in message
    assert "(the design alone is 800,000 x 1,819)" in message
    assert "use solver='iterative'" in message
    # Beneath any solver's needs, the message offers no solver.
    with config_context(memory_limit=1e7):
        with pytest.raises(ValueError, match=r"beyond the memory limit of 10 MB set by "
                                             r"sk_hamiltonian.set_config") as error:
            HamiltonianRegressor(degree=12).fit(S[:2000], Y[:2000])
    assert "solver=" not in str(error.value).split("To fit:")[-1]


def test_memory_limit_is_configured_and_checked():
    assert sk_hamiltonian.get_config()["memory_limit"] == "auto"
    assert physical_memory() is None or physical_memory() > 2**20
    with config_context(memory_limit=np.inf):
        assert sk_hamiltonian.get_config()["memory_limit"] == np.inf
    assert sk_hamiltonian.get_config()["memory_limit"] == "auto"
    for bad in (0, -1.0, float("nan"), "lots", True):
        with pytest.raises(ValueError, match="memory_limit must be 'auto' or a positive"):
            sk_hamiltonian.set_config(memory_limit=bad)
    # A refused call changes nothing.
    with pytest.raises(ValueError, match="kernels must be one of"):
        sk_hamiltonian.set_config(kernels="cuda", memory_limit=1e9)
    assert sk_hamiltonian.get_config()["memory_limit"] == "auto"


@pytest.fixture(scope="module")
def oscillator():
    rng = np.random.default_rng(1)
    S = rng.uniform(-1, 1, size=(300, 2))
    return HamiltonianRegressor(degree=2).fit(S, np.column_stack([-S[:, 1], S[:, 0]]))


def test_simulate_refuses_step_counts_beyond_the_limit(oscillator):
    # time_scale_ = 1: the default step is 0.1, so [0, 1e12] is 1e13 steps.
    with pytest.raises(ValueError) as error:
        oscillator.simulate([0.5, 0.0], [0.0, 1e12])
    message = str(error.value)
    assert "t runs from 0 to 1e+12 (2 output times)" in message
    assert "max_step=0.1 (the default step for this model)" in message
    assert "1e+13 integration steps per initial state, beyond the limit of 1e+07" in message
    with pytest.raises(ValueError, match=r"with max_step=1e-12 that is 1e\+12 integration steps"):
        oscillator.simulate([0.5, 0.0], [0.0, 1.0], max_step=1e-12)
    # Within the limit, stepping from one output time to the next, it runs
    # (one RK4 step of 1e12 leaves the box, and says so).
    with pytest.warns(sk_hamiltonian.DomainWarning):
        assert oscillator.simulate([0.5, 0.0], [0.0, 1e12], max_step=np.inf).shape == (2, 2)


def test_simulate_refuses_outputs_beyond_the_memory_limit(oscillator):
    t = np.linspace(0, 1, 1001)
    with config_context(memory_limit=1e5):
        with pytest.raises(ValueError, match=r"t asks for 1,001 output times of 2 variables "
                                             r"from 10 initial state\(s\): about 480 kB"):
            oscillator.simulate(np.zeros((10, 2)) + 0.1, t)
        assert oscillator.simulate([0.1, 0.0], t[:10]).shape == (10, 2)


@pytest.mark.parametrize("scale", [1e150, 1e300])
def test_data_beyond_the_float_range_of_a_fit_are_refused_with_the_fix(scale):
    X = make_trajectories(single_pendulum(), 30, 20, 0.01, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warnings on the way either
        Xt = DerivativeTransformer(dt=0.01).fit_transform(X * scale)
        for Regressor in (HamiltonianRegressor, VectorFieldRegressor):
            with pytest.raises(ValueError, match=r"the states X reach .*e\+(150|300) in magnitude, "
                                                 r"beyond 1e\+100.*Rescale the data"):
                Regressor(degree=4).fit(Xt)
        S, Y = Xt[..., 1:3].reshape(-1, 2), Xt[..., 3:5].reshape(-1, 2)
        with pytest.raises(ValueError, match="Rescale the data"):
            HamiltonianRegressor(degree=4, solver="normal").fit(S, Y)


def test_large_but_representable_data_give_the_scaled_model():
    # The same pendulum in units 1e40 times smaller: the learned H~ is 1e80
    # times larger, and its field the same up to the units, to round-off.
    X = make_trajectories(single_pendulum(), 50, 20, 0.01, random_state=0)
    scale = 1e40
    models = [
        HamiltonianRegressor(degree=4).fit(DerivativeTransformer(dt=0.01).fit_transform(X * s))
        for s in (1.0, scale)
    ]
    assert np.all(np.isfinite(models[1].coef_))
    np.testing.assert_allclose(models[1].coef_, models[0].coef_ * scale**2, rtol=1e-8)
    states = X[0]
    np.testing.assert_allclose(models[1].predict(states * scale), models[0].predict(states) * scale,
                               rtol=1e-8, atol=1e-8 * scale)


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="resource limits are POSIX")
def test_the_memory_limit_follows_the_process_own_address_space_limit():
    # Under `ulimit -v 4 GiB` on a larger machine the automatic limit is three
    # quarters of what that cap leaves, not of the machine's memory: a request
    # beyond it is refused by name before it is allocated.
    import resource
    import subprocess
    import sys

    cap = 4 * 2**30
    code = ("from sk_hamiltonian._memory import memory_limit, physical_memory; "
            "print(physical_memory(), memory_limit())")

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         preexec_fn=limit, check=True).stdout.split()
    usable, planned = int(out[0]), float(out[1])
    assert usable < cap
    assert planned == pytest.approx(0.75 * usable)
