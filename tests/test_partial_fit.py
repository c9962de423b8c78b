"""partial_fit: chunks give fit's coefficients, in memory that does not grow with the samples."""

import tracemalloc

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, VectorFieldRegressor
from sk_hamiltonian.datasets import henon_heiles, make_trajectories

DT = 0.01
SYSTEM = henon_heiles()
DOMAIN = SYSTEM.domain


@pytest.fixture(scope="module")
def layout():
    X = make_trajectories(SYSTEM, 240, 3, DT, random_state=2)
    return DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)


def relative(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize(
    "Model, params",
    [
        (HamiltonianRegressor, {}),
        (HamiltonianRegressor, dict(damping=True)),
        (HamiltonianRegressor, dict(fit_on="steps")),
        (VectorFieldRegressor, {}),
    ],
)
def test_chunks_of_trajectories_give_the_fit_on_all_of_them(layout, Model, params):
    full = Model(degree=4, domain=DOMAIN, solver="normal", **params).fit(layout)
    model = Model(degree=4, domain=DOMAIN, **params)
    for chunk in np.array_split(layout, 6):
        model.partial_fit(chunk)
    assert relative(model.coef_, full.coef_) < 1e-10
    assert model.cond_ == pytest.approx(full.cond_, rel=1e-8)
    assert model.solver_ == "normal" and model.n_terms_ == full.n_terms_
    # Statistics over all samples, not the last chunk.
    assert np.allclose(model.state_scale_, full.state_scale_, rtol=1e-12)
    assert model.dt_ == pytest.approx(full.dt_)
    assert np.isfinite(model.time_scale_)
    if params.get("damping"):
        assert np.allclose(model.damping_, full.damping_, rtol=1e-8, atol=1e-12)


def test_chunks_of_states_with_weights(layout):
    rng = np.random.default_rng(0)
    X = rng.uniform(DOMAIN[:, 0], DOMAIN[:, 1], size=(900, 4))
    y = rng.normal(size=(900, 4))
    w = rng.uniform(0.5, 2.0, size=900)
    full = HamiltonianRegressor(degree=3, domain=DOMAIN, solver="lstsq").fit(X, y, sample_weight=w)
    model = HamiltonianRegressor(degree=3, domain=DOMAIN)
    # Chunks smaller than the number of unknowns (34) are fine: only the
    # accumulated equations must determine the coefficients.
    for part in np.array_split(np.arange(900), 40):
        model.partial_fit(X[part], y[part], sample_weight=w[part])
    assert relative(model.coef_, full.coef_) < 1e-10


def test_partial_fit_needs_a_domain_and_fixed_parameters(layout):
    model = HamiltonianRegressor(degree=3)
    assert not hasattr(model, "partial_fit")
    # The method is hidden (so scikit-learn's common checks, run with the
    # default domain=None, skip it), and the error the user sees is the
    # reason itself with the fix, not "has no attribute" with the reason
    # chained below it (issue 32).
    with pytest.raises(AttributeError, match="partial_fit needs an explicit `domain`") as error:
        model.partial_fit(layout)
    assert "Pass domain=" in str(error.value) and error.value.__cause__ is None
    # From the class, as scikit-learn's available_if allows: checked at the call.
    with pytest.raises(AttributeError, match="explicit `domain`"):
        HamiltonianRegressor.partial_fit(model, layout)
    model = HamiltonianRegressor(degree=3, domain=DOMAIN).partial_fit(layout[:50])
    model.set_params(degree=4)
    with pytest.raises(ValueError, match="`degree` changed from 3 to 4"):
        model.partial_fit(layout[50:])
    with pytest.raises(ValueError, match="solver='auto' or 'normal'"):
        HamiltonianRegressor(domain=DOMAIN, solver="lstsq").partial_fit(layout)
    fitted = HamiltonianRegressor(degree=3, domain=DOMAIN).partial_fit(layout[:50])
    with pytest.raises(ValueError, match="features"):
        fitted.partial_fit(np.zeros((5, 2)), np.zeros((5, 2)))


def test_fit_starts_over(layout):
    model = HamiltonianRegressor(degree=3, domain=DOMAIN).partial_fit(layout[:100])
    model.fit(layout[100:])
    once = clone(model).fit(layout[100:])
    assert np.array_equal(model.coef_, once.coef_)
    model.partial_fit(layout[:100])  # a fresh accumulation after fit
    assert relative(model.coef_, clone(model).partial_fit(layout[:100]).coef_) < 1e-14


def test_partial_fit_through_a_pipeline(layout):
    X = make_trajectories(SYSTEM, 240, 3, DT, random_state=2)
    pipe = make_pipeline(
        DerivativeTransformer(dt=DT, method="finite_difference"),
        HamiltonianRegressor(degree=4, domain=DOMAIN),
    )
    transformer, model = pipe[0], pipe[-1]
    for chunk in np.array_split(X, 4):
        model.partial_fit(transformer.fit_transform(chunk))
    full = HamiltonianRegressor(degree=4, domain=DOMAIN, solver="normal").fit(layout)
    assert relative(model.coef_, full.coef_) < 1e-10


def _peak_after_warm_up(n_chunks, chunk):
    model = HamiltonianRegressor(degree=5, domain=DOMAIN)
    model.partial_fit(chunk)  # warm-up: workspace buffers, plan, caches
    tracemalloc.start()
    for _ in range(n_chunks):
        model.partial_fit(chunk)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def test_memory_does_not_grow_with_the_number_of_samples(layout):
    chunk = layout[:60]
    few, many = _peak_after_warm_up(3, chunk), _peak_after_warm_up(30, chunk)
    # Ten times the samples, the same peak (a few kB of bookkeeping aside);
    # the data themselves would be 10 x 60 x 4 x 13 x 8 B = 250 kB more.
    assert many < few * 1.1 + 20_000
