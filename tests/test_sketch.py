"""The sketch that preconditions ``solver="sketch"``, and passes over the samples in threads.

The solver's agreement with ``lstsq`` is tested with the others in
``test_solvers.py``; here, what makes it fast: the sketch is a CountSketch
(every row of the design lands, with a sign, in one row of the sketch), it
preconditions the design to a condition number of a few whatever the
design's, and the design operator's passes give the same answers on one
thread and on several.
"""

import threading
import warnings

import numpy as np
import pytest
from scipy import linalg
from sklearn.exceptions import ConvergenceWarning

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
from sk_hamiltonian import _fit_steps as steps
from sk_hamiltonian import _threads as threads
from sk_hamiltonian._design import quadrature_nodes
from sk_hamiltonian._design_operator import DesignOperator
from sk_hamiltonian._sketch import DesignSketch
from sk_hamiltonian.datasets import henon_heiles, make_trajectories

DT = 0.01


class _LastOffset:
    """A generator whose windows start three rows before the sketch's end."""

    def __init__(self, rng):
        self.rng = rng

    def integers(self, high):
        return high - 3

    def choice(self, *args, **kwargs):
        return self.rng.choice(*args, **kwargs)


@pytest.mark.parametrize("offset_near_the_end", [False, True])
def test_each_row_lands_once_with_a_sign(offset_near_the_end):
    # One block of fewer rows than the sketch: no two rows meet, so the
    # sketch's nonzero rows are the block's rows, each times +1 or -1, in
    # their group's columns; a window that runs past the end wraps around.
    rng = np.random.default_rng(0)
    groups = [np.array([0, 2, 3]), np.arange(5)]
    sketch = DesignSketch(5, groups, n_rows=20, seed=1)
    if offset_near_the_end:
        sketch._rng = _LastOffset(sketch._rng)
    A = rng.normal(size=(7, 3))
    sketch.add(A, None, group=0)
    S = sketch.transposed.T
    touched = np.flatnonzero(np.any(S != 0, axis=1))
    assert touched.size == 7
    if offset_near_the_end:
        assert set(touched) == {17, 18, 19, 0, 1, 2, 3}
    assert np.all(S[:, [1, 4]] == 0)
    landed = S[touched][:, groups[0]]
    for row in A:
        matches = [k for k, x in enumerate(landed) if np.array_equal(x, row) or np.array_equal(x, -row)]
        assert len(matches) == 1


def test_blocks_longer_than_the_sketch_are_added_in_full():
    # Rows beyond the sketch's size go round again: the sketch's squared norm
    # is the design's plus the cross terms of the rows that met, whose signs
    # make them average out; the Gram matrix is still close to A^T A.
    rng = np.random.default_rng(1)
    A = rng.normal(size=(5000, 10))
    gram = DesignSketch(10, n_rows=400, seed=0).add(A).gram()
    assert np.array_equal(gram, gram.T)
    exact = A.T @ A
    assert np.linalg.norm(gram - exact) < 0.2 * np.linalg.norm(exact)


def test_the_sketch_preconditions_an_ill_conditioned_design_to_a_few():
    # Correlated columns (condition number 1e4 once equilibrated) on scales
    # eight orders of magnitude apart. With the triangle of its sketch (three
    # rows per column, equilibrated as the solver does), the preconditioned
    # design's condition number is near (1 + 1/sqrt(3)) / (1 - 1/sqrt(3)) =
    # 3.7, as for a Gaussian embedding.
    rng = np.random.default_rng(2)
    n = 60
    U, _ = np.linalg.qr(rng.normal(size=(6000, n)))
    V, _ = np.linalg.qr(rng.normal(size=(n, n)))
    A = (U * np.logspace(0, -4, n)) @ V.T * np.logspace(0, 8, n)
    sketch = DesignSketch(n, seed=0)
    for block in np.array_split(A, 7):
        sketch.add(block)
    gram = sketch.gram()
    norms = np.sqrt(np.diag(gram))
    R = linalg.cholesky(gram / np.outer(norms, norms))
    equilibrated = A / norms
    assert np.linalg.cond(equilibrated) > 1e3
    assert np.linalg.cond(linalg.solve_triangular(R, equilibrated.T, trans="T").T) < 6


def test_the_sketched_fit_does_not_need_samples_over_the_box():
    # Samples on a small part of a wide box: the closed-form preconditioner
    # (the uniform measure on the box) stalls, the sketch's does not.
    X = make_trajectories(henon_heiles(), 200, 3, DT, random_state=1)
    Xt = DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)
    domain = np.array(henon_heiles().domain) * 3.0
    reference = HamiltonianRegressor(degree=5, domain=domain, solver="lstsq").fit(Xt)
    counts = {}
    for solver in ("iterative", "sketch"):
        model = HamiltonianRegressor(degree=5, domain=domain, solver=solver)
        iterations = []
        model._progress = lambda message: (lambda i, r: iterations.append(i))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            model.fit(Xt)
        counts[solver] = len(iterations)
        if solver == "sketch":
            assert not caught
            relative = np.linalg.norm(model.coef_ - reference.coef_)
            assert relative < 1e-8 * np.linalg.norm(reference.coef_)
    # Measured: 37 iterations, against 400 (the cap, with a warning).
    assert counts["sketch"] <= 60 < counts["iterative"]


def test_operator_passes_agree_on_one_thread_and_on_several(monkeypatch):
    X = make_trajectories(henon_heiles(), 300, 3, DT, random_state=0)
    Xt = DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=4)
    data = model._training_data(Xt, None, None)
    space = steps.build_space(model, data)
    operator = DesignOperator(space, data, "derivatives", quadrature_nodes(space), "gradient")
    monkeypatch.setattr("sk_hamiltonian._design_operator.CHUNK_SAMPLES", 128)
    x = np.random.default_rng(0).normal(size=(space.n_terms, 1))
    results = {}
    for idle in (0.0, 1.0):
        monkeypatch.setattr(threads, "idle_cores", lambda: idle)
        monkeypatch.setattr(threads.os, "cpu_count", lambda: 2)
        y = operator.matvec(x)
        results[idle] = (y, operator.rmatvec(y))
    (y1, z1), (y2, z2) = results[0.0], results[1.0]
    assert np.array_equal(y1, y2)  # each chunk writes its own samples
    # Summed in the chunks' order either way; the BLAS may round differently.
    assert np.allclose(z1, z2, rtol=1e-13, atol=1e-13 * np.abs(z1).max())


def test_map_on_idle_cores_keeps_the_order_and_uses_threads(monkeypatch):
    monkeypatch.setattr(threads, "idle_cores", lambda: 1.0)
    monkeypatch.setattr(threads.os, "cpu_count", lambda: 2)
    names = []

    def work(k):
        names.append(threading.current_thread().name)
        return k * k

    assert threads.map_on_idle_cores(work, range(9)) == [k * k for k in range(9)]
    assert all(name.startswith("sk_hamiltonian") for name in names)
    # Called from a worker of the pool, it stays in that worker (a worker
    # waiting for the pool could wait forever).
    names.clear()
    nested = threads.thread_pool().submit(threads.map_on_idle_cores, work, range(4))
    assert nested.result(timeout=60) == [0, 1, 4, 9]
    assert len(set(names)) == 1
    monkeypatch.setattr(threads, "idle_cores", lambda: 0.0)
    names.clear()
    assert threads.map_on_idle_cores(work, range(3)) == [0, 1, 4]
    assert names == [threading.current_thread().name] * 3

