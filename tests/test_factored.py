"""The gradient design as maps of a value design, and its normal equations from one Gram matrix.

``d phi_j / d x_i = sum_l T_i[l, j] psi_l`` must hold at any point for every
family and index set, so the factored normal equations equal, to round-off,
those accumulated group by group from the gradients themselves; and a fit
takes the factored route only where it costs fewer multiply-adds.
"""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, _factored
from sk_hamiltonian._factored import FactoredNormalEquations
from sk_hamiltonian._solvers import NormalEquations
from sk_hamiltonian._space import ModelSpace, index_set
from sk_hamiltonian._space.fourier import (
    fourier_column, fourier_derivative_matrix, fourier_frequency, fourier_tables,
)
from sk_hamiltonian.datasets import henon_heiles, make_trajectories

DT = 0.01
ROUND_OFF = 1e-13  # relative: the same sums, in another order


@pytest.fixture(scope="module")
def layout():
    X = make_trajectories(henon_heiles(), 60, 4, DT, random_state=3)
    return DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)


def relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def test_fourier_derivative_matrix_maps_the_table_onto_its_derivative():
    theta = np.random.default_rng(0).uniform(-4, 4, size=(9, 2))
    value, slope = fourier_tables(theta, 5)
    assert np.allclose(value @ fourier_derivative_matrix(5), slope, rtol=0, atol=1e-14)
    frequencies = np.arange(-5, 6)
    assert np.array_equal(fourier_frequency(fourier_column(frequencies)), frequencies)


SPACES = [
    # (periodic, index-set options): total degree, angles, a sparse lattice.
    ([0, 0, 0, 0], {}),
    ([0, 0, 1, 1], dict(momentum_degree=3)),
    ([0, 1], {}),
    ([0] * 6, dict(couplings=[(3, 4), (4, 5)])),
]


@pytest.mark.parametrize("periodic, options", SPACES)
def test_maps_of_the_value_basis_give_the_gradients(periodic, options):
    periodic = np.array(periodic, dtype=bool)
    m = periodic.size
    domain = np.where(periodic[:, None], [0.0, 2 * np.pi], [-1.5, 2.0])
    space = ModelSpace(domain, index_set(m, 5, periodic=periodic, **options), periodic)
    maps = space.derivative_maps()
    X = np.random.default_rng(1).uniform(-1.5, 2.0, size=(40, m))
    gradients = space.gradients_t(X)
    values = maps.value_space.values_t(X)
    for i in range(m):
        assert relative(maps.maps_t[i] @ values, gradients[:, i]) < ROUND_OFF
    assert space.derivative_maps() is maps  # built once


def _both(model, data):
    """Factored and grouped normal equations of a fitted model on ``data``."""
    design = model._design(model._space)
    factored = design.accumulate(data)
    grouped = NormalEquations(design.n_columns, design.groups).add_blocks(
        design.blocks(data, grouped=True))
    return factored, factored.result(), grouped.result()


@pytest.mark.parametrize("params", [
    dict(degree=5),
    dict(degree=4, fit_on="steps"),
    dict(degree=4, fit_on="simpson", damping=True),
    dict(degree=4, damping=True, periodic=[0, 0, 1, 1],
         domain=[[-1, 1], [-1, 1], [-np.pi, np.pi], [-np.pi, np.pi]]),
])
def test_factored_normal_equations_equal_the_grouped_ones(layout, params):
    weight = np.random.default_rng(2).uniform(0.5, 2.0, size=layout.shape[0])
    model = HamiltonianRegressor(solver="normal", **params)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # states outside a narrow box do not matter here
        model.fit(layout, sample_weight=weight)
    data = model._training_data(layout, None, weight, reset=False)
    factored, (gram, rhs), (expected_gram, expected_rhs) = _both(model, data)
    assert isinstance(factored, FactoredNormalEquations)
    assert relative(gram, expected_gram) < ROUND_OFF
    assert relative(rhs, expected_rhs) < ROUND_OFF
    assert np.array_equal(gram, gram.T)
    assert factored.n_rows == data.n_rows(model.fit_on) * 4


def test_blocks_and_tiles_of_the_maps_products_cover_every_entry(layout, monkeypatch):
    # Blocks of 7 rows and tiles of 6: the last of each is partial.
    monkeypatch.setattr(_factored, "RESULT_ROWS", 7)
    monkeypatch.setattr(_factored, "MIRROR_TILE", 6)
    model = HamiltonianRegressor(degree=5, solver="normal").fit(layout)
    data = model._training_data(layout, None, None, reset=False)
    _, (gram, rhs), (expected_gram, expected_rhs) = _both(model, data)
    assert model.n_terms_ % 7 and model._space.derivative_maps().n_values % 6
    assert relative(gram, expected_gram) < ROUND_OFF
    assert relative(rhs, expected_rhs) < ROUND_OFF


def test_factored_route_only_where_it_costs_less(layout):
    dense = HamiltonianRegressor(degree=4).fit(layout)
    maps = dense._space.derivative_maps()
    design = dense._design(dense._space)
    assert maps.n_values ** 2 < sum(g.size**2 for g in design.groups)
    assert isinstance(design.accumulator(), FactoredNormalEquations)
    # Momenta alone, positions coupled in one pair: groups of 4, 4, 10 and
    # 10 functions (232 products per row) against a value basis of 16 (256).
    chain = HamiltonianRegressor(degree=4, separable=True, couplings=[(2, 3)]).fit(layout)
    maps = chain._space.derivative_maps()
    design = chain._design(chain._space)
    assert maps.n_values ** 2 > sum(g.size**2 for g in design.groups)
    assert type(design.accumulator()) is NormalEquations


# Finite differences of a conservative system fit no friction.
@pytest.mark.filterwarnings("ignore::sk_hamiltonian.ConservationWarning")
def test_chunks_add_up_to_the_whole(layout):
    model = HamiltonianRegressor(degree=4, damping=True, solver="normal").fit(layout)
    data = model._training_data(layout, None, None, reset=False)
    first = model._training_data(layout[:30], None, None, reset=False)
    second = model._training_data(layout[30:], None, None, reset=False)
    design = model._design(model._space)
    total = design.accumulate(first)
    total += design.accumulate(second)
    gram, rhs = total.result()
    expected_gram, expected_rhs = design.accumulate(data).result()
    assert relative(gram, expected_gram) < ROUND_OFF
    assert relative(rhs, expected_rhs) < ROUND_OFF
    assert total.n_rows == design.accumulate(data).n_rows


@pytest.mark.filterwarnings("ignore::sk_hamiltonian.ConservationWarning")
def test_empty_accumulator_gives_zero_equations(layout):
    model = HamiltonianRegressor(degree=3, damping=True).fit(layout)
    design = model._design(model._space)
    gram, rhs = design.accumulator().result()
    n = design.n_columns
    assert gram.shape == (n, n) and rhs.shape == (n,)
    assert not gram.any() and not rhs.any()
