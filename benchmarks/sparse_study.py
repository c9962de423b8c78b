"""Sparse fits against dense ones on three scenes (the numbers of docs/sparse.rst).

* The paper's noisy pendulum (Example 1: 500 trajectories of 41 samples, 8 %
  noise, Q = 3), mechanical Fourier space of degree 8: terms and relative
  error at T = 20 from the paper's initial state, per threshold.
* Hénon-Heiles with 2 % noise (500 x 41, Q = 5), degree 6: the same.
* A chain of five unit masses and springs between walls, one trajectory of 800
  steps of dt = 0.1, fitted on its steps (``fit_on="steps"``, the AVF map) and
  on its pairs of steps (``fit_on="simpson"``) at degree 2, absolute noise 0
  to 1e-2 (the states span about +-0.8): terms, the worst relative error of a
  true term and the number of spurious ones (threshold 0.03), and the
  held-out rollout error (20 time units) of the dense and the thresholded
  model, simulated with its default method (AVF at the data step after a
  steps fit, RK4 after a Simpson fit) and with RK4 at a tenth of the step.

``--chain`` runs the chain table only.

Run: ``PYTHONPATH=. python benchmarks/sparse_study.py`` (a few minutes).
"""

import os
import sys
import warnings

for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

import numpy as np  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.datasets import (  # noqa: E402
    PAPER_DT,
    fput_chain,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms  # noqa: E402

THRESHOLDS = [0.0, 1e-3, 1e-2, 3e-2, 0.1]


def error_at_end(model, system, t_end=20.0):
    t = np.arange(0, t_end + PAPER_DT / 2, PAPER_DT)
    truth = system.solve(system.initial_state, t)
    Y = model.simulate(system.initial_state, t, on_failure="nan")
    return np.linalg.norm(Y[-1] - truth[-1]) / np.linalg.norm(truth[-1])


def threshold_table(title, system, noise, Q, params):
    print(f"\n## {title}")
    X = make_trajectories(system, 500, 40, PAPER_DT, noise=noise, random_state=0)
    Xt = DerivativeTransformer(dt=PAPER_DT, degree=Q).fit_transform(X)
    print("| threshold | terms | solves | error at T = 20 | formula (up to 8 terms) |")
    print("|---|---|---|---|---|")
    for threshold in THRESHOLDS:
        model = HamiltonianRegressor(threshold=threshold, **params).fit(Xt)
        formula = format_hamiltonian(model) if model.n_terms_ <= 8 else ""
        print(f"| {threshold:g} | {model.n_terms_} | {model.n_iter_} | "
              f"{error_at_end(model, system):.4f} | {formula} |")


def chain_truth(n_masses):
    """Readable terms of unit masses and unit springs between two walls."""
    truth = {}
    for i in range(1, n_masses + 1):
        truth[f"p{i}^2"], truth[f"q{i}^2"] = 0.5, 1.0
        if i < n_masses:
            truth[f"q{i}*q{i + 1}"] = -1.0
    return truth


def term_errors(model, truth):
    """Worst relative error of a true term, and the number of spurious terms."""
    terms = {term.text: term.coefficient for term in hamiltonian_terms(model)}
    worst = max(abs(terms.get(name, 0.0) / value - 1.0) for name, value in truth.items())
    return worst, len(set(terms) - set(truth))


def chain_table():
    print("\n## Chain of five masses, one trajectory of 800 steps, degree 2")
    chain, truth = fput_chain(5, alpha=0.0, beta=0.0), chain_truth(5)
    rng = np.random.default_rng(0)
    times = 0.1 * np.arange(801)
    record = chain.solve(rng.uniform(-0.5, 0.5, 10), times)
    start = rng.uniform(-0.5, 0.5, 10)
    held_t = times[:201]
    truth_path = chain.solve(start, held_t)
    print("| noise (absolute) | fit_on | model | terms | worst true term | spurious | "
          "held-out error (default method) | error, RK4 at dt / 10 |")
    print("|---|---|---|---|---|---|---|---|")
    for noise in (0.0, 1e-3, 3e-3, 1e-2):
        noisy = record + noise * rng.standard_normal(record.shape)
        Xt = DerivativeTransformer(dt=0.1, method="finite_difference").fit_transform(noisy[None])
        for fit_on in ("steps", "simpson"):
            for label, threshold in (("dense", 0.0), ("sparse 0.03", 0.03)):
                model = HamiltonianRegressor(degree=2, fit_on=fit_on, threshold=threshold).fit(Xt)
                errors = [
                    np.linalg.norm(model.simulate(start, held_t, **options) - truth_path)
                    / np.linalg.norm(truth_path)
                    for options in ({}, dict(method="rk4", max_step=0.01))
                ]
                worst, spurious = term_errors(model, truth) if threshold else ("", "")
                worst = f"{worst:.2%}" if threshold else ""
                print(f"| {noise:g} | {fit_on} | {label} | {model.n_terms_} | {worst} | "
                      f"{spurious} | {errors[0]:.2e} | {errors[1]:.2e} |")


def main():
    warnings.simplefilter("ignore")
    if "--chain" in sys.argv[1:]:
        chain_table()
        return
    threshold_table(
        "Noisy pendulum (Example 1 data, Q = 3), periodic mechanical space, degree 8",
        single_pendulum(), 0.08, 3, dict(degree=8, periodic=[False, True], momentum_degree=2),
    )
    threshold_table("Hénon-Heiles, 2 % noise (Q = 5), degree 6", henon_heiles(), 0.02, 5,
                    dict(degree=6))
    chain_table()


if __name__ == "__main__":
    main()
