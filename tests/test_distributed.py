"""Scale-out with dask (optional extra ``distributed``): fits on dask arrays, CV on a cluster.

Runs on an in-process ``LocalCluster`` (loopback only); skipped when dask is
not installed.
"""

import warnings

import numpy as np
import pytest

dask = pytest.importorskip("dask")
da = pytest.importorskip("dask.array")
distributed = pytest.importorskip("distributed")

import joblib  # noqa: E402
from sklearn.model_selection import GridSearchCV, KFold  # noqa: E402
from sklearn.pipeline import make_pipeline  # noqa: E402

from sk_hamiltonian import (  # noqa: E402
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian.datasets import henon_heiles, make_trajectories  # noqa: E402

DT = 0.01


@pytest.fixture(scope="module")
def client():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # distributed's own start-up chatter
        cluster = distributed.LocalCluster(
            processes=False, n_workers=1, threads_per_worker=2, dashboard_address=None
        )
        client = distributed.Client(cluster)
    yield client
    client.close()
    cluster.close()


@pytest.fixture(scope="module")
def trajectories():
    return make_trajectories(henon_heiles(), 160, 3, DT, random_state=1)


@pytest.fixture(scope="module")
def layout(trajectories):
    return DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(trajectories)


def relative(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("params", [{}, dict(damping=True), dict(fit_on="steps"), dict(fit_on="simpson")])
def test_fit_on_a_dask_layout_gives_the_in_memory_coefficients(client, layout, params):
    reference = HamiltonianRegressor(degree=4, solver="lstsq", **params).fit(layout)
    # Chunks that cut trajectories apart are rechunked to whole trajectories.
    chunked = da.from_array(layout, chunks=(37, 2, 5))
    model = HamiltonianRegressor(degree=4, **params).fit(chunked)
    assert relative(model.coef_, reference.coef_) < 1e-10
    assert np.array_equal(model.domain_, reference.domain_)
    assert model.cond_ == pytest.approx(reference.cond_, rel=1e-8)
    assert model.solver_ == "normal" and model.n_features_in_ == 4
    assert np.allclose(model.state_scale_, reference.state_scale_, rtol=1e-12)
    assert model.dt_ == pytest.approx(reference.dt_)


def test_fit_on_dask_states_and_derivatives_with_weights(client, layout):
    states = layout[..., 1:5].reshape(-1, 4)
    derivatives = layout[..., 5:9].reshape(-1, 4)
    weights = np.random.default_rng(0).uniform(0.5, 2.0, size=states.shape[0])
    reference = VectorFieldRegressor(degree=3, solver="lstsq").fit(
        states, derivatives, sample_weight=weights
    )
    model = VectorFieldRegressor(degree=3).fit(
        da.from_array(states, chunks=100), da.from_array(derivatives, chunks=100),
        sample_weight=da.from_array(weights, chunks=50),
    )
    assert relative(model.coef_, reference.coef_) < 1e-10
    assert np.allclose(model.predict(states[:5]), reference.predict(states[:5]), atol=1e-10)


def test_dask_fit_checks_like_fit(client, layout):
    domain = np.array(henon_heiles().domain) * 0.5
    with pytest.warns(DomainWarning, match="outside the domain"):
        HamiltonianRegressor(degree=2, domain=domain).fit(da.from_array(layout, chunks=40))
    with pytest.raises(ValueError, match="underdetermined"):
        HamiltonianRegressor(degree=9).fit(da.from_array(layout[:5], chunks=2))
    with pytest.raises(ValueError, match="derivative layout"):
        HamiltonianRegressor().fit(da.from_array(layout[..., 1:5].reshape(-1, 4), chunks=50))


def test_grid_search_on_the_cluster_equals_the_local_search(client, trajectories):
    pipe = make_pipeline(
        DerivativeTransformer(dt=DT, method="finite_difference"), HamiltonianRegressor()
    )
    grid = {"hamiltonianregressor__degree": [2, 3, 4]}
    cv = KFold(3, shuffle=True, random_state=0)
    local = GridSearchCV(pipe, grid, cv=cv).fit(trajectories)
    with joblib.parallel_config(backend="dask"):
        remote = GridSearchCV(pipe, grid, cv=cv, n_jobs=-1).fit(trajectories)
    assert remote.best_params_ == local.best_params_
    assert np.allclose(
        remote.cv_results_["mean_test_score"], local.cv_results_["mean_test_score"], rtol=1e-12
    )
