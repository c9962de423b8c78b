"""
Finding the law: the search over model spaces, fit targets and sparsity
=======================================================================

:class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` cross-validates
what the package can do — the model space (each position polynomial,
periodic or mixed; a general or a mechanical Hamiltonian), the fit target,
the de-noising degree, the degree and the sparsity threshold — and returns the
simplest model the data cannot tell from the best, its coefficients fitted to
the raw trajectories themselves. Two scenes:

* the paper's noisy pendulum (Example 1: 500 trajectories of 41 samples,
  ``dt = 0.01``, 8 % noise): the search finds a periodic angle and keeps
  ``p**2`` and ``cos q``;
* a pendulum on a torsion spring, ``H = p**2 / 2 + q**2 / 2 + 4 (1 - cos q)``
  (300 trajectories of 41 samples, ``dt = 0.02``, 5 % noise): neither a
  polynomial nor periodic in ``q``, its law is three terms in a *mixed* space,
  which the search finds.

Both learned models are then simulated beside the truth, and their energy
stays constant to round-off with the averaged-vector-field integrator.

Quick mode (``SK_HAMILTONIAN_QUICK=1``, the documentation build): fewer
trajectories, three folds, fewer de-noising degrees and fit targets.
"""

# %%
# The noisy pendulum
# ------------------
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from sklearn.model_selection import KFold

from sk_hamiltonian import ConservationWarning, DomainWarning
from sk_hamiltonian.datasets import make_trajectories, single_pendulum, torsion_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)
# Short noisy trajectories near the edge of the box leave it, and poor
# candidates' energy trends along the data: both are expected here.
warnings.filterwarnings("ignore", category=DomainWarning)
warnings.filterwarnings("ignore", category=ConservationWarning)

settings = dict(cv=KFold(3 if QUICK else 5, shuffle=True, random_state=0))
if QUICK:
    settings.update(denoise_degrees=[3, 5], fit_on=["derivatives", "simpson"])

pendulum = single_pendulum()
X = make_trajectories(pendulum, 200 if QUICK else 500, 40, 0.01, noise=0.08, random_state=0)
search = HamiltonianSearchCV(dt=0.01, **settings).fit(X)
model = search.best_estimator_[-1]
print("kept spaces:", search.kept_spaces_)
print("chosen:", search.best_params_)
print("coefficients:", search.refinement_["status"])  # fitted to the raw trajectories
print(format_hamiltonian(model))

# %%
# The finalists: one per de-noising degree and fit target, scored by rollouts
# against the held-out observations. Those within one paired standard error of
# the best score are tied; the search takes the simplest of them.
results = search.cv_results_
for i in np.flatnonzero(results["stage"] == "finalist"):
    params = results["params"][i]
    layout = params.get("derivativetransformer__degree", "fd")
    print(f"Q={layout!s:3} {params['hamiltonianregressor__fit_on']:12s} "
          f"{results['n_terms'][i]:3d} terms  score {results['mean_test_score'][i]:.6f}"
          + ("  tied" if results["tied"][i] else "")
          + ("  <- chosen" if i == search.best_index_ else ""))

# %%
# The torsion pendulum: a mixed space
# -----------------------------------
torsion = torsion_pendulum()
Xs = make_trajectories(torsion, 150 if QUICK else 300, 40, 0.02, noise=0.05, random_state=0)
torsion_search = HamiltonianSearchCV(dt=0.02, **settings).fit(Xs)
torsion_model = torsion_search.best_estimator_[-1]
print("kept spaces:", torsion_search.kept_spaces_)
print(format_hamiltonian(torsion_model))

# %%
# Simulated beside the truth
# --------------------------
# From each system's test state to T = 20, with the averaged-vector-field
# integrator, whose learned energy stays constant to round-off.
fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex=True)
summary = {}
for row, (name, system, learned) in enumerate(
    (("pendulum", pendulum, model), ("torsion pendulum", torsion, torsion_model))
):
    t = np.arange(0.0, 20.0 + 1e-9, 0.01)
    truth = system.solve(system.initial_state, t, max_step=1e-3)
    Y = learned.simulate(system.initial_state, t, method="avf")
    difference = Y - truth
    if learned.periodic_.any():  # the learned angle is wrapped: compare the short way round
        difference[:, learned.periodic_] = (difference[:, learned.periodic_] + np.pi) % (
            2 * np.pi) - np.pi
    error = np.linalg.norm(difference, axis=1) / np.linalg.norm(truth, axis=1)
    energy = learned.hamiltonian(Y)
    summary[name] = dict(error_T20=float(error[-1]), drift=float(np.ptp(energy)))
    print(f"{name}: relative error at T = 20: {error[-1]:.3g}; H~ drift with AVF: "
          f"{np.ptp(energy):.1e}")
    axes[row, 0].plot(t, truth[:, 1], color="0.7", lw=4, label="truth")
    axes[row, 0].plot(t, np.unwrap(Y[:, 1]) if learned.periodic_[1] else Y[:, 1],
                      color="C0", lw=1, label="learned")
    axes[row, 0].set_ylabel(f"{name}: q")
    axes[row, 1].semilogy(t, np.maximum(error, 1e-16), color="C1")
    axes[row, 1].set_ylabel("relative error")
axes[0, 0].legend(loc="upper right", fontsize=8)
for ax in axes[1]:
    ax.set_xlabel("t")
fig.suptitle("The searched models from the test states")
fig.tight_layout()
fig.savefig(FIGURES / "search_rollouts.png", dpi=120)

results_file = {
    "quick_mode": QUICK,
    "pendulum": {
        "terms": sorted(term.text for term in hamiltonian_terms(model)),
        "coefficients": {term.text: term.coefficient for term in hamiltonian_terms(model)},
        "kept_spaces": search.kept_spaces_, **summary["pendulum"],
    },
    "torsion": {
        "terms": sorted(term.text for term in hamiltonian_terms(torsion_model)),
        "coefficients": {term.text: term.coefficient
                         for term in hamiltonian_terms(torsion_model)},
        "kept_spaces": torsion_search.kept_spaces_, **summary["torsion pendulum"],
    },
}
(FIGURES / "search.json").write_text(json.dumps(results_file, indent=2))
