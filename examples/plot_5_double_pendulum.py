"""
Example 5: double pendulum, and convergence in the degree
=========================================================

The paper's last example: a double pendulum with unit masses and rods, in its
angles ``q1, q2`` and canonical momenta ``p1, p2``. Its Hamiltonian is not a
polynomial, so high degrees are needed: ``H~`` has degree ``n = 15``
(3 875 coefficients), learned from ``M = 20 000`` clean trajectories of
``J = 2`` steps of ``dt = 0.01`` (:data:`~sk_hamiltonian.datasets.PAPER_DT`)
started uniformly in ``D = (-5, 5) x (-4, 4) x (-1, 1) x (-1, 1)``, with
second-order finite differences. As in the paper, ``n = 16`` with
``M = 20 000`` and ``n = 18`` with ``M = 60 000`` show the convergence in the
degree. Each learned system is simulated from ``u0* = (0, 0, pi/6, pi/4)`` up
to ``T = 20`` with RK4: the Hamiltonian over time (paper's Figure 16), the
states (Figure 17), phase plots (Figure 18) and relative errors (Figure 19).

The design has 12 equations per trajectory (3 states of 4 components), so the
``"normal"`` solver streams it into the normal equations: ``n = 15`` with
``M = 20 000`` forms a 3 875 x 3 875 matrix from 240 000 equations.

* ``n = 18`` with ``M = 60 000`` (7 314 coefficients, 720 000 equations)
  takes a quarter to half an hour on two cores: it runs only if the
  environment variable ``SK_HAMILTONIAN_LONG=1`` is set.
* Quick mode (``SK_HAMILTONIAN_QUICK=1``, used by the documentation build):
  ``M = 4 000`` for both ``n = 15`` and ``n = 16`` (still 10 equations per
  unknown), and the conservation check runs to ``T = 2``, so that the example
  runs in a few minutes.
"""

# %%
# Data and models
# ---------------
import warnings

import matplotlib.pyplot as plt
import numpy as np

from sk_hamiltonian import DerivativeTransformer, DomainWarning, HamiltonianRegressor
from sk_hamiltonian import _paper as paper
from sk_hamiltonian.datasets import PAPER_DT, double_pendulum, make_trajectories
from sk_hamiltonian.plotting import plot_energy

# Trajectories started near the boundary of D leave it within their two steps;
# the basis stays the paper's, on D.
warnings.filterwarnings("ignore", category=DomainWarning)

system = double_pendulum()
settings = system.paper_settings  # n = 15, M = 20 000, J = 2, T = 20
T_END = settings["t_final"]
RUNS = [(15, paper.pick(20_000, 4_000)), (16, paper.pick(20_000, 4_000))]
if paper.long_runs():
    RUNS.append((18, 60_000))

t = paper.time_grid(T_END)
u = paper.reference(system, t)
models, trajectories, errors = {}, {"exact": u}, {}
results = {"t_end": T_END, "runs": {}}
for degree, n_trajectories in RUNS:
    label = f"n = {degree}, M = {n_trajectories}"
    X = make_trajectories(
        system, n_trajectories, settings["n_intervals"], PAPER_DT, random_state=0
    )
    Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=degree, domain=system.domain, solver="normal")
    models[label] = model.fit(Xt)
    trajectories[label] = paper.rollout(model, system.initial_state, t)
    errors[label] = paper.relative_error(trajectories[label], u)
    row = paper.error_table(t, {label: errors[label]}, [5.0, 10.0, 20.0])[0]
    row.update(n_terms=model.n_terms_, cond=model.cond_)
    print(paper.format_table([row], list(row)))
    # Saved after every run, so that an interrupted long run keeps its numbers.
    results["runs"][label] = row
    paper.save_results("ex5_double_pendulum", results)

# %%
# Hamiltonian over time (Figure 16)
# ---------------------------------
# Each ``H~`` is shifted by the constant of the paper's Theorem 3.5 (the mean
# of ``H - H~`` over ``D``) to be comparable with ``H``. RK4 at step ``dt``
# conserves ``H~`` to a few parts in ``1e8`` or better; the averaged vector
# field (AVF) integrator to round-off.
first = next(iter(models))
fig, ax = plt.subplots(figsize=(6.5, 4))
plot_energy(t, {
    "$H(u(t))$, exact": system.hamiltonian(u),
    **{
        rf"$\tilde H(\tilde u(t)) + C$, {label}": model.hamiltonian(trajectories[label])
        + paper.hamiltonian_offset(model, system)
        for label, model in models.items()
    },
}, deviation=False, ax=ax)
ax.set_title("Hamiltonian along the trajectories")
fig.tight_layout()
paper.save_figure(fig, "ex5_hamiltonian")
# An AVF step of a degree-15 H~ costs about ten RK4 steps; conservation does
# not depend on the horizon, so quick mode checks it up to T = 2 only.
T_CONSERVATION = paper.pick(T_END, 2.0)
results["drift"] = paper.conservation(models[first], system, paper.time_grid(T_CONSERVATION))
print(f"relative drift of H~ ({first}) up to T = {T_CONSERVATION:g}: "
      + ", ".join(f"{m} {v:.2e}" for m, v in results["drift"].items()))

# %%
# States (Figure 17), for the paper's ``n = 15``
# ----------------------------------------------
fig = paper.plot_states(t, u, trajectories[first], first)
paper.save_figure(fig, "ex5_states")

# %%
# Phase plots (Figure 18): ``(q1, p2)`` and ``(q2, p1)``, one column per model
# ------------------------------------------------------------------------------
fig = paper.plot_phase(trajectories, [(2, 1), (3, 0)])
paper.save_figure(fig, "ex5_phase")

# %%
# Relative errors (Figure 19): they decrease with the degree
# -----------------------------------------------------------
fig, ax = plt.subplots(figsize=(6.5, 4))
paper.plot_errors(ax, t, errors)
fig.tight_layout()
paper.save_figure(fig, "ex5_errors")
print(paper.format_table(list(results["runs"].values()), ["model", "T=5", "T=10", "T=20", "mean"]))
results["mean_error"] = {label: float(np.mean(err)) for label, err in errors.items()}
paper.save_results("ex5_double_pendulum", results)
