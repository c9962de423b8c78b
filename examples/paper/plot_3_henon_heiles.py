"""
Example 3: the Hénon–Heiles system
==================================

The paper's third example, the Hénon–Heiles Hamiltonian
``H = (p1**2 + p2**2) / 2 + (q1**2 + q2**2) / 2 + q1**2 q2 - q2**3 / 3``, a
cubic polynomial with two degrees of freedom. The data are ``M = 500`` clean
trajectories of ``J = 2`` steps of ``dt = 0.01``
(:data:`~sk_hamiltonian.datasets.PAPER_DT`) started uniformly in
``D = [-1, 1]**4``; derivatives come from second-order finite differences, and
``H~`` is a polynomial of degree ``n = 3``. The learned system is simulated
from ``u0* = (0.3, -0.25, 0.2, -0.25)`` with RK4: errors and Hamiltonians over
time (paper's Figure 9), trajectories (Figure 10) and phase plots (Figure 11).
The paper shows the structure-preserving (SP) model only; the non-SP baseline
is added here for comparison.

Quick mode (``SK_HAMILTONIAN_QUICK=1``, used by the documentation build): the
horizon is ``T = 20`` instead of 100; data and models are the paper's.
"""

# %%
# Data and models
# ---------------
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from sk_hamiltonian import (
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian.datasets import PAPER_DT, henon_heiles, make_trajectories
from sk_hamiltonian.metrics import (
    hamiltonian_deviation,
    hamiltonian_offset,
    hamiltonian_range,
    relative_error,
)
from sk_hamiltonian.plotting import plot_energy, plot_errors, plot_phase, plot_states

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").lower() not in ("", "0", "false", "no")
# Figures and measured numbers go to figures/ next to this script (sphinx-gallery
# sets sys.argv[0] to the script it runs), or to $SK_HAMILTONIAN_FIGURES.
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)

# Trajectories started near the boundary of D leave it within their two steps;
# the basis stays the paper's, on D.
warnings.filterwarnings("ignore", category=DomainWarning)

system = henon_heiles()
settings = system.paper_settings  # n = 3, M = 500, J = 2, clean data
T_END = 20.0 if QUICK else 100.0

X = make_trajectories(
    system, settings["n_trajectories"], settings["n_intervals"], PAPER_DT, random_state=0
)
Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
sp = HamiltonianRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)
non_sp = VectorFieldRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)

# %%
# Errors and Hamiltonian over time (Figure 9)
# -------------------------------------------
# The true system is solved by RK4 at step ``dt / 10``, the learned ones by
# RK4 at step ``dt``, the paper's solver (``max_step=PAPER_DT``; by default
# ``simulate`` picks its own step). ``H~`` is shifted by the constant of the
# paper's Theorem 3.5 (the mean of ``H - H~`` over ``D``) to be comparable
# with ``H``.
t = PAPER_DT * np.arange(round(T_END / PAPER_DT) + 1)
x0 = system.initial_state
trajectories = {"exact": system.solve(x0, t, max_step=PAPER_DT / 10)}
for label, model in {"SP": sp, "non-SP": non_sp}.items():
    trajectories[label] = model.simulate(x0, t, method="rk4", max_step=PAPER_DT)
errors = {label: relative_error(trajectories[label], trajectories["exact"])
          for label in ("SP", "non-SP")}

fig, (ax_err, ax_ham) = plt.subplots(1, 2, figsize=(11, 4))
plot_errors(t, errors, ax=ax_err)
plot_energy(t, {
    "$H(u(t))$, exact": system.hamiltonian(trajectories["exact"]),
    r"$\tilde H(\tilde u(t)) + C$, SP": sp.hamiltonian(trajectories["SP"])
    + hamiltonian_offset(sp, system.hamiltonian, system.domain),
    r"$H(\tilde u(t))$, SP": system.hamiltonian(trajectories["SP"]),
}, deviation=False, ax=ax_ham)
ax_ham.set_title("Hamiltonian along the trajectories")
fig.tight_layout()
fig.savefig(FIGURES / "ex3_errors_hamiltonian.png", dpi=110)

CHECKPOINTS = [T for T in (10.0, 50.0, 100.0) if T < T_END] + [T_END]
rows = {
    label: {**{f"T={T:g}": float(e[round(T / PAPER_DT)]) for T in CHECKPOINTS},
            "mean": float(np.mean(e))}
    for label, e in errors.items()
}
for label, row in rows.items():
    print(f"{label:>7}: " + ", ".join(f"{key} {value:.3e}" for key, value in row.items()))

# %%
# The SP model conserves its own ``H~``: up to RK4's small drift, and to
# round-off with the averaged vector field integrator (``method="avf"``). The
# drift is measured against the range of ``H~`` over ``D``, since ``H~`` is
# only defined up to a constant.
scale = hamiltonian_range(sp, system.domain)
u_avf = sp.simulate(x0, t, method="avf", max_step=PAPER_DT)
drift = {
    method: hamiltonian_deviation(t, sp.hamiltonian(U))["linf"] / scale
    for method, U in (("rk4", trajectories["SP"]), ("avf", u_avf))
}
print("relative drift of H~: " + ", ".join(f"{m} {v:.2e}" for m, v in drift.items()))

# %%
# Trajectories (Figure 10)
# ------------------------
axes = plot_states(t, {"exact": trajectories["exact"], "SP": trajectories["SP"]})
axes[0].figure.tight_layout()
axes[0].figure.savefig(FIGURES / "ex3_states_sp.png", dpi=110)

# %%
# Phase plots (Figure 11): ``(q1, p1)`` and ``(q2, p2)``
# ------------------------------------------------------
# One row per degree of freedom, one column per trajectory.
fig, axes = plt.subplots(2, 3, figsize=(10.2, 6.4), sharex="row", sharey="row")
for pair, row in enumerate(axes):
    for ax, (label, U) in zip(row, trajectories.items()):
        plot_phase({label: U}, pair=pair, ax=ax).get_legend().remove()
        ax.set_title(label)
fig.tight_layout()
fig.savefig(FIGURES / "ex3_phase.png", dpi=110)

results = {"t_end": T_END, "quick_mode": QUICK, "errors": rows, "drift": drift}
(FIGURES / "ex3_henon_heiles.json").write_text(json.dumps(results, indent=2))
