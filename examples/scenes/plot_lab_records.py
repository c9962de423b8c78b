"""
Lab records: their own units, lost readings and readings moved off
==================================================================

Records from a lab are rarely in the units a textbook would choose, and
the logger that wrote them is rarely perfect. Here an anharmonic spring,
``H = p**2/2 + q**2/2 + q**4/4``, is recorded as a lab might: positions in
millimetres beside momenta in SI units, 120 short records of 41 samples
every 0.05 s, 1 % noise, and four kinds of logger fault: readings lost (NaN),
a reading written as 1e6 (a spike), and two readings moved off by thirty
noise levels at the very ends of their records, where no neighbour on one
side gives them away.

:class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` takes the
records as they are:

- the positions spread about a thousand times more than the momenta, so the
  equations of ``dq/dt`` would outweigh those of ``dp/dt`` a million times in
  every misfit; the search compares its candidates with the momenta
  multiplied by the power of ten that brings the two nearest together
  (``preparation_["momentum_scale"]``, here 1000: the numbers of SI units
  again), and fits the chosen terms in the file's units;
- lost readings and spikes are left out before any model sees them, their
  records cut there (``preparation_["missing"]``, ``["left_out"]``);
- readings moved off at the ends of records are found by the trajectory fit,
  as samples alone far off the fitted trajectories, and left out
  (``refinement_["outliers"]``).

Each is named in an :class:`~sk_hamiltonian.OutlierWarning`.

Quick mode (``SK_HAMILTONIAN_QUICK=1``, the documentation build): fewer
de-noising degrees and fit targets.
"""

# %%
# The records, faults and all
# ---------------------------
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from sk_hamiltonian import OutlierWarning
from sk_hamiltonian.datasets import anharmonic_spring
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)

DT = 0.05
MILLIMETRES = np.array([1.0, 1000.0])  # (p, q): momenta as they are, positions in mm
spring = anharmonic_spring()
rng = np.random.default_rng(0)
clean = spring.solve(rng.uniform(-1.5, 1.5, size=(120, 2)), DT * np.arange(41),
                     max_step=DT / 10)
noise = 0.01 * clean.std(axis=(0, 1))
X = (clean + noise * rng.standard_normal(clean.shape)) * MILLIMETRES

X[4, 12] = np.nan  # readings the logger lost
X[9, 30, 1] = np.nan
X[20, 0] = np.nan
X[30, 25, 1] = 1e6  # a reading written as 1e6
X[50, 0, 1] -= 30 * noise[1] * 1000  # moved off, at a record's first sample
X[70, 40, 1] += 30 * noise[1] * 1000  # ... and at another's last

# %%
# The default search
# ------------------
settings = {}
if QUICK:
    settings.update(denoise_degrees=[5], fit_on=["derivatives", "simpson"])
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always", OutlierWarning)
    search = HamiltonianSearchCV(dt=DT, **settings).fit(X)
for warning in caught:  # the search's own words (its inner fits warn of their folds too)
    if str(warning.message).startswith("HamiltonianSearchCV"):
        print("OutlierWarning:", warning.message)
model = search.best_estimator_[-1]
print("learned:", format_hamiltonian(model))
print("truth in these units: 500 p^2 + 0.0005 q^2 + 2.5e-10 q^4")
print("momenta multiplied by", search.preparation_["momentum_scale"],
      "for the comparison of candidates")
print("missing readings:", search.preparation_["missing"])
print("left out before the search:", search.preparation_["left_out"])
print("left out by the trajectory fit:", search.refinement_["outliers"])

# %%
# The learned law, in the file's units
# ------------------------------------
# The model reads and answers in millimetres: simulated from fresh states,
# its trajectories lie on the truth's. The left panel marks what was left
# out and why (the spike at 1e6 mm is off the chart).
t = np.arange(0.0, 20.0 + 1e-9, DT)
starts = np.array([[0.0, 0.5], [0.0, 1.0], [0.0, 1.4]])
truth = spring.solve(starts, t, max_step=DT / 10) * MILLIMETRES
learned = model.simulate(starts * MILLIMETRES, t)
errors = (np.linalg.norm((learned[:, -1] - truth[:, -1]) / MILLIMETRES, axis=1)
          / np.linalg.norm(truth[:, -1] / MILLIMETRES, axis=1))
print("relative error at T = 20 from three fresh states:", np.round(errors, 4).tolist())

fig, (ax_data, ax_model) = plt.subplots(1, 2, figsize=(11, 4))
for k, record in enumerate(X):
    ax_data.plot(record[:, 1], record[:, 0], ".", ms=1, color="0.6",
                 label="records" if k == 0 else None)
lost = np.array([clean[k, j] * MILLIMETRES
                 for k, indices in search.preparation_["left_out"].items() for j in indices])
ax_data.plot(lost[:, 1], lost[:, 0], "x", color="C3", ms=8,
             label="lost or spiked, left out before the search (where the truth was)")
moved = np.array([X[k, j] for k, indices in search.refinement_["outliers"].items()
                  for j in indices])
ax_data.plot(moved[:, 1], moved[:, 0], "o", color="C1", mfc="none", ms=8,
             label="moved off, left out by the trajectory fit")
ax_data.set_xlim(1.2 * np.nanmin(clean[..., 1]) * 1000, 1.2 * np.nanmax(clean[..., 1]) * 1000)
ax_data.set_ylim(1.2 * np.nanmin(clean[..., 0]), 1.8 * np.nanmax(clean[..., 0]))  # the legend
ax_data.set_xlabel("q (mm)")
ax_data.set_ylabel("p (SI)")
ax_data.legend(fontsize="small", markerscale=2)
ax_data.set_title("The records and what was left out")
for k in range(len(starts)):
    ax_model.plot(truth[k, :, 1], truth[k, :, 0], color="0.3", lw=3, alpha=0.4,
                  label="truth" if k == 0 else None)
    ax_model.plot(learned[k, :, 1], learned[k, :, 0], color="C0", lw=1,
                  label="learned" if k == 0 else None)
ax_model.set_xlabel("q (mm)")
ax_model.set_ylabel("p (SI)")
ax_model.legend(fontsize="small")
ax_model.set_title("Learned model from fresh states, T = 20")
fig.tight_layout()
fig.savefig(FIGURES / "lab_records.png", dpi=120)

terms = {term.text: term.coefficient for term in hamiltonian_terms(model)}
results = {
    "quick_mode": QUICK,
    "terms": sorted(terms),
    "coefficients": terms,
    "momentum_scale": search.preparation_["momentum_scale"],
    "missing": {str(k): v for k, v in search.preparation_["missing"].items()},
    "left_out": {str(k): v for k, v in search.preparation_["left_out"].items()},
    "outliers": {str(k): v for k, v in search.refinement_["outliers"].items()},
    "errors_T20": errors.tolist(),
}
(FIGURES / "lab_records.json").write_text(json.dumps(results, indent=2))
