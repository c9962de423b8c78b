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

The true solution from ``u0*`` blows up near ``t = 27.9``. A solution counts
as blown up from the first output time at which a component exceeds ``10`` in
absolute value (:func:`sk_hamiltonian.metrics.blowup_time`); errors are
reported up to ``t = 25``, and past that the blow-up *times* are compared. The
example is the same in quick mode.
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
from sk_hamiltonian.datasets import PAPER_DT, cherry, make_trajectories
from sk_hamiltonian.metrics import (
    blowup_time,
    hamiltonian_deviation,
    hamiltonian_offset,
    hamiltonian_range,
    mask_blowup,
    relative_error,
)
from sk_hamiltonian.plotting import plot_energy, plot_errors, plot_phase, plot_states

# The example is the same in quick mode (SK_HAMILTONIAN_QUICK=1); its results
# record the mode all the same.
QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").lower() not in ("", "0", "false", "no")
# Figures and measured numbers go to figures/ next to this script (sphinx-gallery
# sets sys.argv[0] to the script it runs), or to $SK_HAMILTONIAN_FIGURES.
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)

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
# The true system is solved by RK4 at step ``dt / 10``, the learned ones by
# RK4 at step ``dt`` (``max_step=PAPER_DT``). ``on_failure="nan"`` turns a
# solution that overflows into NaN instead of an error, and
# :func:`~sk_hamiltonian.metrics.mask_blowup` sets it to NaN from its blow-up
# on, so that every curve stops there.
t = PAPER_DT * np.arange(round(T_END / PAPER_DT) + 1)
x0 = system.initial_state
trajectories = {
    "exact": mask_blowup(system.solve(x0, t, max_step=PAPER_DT / 10, on_failure="nan"))
}
for label, model in {"SP": sp, "non-SP": non_sp}.items():
    U = model.simulate(x0, t, method="rk4", max_step=PAPER_DT, on_failure="nan")
    trajectories[label] = mask_blowup(U)
errors = {label: relative_error(trajectories[label], trajectories["exact"])
          for label in ("SP", "non-SP")}

# ``H~`` is shifted by the constant of the paper's Theorem 3.5 (the mean of
# ``H - H~`` over ``D``) to be comparable with ``H``; it is evaluated where
# the SP solution has not blown up.
u_sp = trajectories["SP"]
before = t < blowup_time(t, u_sp)
H_sp = np.full(t.shape, np.nan)
H_sp[before] = sp.hamiltonian(u_sp[before]) + hamiltonian_offset(
    sp, system.hamiltonian, system.domain
)
fig, (ax_err, ax_ham) = plt.subplots(1, 2, figsize=(11, 4))
plot_errors(t, errors, ax=ax_err)
plot_energy(t, {
    "$H(u(t))$, exact": system.hamiltonian(trajectories["exact"]),
    r"$\tilde H(\tilde u(t)) + C$, SP": H_sp,
    r"$H(\tilde u(t))$, SP": system.hamiltonian(u_sp),
}, deviation=False, ax=ax_ham)
ax_ham.set_title("Hamiltonian along the trajectories")
fig.tight_layout()
fig.savefig(FIGURES / "ex4_errors_hamiltonian.png", dpi=110)

rows = {label: {f"T={T:g}": float(e[round(T / PAPER_DT)]) for T in (10.0, 20.0, 25.0)}
        for label, e in errors.items()}
for label, row in rows.items():
    print(f"{label:>7}: " + ", ".join(f"{key} {value:.3e}" for key, value in row.items()))
blowup = {label: blowup_time(t, U) for label, U in trajectories.items()}
print("blow-up times: " + ", ".join(f"{k} {v:.2f}" for k, v in blowup.items()))

# %%
# Up to its blow-up, the SP model conserves its own ``H~``: RK4 drifts most in
# the fast final approach, the averaged vector field integrator
# (``method="avf"``) does not drift. The drift is measured against the range
# of ``H~`` over ``D``.
scale = hamiltonian_range(sp, system.domain)
u_avf = sp.simulate(x0, t[before], method="avf", max_step=PAPER_DT)
drift = {
    method: hamiltonian_deviation(t[before], sp.hamiltonian(U))["linf"] / scale
    for method, U in (("rk4", u_sp[before]), ("avf", u_avf))
}
print("relative drift of H~ before the blow-up: "
      + ", ".join(f"{m} {v:.2e}" for m, v in drift.items()))

# %%
# Trajectories (Figure 13)
# ------------------------
axes = plot_states(t, {"exact": trajectories["exact"], "SP": u_sp})
axes[0].figure.tight_layout()
axes[0].figure.savefig(FIGURES / "ex4_states_sp.png", dpi=110)

# %%
# Phase plots (Figure 14): ``(p1, p2)`` and ``(q1, q2)``
# ------------------------------------------------------
# One row per pair of state variables, one column per trajectory.
fig, axes = plt.subplots(2, 3, figsize=(10.2, 6.4), sharex="row", sharey="row")
for pair, row in zip([(0, 1), (2, 3)], axes):
    for ax, (label, U) in zip(row, trajectories.items()):
        plot_phase({label: U}, pair=pair, ax=ax).get_legend().remove()
        ax.set_title(label)
fig.tight_layout()
fig.savefig(FIGURES / "ex4_phase.png", dpi=110)

results = {
    "t_end": T_END, "quick_mode": QUICK, "errors": rows, "blowup_time": blowup, "drift": drift,
}
(FIGURES / "ex4_cherry.json").write_text(json.dumps(results, indent=2))
