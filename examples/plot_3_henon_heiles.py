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
import warnings

from sk_hamiltonian import (
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    VectorFieldRegressor,
)
from sk_hamiltonian import _paper as paper
from sk_hamiltonian.datasets import PAPER_DT, henon_heiles, make_trajectories

# Trajectories started near the boundary of D leave it within their two steps;
# the basis stays the paper's, on D.
warnings.filterwarnings("ignore", category=DomainWarning)

system = henon_heiles()
settings = system.paper_settings  # n = 3, M = 500, J = 2, clean data
T_END = paper.pick(100.0, 20.0)

X = make_trajectories(
    system, settings["n_trajectories"], settings["n_intervals"], PAPER_DT, random_state=0
)
Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
sp = HamiltonianRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)
non_sp = VectorFieldRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)

# %%
# Errors and Hamiltonian over time (Figure 9)
# -------------------------------------------
# ``H~`` is shifted by the constant of the paper's Theorem 3.5 (the mean of
# ``H - H~`` over ``D``) to be comparable with ``H``.
t = paper.time_grid(T_END)
trajectories, errors = paper.compare(system, {"SP": sp, "non-SP": non_sp}, t)
fig = paper.plot_errors_and_hamiltonian(system, t, trajectories, errors, sp)
paper.save_figure(fig, "ex3_errors_hamiltonian")

rows = paper.error_table(t, errors, paper.checkpoints(T_END))
print(paper.format_table(rows, list(rows[0])))
drift = paper.conservation(sp, system, t)
print("relative drift of H~: " + ", ".join(f"{m} {v:.2e}" for m, v in drift.items()))

# %%
# Trajectories (Figure 10)
# ------------------------
fig = paper.plot_states(t, trajectories["exact"], trajectories["SP"], "SP")
paper.save_figure(fig, "ex3_states_sp")

# %%
# Phase plots (Figure 11): ``(q1, p1)`` and ``(q2, p2)``
# ------------------------------------------------------
fig = paper.plot_phase(trajectories, [(2, 0), (3, 1)])
paper.save_figure(fig, "ex3_phase")

paper.save_results("ex3_henon_heiles", {
    "t_end": T_END,
    "errors": {row["model"]: row for row in rows},
    "drift": drift,
})
