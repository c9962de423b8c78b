"""
Example 4: Cherry's system, which blows up
==========================================

The paper's fourth example, Cherry's Hamiltonian
``H = (q1**2 + p1**2) / 2 - (q2**2 + p2**2) + p2 (p1**2 - q1**2) / 2 - q1 q2 p1``:
a cubic polynomial whose solutions can blow up in finite time. The data are
``M = 500`` clean trajectories of ``J = 2`` steps of ``dt = 0.01``
(:data:`~sk_hamiltonian.datasets.PAPER_DT`) started uniformly in
``D = (-2, 2) x (-1, 2) x (-2, 1) x (-1, 1)``; derivatives come from
second-order finite differences, and ``H~`` is a polynomial of degree
``n = 3``. The learned system is simulated from
``u0* = (-0.05, 0.1, 0.15, 0.1)`` with RK4: errors and Hamiltonians over time
(paper's Figure 12), trajectories (Figure 13) and phase plots (Figure 14). The
non-SP baseline, absent from the paper here, is added for comparison.

The true solution from ``u0*`` blows up near ``t = 27.9``: a trajectory counts
as blown up once a component exceeds ``10`` in absolute value, errors are
reported up to ``t = 25``, and past that the blow-up *times* are compared. The
example is the same in quick mode.
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
from sk_hamiltonian.datasets import PAPER_DT, cherry, make_trajectories

# Trajectories started near the boundary of D leave it within their two steps,
# and the solution from u0* leaves it before blowing up; the basis stays the
# paper's, on D.
warnings.filterwarnings("ignore", category=DomainWarning)

system = cherry()
settings = system.paper_settings  # n = 3, M = 500, J = 2, clean data
T_END = 40.0  # past every blow-up below

X = make_trajectories(
    system, settings["n_trajectories"], settings["n_intervals"], PAPER_DT, random_state=0
)
Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
sp = HamiltonianRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)
non_sp = VectorFieldRegressor(degree=settings["degree"], domain=system.domain).fit(Xt)

# %%
# Errors and Hamiltonian over time (Figure 12)
# --------------------------------------------
# ``H~`` is shifted by the constant of the paper's Theorem 3.5 (the mean of
# ``H - H~`` over ``D``) to be comparable with ``H``. The curves stop where
# the trajectories blow up.
t = paper.time_grid(T_END)
trajectories, errors = paper.compare(system, {"SP": sp, "non-SP": non_sp}, t)
fig = paper.plot_errors_and_hamiltonian(system, t, trajectories, errors, sp)
paper.save_figure(fig, "ex4_errors_hamiltonian")

rows = paper.error_table(t, errors, [10.0, 20.0, 25.0])
print(paper.format_table(rows, ["model", "T=10", "T=20", "T=25"]))
blowup = {label: paper.blowup_time(t, U) for label, U in trajectories.items()}
print("blow-up times: " + ", ".join(f"{k} {v:.2f}" for k, v in blowup.items()))
drift = paper.conservation(sp, system, t)
print("relative drift of H~ before the blow-up: "
      + ", ".join(f"{m} {v:.2e}" for m, v in drift.items()))

# %%
# Trajectories (Figure 13)
# ------------------------
fig = paper.plot_states(t, trajectories["exact"], trajectories["SP"], "SP")
paper.save_figure(fig, "ex4_states_sp")

# %%
# Phase plots (Figure 14): ``(p1, p2)`` and ``(q1, q2)``
# ------------------------------------------------------
fig = paper.plot_phase(trajectories, [(0, 1), (2, 3)])
paper.save_figure(fig, "ex4_phase")

paper.save_results("ex4_cherry", {
    "t_end": T_END,
    "errors": {row["model"]: row for row in rows},
    "blowup_time": blowup,
    "drift": drift,
})
