"""
Example 2: an exponential Hamiltonian
=====================================

The paper's second example, ``H(p, q) = exp(-p**2 - 1.1 q**4)``: a
non-polynomial Hamiltonian learned in the polynomials of degree ``n = 6``.
The data are ``M = 300`` clean trajectories of ``J = 2`` steps of
``dt = 0.01`` (:data:`~sk_hamiltonian.datasets.PAPER_DT`) started uniformly in
``D = [-1, 1]**2``; derivatives come from second-order finite differences.
The structure-preserving (SP) model and the non-SP baseline (the vector field
fitted component-wise in the same polynomial space) are simulated from
``u0* = (0.6, 0.6)`` with RK4 and compared with the true solution: errors and
the Hamiltonian over time (paper's Figure 6), trajectories (Figure 7) and phase
plots (Figure 8).

Quick mode (``SK_HAMILTONIAN_QUICK=1``, used by the documentation build): the
horizon is ``T = 20`` instead of 100, and the robustness check at the end
refits on 3 data sets instead of 10; data and models are the paper's.
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
from sk_hamiltonian.datasets import PAPER_DT, exponential, make_trajectories

# Trajectories started near the boundary of D leave it within their two steps;
# the basis stays the paper's, on D.
warnings.filterwarnings("ignore", category=DomainWarning)

system = exponential()
settings = system.paper_settings  # n = 6, M = 300, J = 2, clean data
T_END = paper.pick(100.0, 20.0)

X = make_trajectories(
    system, settings["n_trajectories"], settings["n_intervals"], PAPER_DT, random_state=0
)


def fit_models(X):
    """SP and non-SP models of the paper's degree, from finite differences."""
    Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
    paper_model = dict(degree=settings["degree"], domain=system.domain)
    return {
        "SP": HamiltonianRegressor(**paper_model).fit(Xt),
        "non-SP": VectorFieldRegressor(**paper_model).fit(Xt),
    }


models = fit_models(X)
sp = models["SP"]

# %%
# Errors and Hamiltonian over time (Figure 6)
# -------------------------------------------
# ``H~`` is shifted by the constant of the paper's Theorem 3.5 (the mean of
# ``H - H~`` over ``D``) to be comparable with ``H``.
t = paper.time_grid(T_END)
trajectories, errors = paper.compare(system, models, t)
fig = paper.plot_errors_and_hamiltonian(system, t, trajectories, errors, sp)
paper.save_figure(fig, "ex2_errors_hamiltonian")

rows = paper.error_table(t, errors, paper.checkpoints(T_END))
print(paper.format_table(rows, list(rows[0])))

# The SP model conserves its own ``H~``: up to RK4's small drift, and to
# round-off with the averaged vector field integrator.
drift = paper.conservation(sp, system, t)
print("relative drift of H~: " + ", ".join(f"{m} {v:.2e}" for m, v in drift.items()))

# %%
# Trajectories (Figure 7)
# -----------------------
for label in ("SP", "non-SP"):
    fig = paper.plot_states(t, trajectories["exact"], trajectories[label], label)
    paper.save_figure(fig, f"ex2_states_{label.replace('-', '_').lower()}")

# %%
# Phase plots (Figure 8)
# ----------------------
fig = paper.plot_phase(trajectories, [(0, 1)])
paper.save_figure(fig, "ex2_phase")

# %%
# How robust is the comparison?
# -----------------------------
# The figures above come from one draw of initial states. Refitting on
# independent draws, the mean relative error over ``[0, 20]`` (before the
# errors saturate) shows whether SP's advantage is systematic.
SEEDS = range(paper.pick(10, 3))
by_seed = paper.over_data_sets(system, fit_models, SEEDS, t_end=20.0)
seed_rows, wins = paper.data_set_summary(by_seed, [("SP", "non-SP")])
print(f"mean relative error over [0, 20], {len(SEEDS)} data sets")
print(paper.format_table(seed_rows, ["model", "median", "min", "max"]))
print("\n".join(f"{k}: {v} of {len(SEEDS)} data sets" for k, v in wins.items()))

paper.save_results("ex2_exponential", {
    "t_end": T_END,
    "errors": {row["model"]: row for row in rows},
    "drift": drift,
    "seeds": {"mean_error_0_20": by_seed, "wins": wins},
})
