"""
Learning from the observed steps instead of estimated derivatives
=================================================================

The paper fits ``grad H~`` to time derivatives estimated from the data; on
clean data their ``O(dt**2)`` finite-difference bias, not the model, limits
the accuracy. ``HamiltonianRegressor(fit_on="steps")`` instead asks the
energy-conserving averaged-vector-field (AVF) map of ``H~`` at the data step to
reproduce every observed step ``x0 -> x1``: the least-squares problem is still
linear, and no derivative is estimated. Such a model is simulated by default
with AVF at its training step ``dt_``.

Two scenes from the paper, each fitted three ways (derivatives, steps, and the
non-SP baseline ``VectorFieldRegressor`` on derivatives):

* clean Hénon–Heiles (500 trajectories of 2 steps of ``dt = 0.01``), at the
  paper's degree 3 and at degree 4;
* the noisy pendulum of Example 1 (8 % noise, 41 samples per trajectory),
  de-noised with ``Q = 3`` and fitted at degree 8, the degrees the
  cross-validated ``sk-hamiltonian`` command picks; the steps fit uses the
  de-noised states.

Quick mode (``SK_HAMILTONIAN_QUICK=1``, the documentation build): 200 instead of
500 pendulum trajectories.
"""

# %%
# Clean Hénon–Heiles
# ------------------
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
from sk_hamiltonian.datasets import PAPER_DT, henon_heiles, make_trajectories, single_pendulum
from sk_hamiltonian.metrics import relative_error
from sk_hamiltonian.plotting import plot_errors

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").lower() not in ("", "0", "false", "no")
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)
# Short trajectories started near the edge of the box leave it: expected.
warnings.filterwarnings("ignore", category=DomainWarning)

system = henon_heiles()
X = make_trajectories(system, 500, 2, PAPER_DT, random_state=0)
Xt = DerivativeTransformer(dt=PAPER_DT, method="finite_difference").fit_transform(X)
t = PAPER_DT * np.arange(2001)
truth = system.solve(system.initial_state, t, max_step=PAPER_DT / 10)

results = {}
errors = {}
for degree in (3, 4):
    models = {
        f"SP derivatives, n={degree}": HamiltonianRegressor(degree, domain=system.domain),
        f"SP steps, n={degree}": HamiltonianRegressor(
            degree, domain=system.domain, fit_on="steps"
        ),
    }
    for label, model in models.items():
        model.fit(Xt)
        # Derivative fits: RK4 at the data step (the paper's solver); steps
        # fits: their default, AVF at the training step.
        step = PAPER_DT if "derivatives" in label else None
        errors[label] = relative_error(model.simulate(system.initial_state, t, max_step=step), truth)
baseline = VectorFieldRegressor(3, domain=system.domain).fit(Xt)
errors["non-SP derivatives, n=3"] = relative_error(
    baseline.simulate(system.initial_state, t, max_step=PAPER_DT), truth
)
results["henon_heiles"] = {label: float(e[-1]) for label, e in errors.items()}
for label, value in results["henon_heiles"].items():
    print(f"Hénon–Heiles, {label:26s} error at T = 20: {value:.2e}")

fig, ax = plt.subplots(figsize=(7, 4))
plot_errors(t, errors, ax=ax)
ax.set_title("Clean Hénon–Heiles: relative error from u0*")
fig.tight_layout()
fig.savefig(FIGURES / "steps_henon_heiles.png", dpi=110)

# %%
# The steps fit is 40 times more accurate than the paper's fit at degree 4,
# and raising the degree helps it (the modified Hamiltonian of the AVF map has
# a few higher-degree terms), while it does not help the derivative fit, which
# only fits its bias harder. It conserves its ``H~`` exactly, like every
# structure-preserving model:
steps_model = HamiltonianRegressor(4, domain=system.domain, fit_on="steps").fit(Xt)
H = steps_model.hamiltonian(steps_model.simulate(system.initial_state, t))
print(f"steps model: training step dt_ = {steps_model.dt_}, max |H~(t) - H~(0)| = "
      f"{np.abs(H - H[0]).max():.1e}")
results["steps_model_drift"] = float(np.abs(H - H[0]).max())

# %%
# The noisy pendulum
# ------------------
pendulum = single_pendulum()
M = 200 if QUICK else 500
Xn = make_trajectories(pendulum, M, 40, PAPER_DT, noise=0.08, random_state=0)
Xtn = DerivativeTransformer(dt=PAPER_DT, degree=3).fit_transform(Xn)
tp = PAPER_DT * np.arange(2001)
truth_p = pendulum.solve(pendulum.initial_state, tp, max_step=PAPER_DT / 10)
pendulum_models = {
    "SP derivatives": HamiltonianRegressor(8),
    "SP steps": HamiltonianRegressor(8, fit_on="steps"),
    "non-SP derivatives": VectorFieldRegressor(8),
}
pendulum_errors = {}
for label, model in pendulum_models.items():
    model.fit(Xtn)
    step = PAPER_DT if "derivatives" in label else None
    Y = model.simulate(pendulum.initial_state, tp, max_step=step, on_failure="nan")
    pendulum_errors[label] = relative_error(Y, truth_p)
results["noisy_pendulum"] = {label: float(e[-1]) for label, e in pendulum_errors.items()}
for label, value in results["noisy_pendulum"].items():
    print(f"noisy pendulum, {label:20s} error at T = 20: {value:.3g}")

fig, ax = plt.subplots(figsize=(7, 4))
plot_errors(tp, pendulum_errors, ax=ax)
ax.set_title(f"Noisy pendulum (8 %, M = {M}): relative error from u0*")
fig.tight_layout()
fig.savefig(FIGURES / "steps_noisy_pendulum.png", dpi=110)

# %%
# Under noise the derivative bias is small next to the noise, and the two fits
# see the same de-noised states: the steps fit does no harm here and gains a
# little. ``fit_on`` is a parameter like any other, so
# :class:`~sklearn.model_selection.GridSearchCV` can choose it; the default
# score already runs each candidate with its own default integrator.
(FIGURES / "steps_fit.json").write_text(json.dumps(dict(results, quick_mode=QUICK), indent=2))
