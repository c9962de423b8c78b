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
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from sk_hamiltonian import DerivativeTransformer, DomainWarning, HamiltonianRegressor
from sk_hamiltonian.datasets import PAPER_DT, double_pendulum, make_trajectories
from sk_hamiltonian.metrics import (
    hamiltonian_deviation,
    hamiltonian_offset,
    hamiltonian_range,
    mask_blowup,
    relative_error,
)
from sk_hamiltonian.plotting import plot_energy, plot_errors, plot_phase, plot_states


def flag(name):
    """Whether the environment variable ``name`` is set to a true value."""
    return os.environ.get(name, "").lower() not in ("", "0", "false", "no")


QUICK, LONG = flag("SK_HAMILTONIAN_QUICK"), flag("SK_HAMILTONIAN_LONG")
# Figures and measured numbers go to figures/ next to this script (sphinx-gallery
# sets sys.argv[0] to the script it runs), or to $SK_HAMILTONIAN_FIGURES.
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)

# Trajectories started near the boundary of D leave it within their two steps;
# the basis stays the paper's, on D.
warnings.filterwarnings("ignore", category=DomainWarning)

system = double_pendulum()
settings = system.paper_settings  # n = 15, M = 20 000, J = 2, T = 20
T_END = settings["t_final"]
M = 4_000 if QUICK else 20_000
RUNS = [(15, M), (16, M)] + ([(18, 60_000)] if LONG else [])

# The true system by RK4 at step dt / 10, the learned ones by RK4 at step dt
# (``max_step=PAPER_DT``; by default ``simulate`` picks its own step).
t = PAPER_DT * np.arange(round(T_END / PAPER_DT) + 1)
x0 = system.initial_state
u = system.solve(x0, t, max_step=PAPER_DT / 10)
models, trajectories, errors = {}, {"exact": u}, {}
results = {"t_end": T_END, "quick_mode": QUICK, "long_runs": LONG, "runs": {}}
for degree, n_trajectories in RUNS:
    label = f"n = {degree}, M = {n_trajectories}"
    X = make_trajectories(
        system, n_trajectories, settings["n_intervals"], PAPER_DT, random_state=0
    )
    Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
    model = HamiltonianRegressor(degree=degree, domain=system.domain, solver="normal")
    models[label] = model.fit(Xt)
    U = model.simulate(x0, t, method="rk4", max_step=PAPER_DT, on_failure="nan")
    trajectories[label] = mask_blowup(U)
    errors[label] = relative_error(trajectories[label], u)
    row = {f"T={T:g}": float(errors[label][round(T / PAPER_DT)]) for T in (5.0, 10.0, 20.0)}
    row.update(mean=float(np.mean(errors[label])), n_terms=model.n_terms_, cond=model.cond_)
    print(f"{label}: " + ", ".join(f"{key} {value:.3g}" for key, value in row.items()
                                   if key != "n_terms") + f", {model.n_terms_} terms")
    # Saved after every run, so that an interrupted long run keeps its numbers.
    results["runs"][label] = row
    (FIGURES / "ex5_double_pendulum.json").write_text(json.dumps(results, indent=2))

# %%
# Hamiltonian over time (Figure 16)
# ---------------------------------
# Each ``H~`` is shifted by the constant of the paper's Theorem 3.5 (the mean
# of ``H - H~`` over ``D``) to be comparable with ``H``. RK4 at step ``dt``
# conserves ``H~`` to a few parts in ``1e8`` or better; the averaged vector
# field (AVF) integrator to round-off.
ax = plot_energy(t, {
    "$H(u(t))$, exact": system.hamiltonian(u),
    **{
        rf"$\tilde H(\tilde u(t)) + C$, {label}": model.hamiltonian(trajectories[label])
        + hamiltonian_offset(model, system.hamiltonian, system.domain)
        for label, model in models.items()
    },
}, deviation=False)
ax.set_title("Hamiltonian along the trajectories")
ax.figure.tight_layout()
ax.figure.savefig(FIGURES / "ex5_hamiltonian.png", dpi=110)

# %%
# The drift of ``H~`` with RK4 and AVF, against the range of ``H~`` over
# ``D``. An AVF step of a degree-15 ``H~`` costs about ten RK4 steps;
# conservation does not depend on the horizon, so quick mode checks it up to
# ``T = 2`` only.
first = next(iter(models))
T_CONSERVATION = 2.0 if QUICK else T_END
t_c = t[: round(T_CONSERVATION / PAPER_DT) + 1]
scale = hamiltonian_range(models[first], system.domain)
results["drift"] = {
    method: hamiltonian_deviation(t_c, models[first].hamiltonian(
        models[first].simulate(x0, t_c, method=method, max_step=PAPER_DT)
    ))["linf"] / scale
    for method in ("rk4", "avf")
}
print(f"relative drift of H~ ({first}) up to T = {T_CONSERVATION:g}: "
      + ", ".join(f"{m} {v:.2e}" for m, v in results["drift"].items()))

# %%
# States (Figure 17), for the paper's ``n = 15``
# ----------------------------------------------
axes = plot_states(t, {"exact": u, first: trajectories[first]})
axes[0].figure.tight_layout()
axes[0].figure.savefig(FIGURES / "ex5_states.png", dpi=110)

# %%
# Phase plots (Figure 18): ``(q1, p2)`` and ``(q2, p1)``, one column per model
# ------------------------------------------------------------------------------
fig, axes = plt.subplots(2, len(trajectories), figsize=(3.4 * len(trajectories), 6.4),
                         sharex="row", sharey="row")
for pair, row in zip([(2, 1), (3, 0)], axes):
    for ax, (label, U) in zip(row, trajectories.items()):
        plot_phase({label: U}, pair=pair, ax=ax).get_legend().remove()
        ax.set_title(label)
fig.tight_layout()
fig.savefig(FIGURES / "ex5_phase.png", dpi=110)

# %%
# Relative errors (Figure 19): they decrease with the degree
# -----------------------------------------------------------
ax = plot_errors(t, errors)
ax.figure.tight_layout()
ax.figure.savefig(FIGURES / "ex5_errors.png", dpi=110)
results["mean_error"] = {label: float(np.mean(err)) for label, err in errors.items()}
(FIGURES / "ex5_double_pendulum.json").write_text(json.dumps(results, indent=2))
