"""
One long record: what a single energy level can tell
====================================================

A lab often records one long run rather than many short bursts.
:class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` takes such a
record as it is: it cuts it into contiguous segments and holds out whole
segments, so that no test sample has a training neighbour.

But a conservative system's record stays on one level set of its
Hamiltonian, ``H = E``, and there the data determine the law only up to terms
that vanish with their gradient on that level: ``H`` and
``H + (H - E)**2 g`` move a state on the level alike, for any ``g``. The
search then keeps the law with the fewest terms among those that explain the
record, and says that the data lie on one level
(an :class:`~sk_hamiltonian.IllConditionedWarning`, and
``preparation_["one_level"]``). Records at a few different energies pin the
law down.

Here: a pendulum recorded once (4 001 samples, ``dt = 0.01``, 2 % noise) and
five times at different energies (801 samples each), each through the
default search, then both learned models simulated from states at energies
across the box, beside the truth.

Quick mode (``SK_HAMILTONIAN_QUICK=1``, the documentation build): shorter
records, fewer de-noising degrees and fit targets.
"""

# %%
# One record, five records
# ------------------------
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from sk_hamiltonian import ConservationWarning, DomainWarning, IllConditionedWarning
from sk_hamiltonian.datasets import single_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)
# Poor candidates leave the data's box and trend in energy: expected here.
warnings.filterwarnings("ignore", category=DomainWarning)
warnings.filterwarnings("ignore", category=ConservationWarning)

DT = 0.01
settings = {}
if QUICK:
    settings.update(denoise_degrees=[3, 5], fit_on=["derivatives", "simpson"])

pendulum = single_pendulum()
# States that swing without going over the top (the energy of the upright
# pendulum is 2 g = 19.6 above the rest state): one record, then five.
starts = np.array([[0.0, 1.6], [0.0, 0.5], [0.0, 1.0], [0.0, 1.4], [0.0, 2.0], [0.0, 2.4]])
n_one, n_five = (2001, 401) if QUICK else (4001, 801)
rng = np.random.default_rng(0)


def record(x0, n_times):
    """A record from the true pendulum, each sample times ``1 + 0.02 z``."""
    clean = pendulum.solve(x0, DT * np.arange(n_times), max_step=DT / 10)
    return clean * (1 + 0.02 * rng.standard_normal(clean.shape))


one = [record(starts[0], n_one)]
five = [record(x0, n_five) for x0 in starts[1:]]

searches = {}
for name, X in (("one record", one), ("five records", five)):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", IllConditionedWarning)
        searches[name] = HamiltonianSearchCV(dt=DT, **settings).fit(X)
    said = [str(w.message) for w in caught if issubclass(w.category, IllConditionedWarning)]
    print(f"{name}: {format_hamiltonian(searches[name].best_estimator_[-1])}")
    print("   one energy level:", "; ".join(said) if said else "no")

# %%
# What the search keeps of the finding
# ------------------------------------
# ``preparation_["one_level"]`` holds the energies' spread as a fraction of
# the learned energy's range over the data's box, their median energy and the
# number of pieces the record was cut into; None when the data reach several
# levels.
print("one record:", searches["one record"].preparation_["one_level"])
print("five records:", searches["five records"].preparation_["one_level"])

# %%
# Off the recorded level
# ----------------------
# Each learned model, simulated with the averaged-vector-field integrator
# from states at energies across the box, against the truth at T = 20. The
# law kept from one record is the one with the fewest terms that explains
# it. Here that is the pendulum's own law, and the model learned from one
# record is as accurate off its level as on it; but nothing in the record
# itself rules out the laws that differ from it off the level, so the search
# says so rather than claiming the law is pinned down.
t = np.arange(0.0, 20.0 + 1e-9, DT)
tests = np.column_stack([np.zeros(9), np.linspace(0.3, 2.6, 9)])
energies = pendulum.hamiltonian(tests)
truths = pendulum.solve(tests, t, max_step=DT / 10)[:, -1]
errors = {}
for name, search in searches.items():
    model = search.best_estimator_[-1]
    difference = model.simulate(tests, t, method="avf")[:, -1] - truths
    if model.periodic_[1]:  # a learned angle is wrapped: the short way round
        difference[:, 1] = (difference[:, 1] + np.pi) % (2 * np.pi) - np.pi
    errors[name] = (np.linalg.norm(difference, axis=1)
                    / np.linalg.norm(truths, axis=1)).tolist()
    print(name, " ".join(f"{e:.2g}" for e in errors[name]))

fig, (ax_phase, ax_error) = plt.subplots(1, 2, figsize=(11, 4))
q, p = np.meshgrid(np.linspace(-np.pi, np.pi, 200), np.linspace(-7.5, 7.5, 200))
ax_phase.contour(q, p, pendulum.hamiltonian(np.stack([p, q], axis=-1)), levels=12,
                 colors="0.85", linewidths=0.8)
for k, samples in enumerate(five):
    ax_phase.plot(samples[:, 1], samples[:, 0], ".", ms=1, color="C0",
                  label="five records" if k == 0 else None)
ax_phase.plot(one[0][:, 1], one[0][:, 0], ".", ms=1, color="C3", label="one record")
ax_phase.set_xlabel("q")
ax_phase.set_ylabel("p")
ax_phase.legend(loc="upper right", fontsize="small", markerscale=8)
ax_phase.set_title("The records on the true energy's level sets")
for name, color in (("one record", "C3"), ("five records", "C0")):
    ax_error.semilogy(energies, np.maximum(errors[name], 1e-16), "o-", color=color, label=name)
for k, level in enumerate(pendulum.hamiltonian(starts)):
    ax_error.axvline(level, color="C3" if k == 0 else "C0", lw=0.8, ls=":")
ax_error.set_xlabel("energy of the test state")
ax_error.set_ylabel("relative error at T = 20")
ax_error.legend(fontsize="small")
ax_error.set_title("Learned models off the recorded levels (dotted)")
fig.tight_layout()
fig.savefig(FIGURES / "one_record.png", dpi=120)

results = {
    "quick_mode": QUICK,
    **{name.replace(" ", "_"): {
        "terms": sorted(term.text for term in hamiltonian_terms(search.best_estimator_[-1])),
        "one_level": search.preparation_["one_level"] is not None,
        "errors_T20": errors[name],
    } for name, search in searches.items()},
    "test_energies": energies.tolist(),
}
(FIGURES / "one_record.json").write_text(json.dumps(results, indent=2))
