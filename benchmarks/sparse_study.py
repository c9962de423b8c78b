"""Sparse fits against dense ones on three scenes (the numbers of docs/sparse.rst).

* The paper's noisy pendulum (Example 1: 500 trajectories of 41 samples, 8 %
  noise, Q = 3), mechanical Fourier space of degree 8: terms and relative
  error at T = 20 from the paper's initial state, per threshold.
* Hénon-Heiles with 2 % noise (500 x 41, Q = 5), degree 6: the same.
* A chain of five unit masses and springs between walls, one trajectory of 800
  steps of dt = 0.1, steps fit at degree 2, noise 0 to 3 % of the states'
  spread: terms and held-out rollout error (20 time units) of the dense and the
  thresholded (0.03) model, simulated with AVF at the data step (the default
  of a steps fit) and with RK4 at a tenth of it.

Run: ``PYTHONPATH=. python benchmarks/sparse_study.py`` (a few minutes).
"""

import os
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
from sk_hamiltonian.inspection import format_hamiltonian  # noqa: E402

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


def chain_table():
    print("\n## Chain of five masses, one trajectory, steps fit at degree 2")
    chain = fput_chain(5, alpha=0.0, beta=0.0)
    rng = np.random.default_rng(0)
    times = 0.1 * np.arange(801)
    record = chain.solve(rng.uniform(-0.5, 0.5, 10), times)
    start = rng.uniform(-0.5, 0.5, 10)
    held_t = times[:201]
    truth = chain.solve(start, held_t)
    print("| noise | model | terms | error, AVF at dt | error, RK4 at dt / 10 |")
    print("|---|---|---|---|---|")
    for noise in (0.0, 0.002, 0.01, 0.03):
        noisy = record + noise * record.std() * rng.standard_normal(record.shape)
        Xt = DerivativeTransformer(dt=0.1, method="finite_difference").fit_transform(noisy[None])
        for label, threshold in (("dense", 0.0), ("sparse 0.03", 0.03)):
            model = HamiltonianRegressor(degree=2, fit_on="steps", threshold=threshold).fit(Xt)
            errors = [
                np.linalg.norm(model.simulate(start, held_t, **options) - truth)
                / np.linalg.norm(truth)
                for options in ({}, dict(method="rk4", max_step=0.01))
            ]
            print(f"| {noise:.1%} | {label} | {model.n_terms_} | {errors[0]:.4f} | "
                  f"{errors[1]:.4f} |")


def main():
    warnings.simplefilter("ignore")
    threshold_table(
        "Noisy pendulum (Example 1 data, Q = 3), periodic mechanical space, degree 8",
        single_pendulum(), 0.08, 3, dict(degree=8, periodic=[False, True], momentum_degree=2),
    )
    threshold_table("Hénon-Heiles, 2 % noise (Q = 5), degree 6", henon_heiles(), 0.02, 5,
                    dict(degree=6))
    chain_table()


if __name__ == "__main__":
    main()
