"""Mixed variables: Legendre polynomials and Fourier terms of one coordinate in one space."""

import numpy as np
import pytest
from numpy.polynomial import legendre

from sk_hamiltonian._space import ModelSpace, index_set
from sk_hamiltonian._space.mixed import code_frequency, factor_degrees, mixed_code
from sk_hamiltonian._space.readable import ReadableBasis

DOMAIN = np.array([[-1.0, 2.0], [-3.0, 4.0]])
MIXED = np.array([False, True])


def _factor(code, x, low, high, mixed):
    """One factor of a basis function, from its definition."""
    if mixed and code < 0:
        k = abs(int(code_frequency(code)))
        return np.cos(k * x) if code_frequency(code) > 0 else np.sin(k * x)
    xi = (2 * x - (low + high)) / (high - low)
    return legendre.legval(xi, np.eye(code + 1)[code])


def _values(powers, X):
    return np.stack([
        np.prod([_factor(row[i], X[:, i], *DOMAIN[i], MIXED[i]) for i in range(2)], axis=0)
        for row in powers
    ], axis=1)


def test_codes_of_a_mixed_variable():
    assert mixed_code(1) == -1 and mixed_code(-1) == -2 and mixed_code(2) == -3
    assert code_frequency(-3) == 2 and code_frequency(-4) == -2 and code_frequency(5) == 0
    powers = np.array([[2, -3], [1, 4], [0, -2]])
    assert factor_degrees(powers, MIXED).tolist() == [[2, 2], [1, 4], [0, 1]]


def test_index_set_holds_polynomial_and_trigonometric_terms_of_each_degree():
    powers = index_set(2, 3, mixed=MIXED)
    degrees = factor_degrees(powers, MIXED).sum(axis=1)
    assert degrees.max() == 3 and np.all(np.diff(degrees) >= 0)  # graded
    # Degree 1 in q: q, cos q, sin q; with the momentum's p: p, p q, p cos q, p sin q.
    rows = {tuple(r) for r in powers.tolist()}
    assert {(0, 1), (0, -1), (0, -2), (1, 1), (1, -1), (1, -2), (1, 0)} <= rows
    assert len(rows) == powers.shape[0]
    # Without mixed variables the index set is unchanged.
    assert np.array_equal(index_set(2, 3), index_set(2, 3, mixed=[False, False]))


def test_values_gradients_and_hessians_match_their_definition():
    powers = index_set(2, 4, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    X = np.random.default_rng(0).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(9, 2))
    np.testing.assert_allclose(space.values(X), _values(powers, X), atol=1e-13)
    h = 1e-6
    numeric = np.stack([(space.values(X + h * e) - space.values(X - h * e)) / (2 * h)
                        for e in np.eye(2)], axis=1)
    np.testing.assert_allclose(space.gradients(X), numeric, atol=1e-7)
    coef = np.random.default_rng(1).normal(size=powers.shape[0])
    grad = lambda Y: space.gradient_dot(Y, coef)  # noqa: E731
    numeric = np.stack([(grad(X + h * e) - grad(X - h * e)) / (2 * h) for e in np.eye(2)], axis=2)
    np.testing.assert_allclose(space.hessian_dot(X, coef), numeric, atol=1e-6)
    np.testing.assert_allclose(space.value_dot(X, coef), space.values(X) @ coef, atol=1e-12)


def test_a_sparse_subset_evaluates_as_the_dense_space():
    powers = index_set(2, 5, mixed=MIXED)
    keep = np.zeros(powers.shape[0], dtype=bool)
    keep[[2, 5, 11]] = True
    dense, sparse = ModelSpace(DOMAIN, powers, mixed=MIXED), ModelSpace(DOMAIN, powers[keep], mixed=MIXED)
    X = np.random.default_rng(2).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(5, 2))
    coef = np.zeros(powers.shape[0])
    coef[keep] = [1.5, -2.0, 0.25]
    np.testing.assert_allclose(sparse.gradient_dot(X, coef[keep]), dense.gradient_dot(X, coef),
                               atol=1e-12)


def test_readable_basis_is_monomials_and_angles():
    powers = index_set(2, 4, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    readable = ReadableBasis(powers, DOMAIN, [False, False], MIXED)
    X = np.random.default_rng(3).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(11, 2))
    for j, (a, code) in enumerate(powers):
        q = X[:, 1]
        factor = q**code if code >= 0 else _factor(code, q, *DOMAIN[1], True)
        fitting = readable.to_fitting[:, [j]].toarray().ravel()
        difference = space.values(X) @ fitting - X[:, 0] ** a * factor
        assert np.ptp(difference) < 1e-10  # equal up to the dropped constant


def test_derivative_maps_give_the_gradient():
    powers = index_set(2, 5, mixed=MIXED)
    space = ModelSpace(DOMAIN, powers, mixed=MIXED)
    maps = space.derivative_maps()
    X = np.random.default_rng(4).uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(6, 2))
    values = maps.value_space.values(X)
    gradients = space.gradients(X)
    for i, T in enumerate(maps.maps_t):
        np.testing.assert_allclose(values @ T.T.toarray(), gradients[:, i], atol=1e-10)


# The compiled kernels on mixed spaces: tests/test_kernels.py (its SPACES).


# --------------------------------------------------------------- the regressors
def _torsion_data(n=600, seed=0):
    """States of the torsion pendulum H = p^2/2 + q^2/2 + 4 (1 - cos q) and their exact derivatives."""
    from sk_hamiltonian.datasets import torsion_pendulum

    system = torsion_pendulum()
    X = np.random.default_rng(seed).uniform(-4, 4, size=(n, 2))
    return system, X, system.vector_field(X)


def test_a_mixed_hamiltonian_is_recovered_to_round_off():
    from sk_hamiltonian import HamiltonianRegressor
    from sk_hamiltonian.inspection import hamiltonian_terms

    system, X, Y = _torsion_data()
    model = HamiltonianRegressor(degree=4, mixed=[False, True], threshold=0.01).fit(X, Y)
    terms = {t.text: t.coefficient for t in hamiltonian_terms(model)}
    assert set(terms) == {"p^2", "q^2", "cos(q)"}
    np.testing.assert_allclose([terms["p^2"], terms["q^2"], terms["cos(q)"]], [0.5, 0.5, -4.0],
                               rtol=1e-12)
    # Dense too: the space holds H exactly.
    dense = HamiltonianRegressor(degree=5, mixed=[False, True]).fit(X, Y)
    F = np.random.default_rng(1).uniform(-4, 4, size=(50, 2))
    difference = dense.hamiltonian(F) - system.hamiltonian(F)
    assert np.ptp(difference) < 1e-11
    np.testing.assert_allclose(dense.predict(F), system.vector_field(F), atol=1e-11)


def test_a_polynomial_or_periodic_space_cannot_hold_it():
    from sk_hamiltonian import HamiltonianRegressor

    system, X, Y = _torsion_data()
    F = np.random.default_rng(1).uniform(-4, 4, size=(200, 2))
    errors = {}
    for name, params in (("polynomial", {}), ("periodic", dict(periodic=[False, True])),
                         ("mixed", dict(mixed=[False, True]))):
        model = HamiltonianRegressor(degree=5, **params).fit(X, Y)
        errors[name] = np.std(model.hamiltonian(F) - system.hamiltonian(F))
    assert errors["mixed"] < 1e-10 < 1e-3 < errors["polynomial"] < errors["periodic"]


def test_avf_conserves_a_mixed_hamiltonian_to_round_off():
    from sk_hamiltonian import HamiltonianRegressor

    _, X, Y = _torsion_data()
    rng = np.random.default_rng(2)
    model = HamiltonianRegressor(degree=5, mixed=[False, True]).fit(X, Y + 0.01 * rng.normal(size=Y.shape))
    t = np.linspace(0.0, 20.0, 201)
    Z = model.simulate([0.5, 2.0], t, method="avf", max_step=0.1)
    energy = model.hamiltonian(Z)
    assert np.ptp(energy) < 1e-12 * max(1.0, np.abs(energy).max())
    # RK4 at the same step drifts: the conservation is AVF's, not the scene's.
    drift = np.ptp(model.hamiltonian(model.simulate([0.5, 2.0], t, method="rk4", max_step=0.1)))
    assert drift > 100 * np.ptp(energy)


def test_mixed_and_periodic_on_one_variable_is_refused():
    from sk_hamiltonian import HamiltonianRegressor

    _, X, Y = _torsion_data(50)
    with pytest.raises(ValueError, match="both periodic and mixed"):
        HamiltonianRegressor(periodic=[False, True], mixed=[False, True]).fit(X, Y)
    with pytest.raises(ValueError, match="mixed must be None or an array of 2 booleans"):
        HamiltonianRegressor(mixed=[True]).fit(X, Y)


def test_a_mixed_model_file_round_trips(tmp_path):
    from sk_hamiltonian import HamiltonianRegressor, ModelFileError, load, save

    _, X, Y = _torsion_data()
    for params in (dict(degree=4, mixed=[False, True], threshold=0.01),
                   dict(degree=5, mixed=[True, True], momentum_degree=2)):
        model = HamiltonianRegressor(**params).fit(X, Y)
        save(model, tmp_path / "mixed.skh")
        loaded = load(tmp_path / "mixed.skh")
        np.testing.assert_array_equal(loaded.mixed_, model.mixed_)
        np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
        assert loaded.get_params()["mixed"] == params["mixed"]
    # A file whose mixed_ contradicts its parameter is refused.
    model.mixed_ = np.array([False, True])
    save(model, tmp_path / "wrong.skh")
    with pytest.raises(ModelFileError, match="mixed_ differs from the mixed parameter"):
        load(tmp_path / "wrong.skh")
