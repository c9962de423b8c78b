"""
Sparse Hamiltonians: the formula back from noisy data
=====================================================

A dense fit uses every term of its space; the true Hamiltonian of a physical
scene usually has a handful. ``HamiltonianRegressor(threshold=...)`` runs
sequentially thresholded least squares (STLSQ) in the *readable* basis, the
monomials and angles of :func:`~sk_hamiltonian.inspection.hamiltonian_terms`:
terms whose scaled coefficient is below ``threshold`` times the largest are
dropped and the rest refitted, until no term is dropped. The learned system is
still Hamiltonian, so it still conserves ``H~`` exactly.

Two scenes:

* the paper's noisy pendulum (Example 1: 500 trajectories of 41 samples, 8 %
  noise, de-noised with ``Q = 3``), in the mechanical Fourier space of degree
  8 (44 terms): the threshold path chooses the threshold by cross-validation,
  the chosen model reads as ``p**2 / 2 - 9.8 cos q``, and its trajectory from
  the paper's initial state is compared with the dense one;
* a chain of five unit masses and springs between two walls, learned from *one*
  trajectory of 800 steps of ``dt = 0.1`` with 3 % noise, by the steps fit at
  degree 2 (65 terms): the 14 true monomials come back, and a held-out rollout
  is compared with the dense fit's.

Quick mode (``SK_HAMILTONIAN_QUICK=1``, the documentation build): 3 folds
instead of 5.
"""

# %%
# The noisy pendulum, and the threshold chosen by cross-validation
# ----------------------------------------------------------------
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from sklearn.model_selection import KFold
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import DerivativeTransformer, DomainWarning, HamiltonianRegressor
from sk_hamiltonian.datasets import PAPER_DT, fput_chain, make_trajectories, single_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.metrics import relative_error
from sk_hamiltonian.model_selection import threshold_path
from sk_hamiltonian.plotting import plot_errors, plot_threshold_path

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)
# Short noisy trajectories near the edge of the box leave it: expected.
warnings.filterwarnings("ignore", category=DomainWarning)

system = single_pendulum()
X = make_trajectories(system, 500, 40, PAPER_DT, noise=0.08, random_state=0)
space = dict(degree=8, periodic=[False, True], momentum_degree=2)
pipe = make_pipeline(DerivativeTransformer(dt=PAPER_DT, degree=3), HamiltonianRegressor(**space))
thresholds = [0.0, 1e-3, 1e-2, 3e-2, 0.1]
path = threshold_path(pipe, X, thresholds, cv=KFold(3 if QUICK else 5, shuffle=True, random_state=0))
chosen = path.thresholds[path.best_index]
for value, terms, score, error, tied in zip(
    path.thresholds, path.n_terms, path.mean_score, path.std_error, path.tied
):
    print(f"threshold {value:<6g} {terms:3d} terms  score {score:.4f} +- {error:.4f}"
          + ("  (tied with the best)" if tied else ""))
print(f"chosen threshold (best mean score): {chosen:g}")

fig, ax = plt.subplots(figsize=(6, 4))
plot_threshold_path(path, ax=ax)
ax.set_title("Noisy pendulum: cross-validated score against model size")
fig.tight_layout()
fig.savefig(FIGURES / "sparse_threshold_path.png", dpi=120)

# %%
# The chosen model and the dense one, from the paper's initial state
# ------------------------------------------------------------------
Xt = DerivativeTransformer(dt=PAPER_DT, degree=3).fit_transform(X)
dense = HamiltonianRegressor(**space).fit(Xt)
sparse = HamiltonianRegressor(threshold=chosen, **space).fit(Xt)
print(format_hamiltonian(sparse))
t = np.arange(0, 20 + PAPER_DT / 2, PAPER_DT)
truth = system.solve(system.initial_state, t)
errors = {
    f"dense ({dense.n_terms_} terms)": relative_error(dense.simulate(system.initial_state, t), truth),
    f"sparse ({sparse.n_terms_} terms)": relative_error(
        sparse.simulate(system.initial_state, t), truth
    ),
}
for label, e in errors.items():
    print(f"{label}: relative error at T = 20: {e[-1]:.3f}")
fig, ax = plt.subplots(figsize=(6, 4))
plot_errors(t, errors, ax=ax)
ax.set_title("Noisy pendulum: error from the paper's initial state")
fig.tight_layout()
fig.savefig(FIGURES / "sparse_pendulum_errors.png", dpi=120)

# %%
# A chain of masses and springs from one trajectory
# -------------------------------------------------
# One record of 800 steps of ``dt = 0.1`` with noise 1e-3 (the states span
# about +-0.8), fitted at degree 2 on its pairs of consecutive steps:
# ``fit_on="simpson"`` needs no derivative estimate and, unlike
# ``fit_on="steps"``, learns the Hamiltonian itself rather than the modified
# one of the AVF map at this step, so a threshold keeps the true
# coefficients.
chain = fput_chain(5, alpha=0.0, beta=0.0)
rng = np.random.default_rng(0)
times = 0.1 * np.arange(801)
record = chain.solve(rng.uniform(-0.5, 0.5, 10), times)
noisy = record + 1e-3 * rng.standard_normal(record.shape)
Xc = DerivativeTransformer(dt=0.1, method="finite_difference").fit_transform(noisy[None])
chain_dense = HamiltonianRegressor(degree=2, fit_on="simpson").fit(Xc)
chain_sparse = HamiltonianRegressor(degree=2, fit_on="simpson", threshold=0.03).fit(Xc)
names = [f"p{i}" for i in range(1, 6)] + [f"q{i}" for i in range(1, 6)]
print(format_hamiltonian(chain_sparse, state_names=names, max_terms=14))
held_out_start = rng.uniform(-0.5, 0.5, 10)
held_t = times[:201]
held_truth = chain.solve(held_out_start, held_t)
chain_errors = {
    label: float(np.linalg.norm(model.simulate(held_out_start, held_t) - held_truth)
                 / np.linalg.norm(held_truth))
    for label, model in (("dense", chain_dense), ("sparse", chain_sparse))
}
print(f"held-out rollout error over 20 time units: dense {chain_errors['dense']:.4f} "
      f"({chain_dense.n_terms_} terms), sparse {chain_errors['sparse']:.4f} "
      f"({chain_sparse.n_terms_} terms)")

results = {
    "quick_mode": QUICK,
    "pendulum": {
        "thresholds": path.thresholds.tolist(), "n_terms": path.n_terms.tolist(),
        "mean_score": path.mean_score.tolist(), "std_error": path.std_error.tolist(),
        "chosen": float(chosen),
        "terms": {str(term.powers): term.coefficient for term in hamiltonian_terms(sparse)},
        "error_T20": {"dense": float(errors[next(iter(errors))][-1]),
                      "sparse": float(list(errors.values())[1][-1])},
    },
    "chain": {
        "terms": {term.text: term.coefficient
                  for term in hamiltonian_terms(chain_sparse, state_names=names)},
        "n_terms": {"dense": chain_dense.n_terms_, "sparse": chain_sparse.n_terms_},
        "held_out_error": chain_errors,
    },
}
(FIGURES / "sparse_hamiltonians.json").write_text(json.dumps(results, indent=2))
