"""
One record at small angles: terms the trajectories drop
=======================================================

A pendulum, ``H = p**2 / 2 - 9.8 cos q``, recorded once (3 001 samples,
``dt = 0.02``, 2 % relative noise) at angles within about 1 rad. Along one
orbit ``p**2`` is a function of ``q``, so terms such as ``p**2 q**2`` stand in
for powers of ``q``; at small angles ``cos q``, ``q**2`` and ``q**4`` are
nearly collinear. The finalists of
:class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` keep
``p^2, q^2`` (which misses ``q**4``) or six terms with ``p^2 q^2`` and
``p^2 q^4``; their rollout scores, over a fraction of a second of held-out
data, hardly tell them apart.

Stage 3 fits each set of terms to the raw trajectories and weighs them by an
information criterion (``judgement_``). The larger set wins; its terms are
then dropped one at a time while the criterion improves
(``judgement_["pruned"]``), down to ``p^2, q^2, q^4``, whose softening
``q**4`` is offered ``cos q`` in its place. The search is run twice, with its
default folds and with shuffled ones: under the shuffled folds the six-term
finalist scores just outside the tie, and is judged with the tied ones as
their *richer* rival, then preferred (``judgement_["untied"]``). Both give the
cosine law. Then the three laws of
the path, each fitted by least squares on named terms
(``HamiltonianRegressor(terms=...)``), are simulated from fresh states.

The search runs with its defaults in quick mode too
(``SK_HAMILTONIAN_QUICK=1``, the documentation build): the path above is
the defaults'.
"""

# %%
# The record and two searches
# ---------------------------
import json
import os
import sys
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from sklearn.model_selection import KFold

from sk_hamiltonian import (
    ConservationWarning,
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
    IllConditionedWarning,
)
from sk_hamiltonian.datasets import single_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
here = Path(sys.argv[0]).resolve().parent if Path(sys.argv[0]).name.startswith("plot_") else Path()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or here / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)
# Poor candidates leave the data's box and trend in energy; one record lies on
# one energy level (the search says so): expected here.
for category in (DomainWarning, ConservationWarning, IllConditionedWarning):
    warnings.filterwarnings("ignore", category=category)

DT = 0.02
system = single_pendulum()
box = np.asarray(system.domain, dtype=float)


def states_below(energy, n, rng):
    """``n`` uniform states of the pendulum's box below ``energy``."""
    found = []
    while len(found) < n:
        x = rng.uniform(box[:, 0], box[:, 1], size=(256, 2))
        found.extend(x[system.hamiltonian(x) < energy])
    return np.array(found[:n])


rng = np.random.default_rng(12)
clean = system.solve(states_below(5.0, 1, rng), DT * np.arange(3001), max_step=DT / 10)
X = clean * (1 + 0.02 * rng.standard_normal(clean.shape))

searches = {
    "default folds": HamiltonianSearchCV(dt=DT).fit(X),
    "shuffled folds": HamiltonianSearchCV(
        dt=DT, cv=KFold(5, shuffle=True, random_state=1)).fit(X),
}
for name, search in searches.items():
    judgement = search.judgement_
    print(f"{name}: {format_hamiltonian(search.best_estimator_[-1])}")
    print(f"  untied finalist judged and taken: {judgement['untied']}")
    print(f"  pruned: {judgement['pruned']}")
    print(f"  last verdict ({judgement['kind']}): criterion {judgement['bic'].round(2)} "
          f"for {judgement['terms']}")

# %%
# The stages in ``cv_results_``
# -----------------------------
# The finalists (one per layout and fit target), the pruned law and the two
# cosine offers, with their number of terms and mean rollout score.
results = searches["shuffled folds"].cv_results_
for i in np.flatnonzero(np.isin(results["stage"], ["finalist", "pruned", "cosine"])):
    print(f"{results['stage'][i]:9s} terms {results['n_terms'][i]:2d}  "
          f"score {results['mean_test_score'][i]:.4f}  tied {results['tied'][i]}")

# %%
# The laws of the path, simulated
# -------------------------------
# Each set of terms fitted by least squares to the same derivatives (a
# de-noising polynomial of degree 5), then simulated from 20 fresh states
# below the record's energy, against the truth at T = 20.
Xt = DerivativeTransformer(dt=DT, degree=5).fit_transform(X)
named = {
    "six terms": HamiltonianRegressor(6, momentum_degree=2, terms=[
        [2, 0], [0, 2], [0, 4], [0, 6], [2, 2], [2, 4]]),
    "pruned: p^2, q^2, q^4": HamiltonianRegressor(4, momentum_degree=2,
                                                   terms=[[2, 0], [0, 2], [0, 4]]),
}
models = {"search": searches["default folds"].best_estimator_[-1]}
for name, model in named.items():
    models[name] = model.fit(Xt)
    print(f"{name}: {format_hamiltonian(model)}")

energy = system.hamiltonian(clean[0, :1])[0]
tests = states_below(energy, 20, np.random.default_rng(1))
t = np.arange(0.0, 20.0 + 1e-9, DT)
truths = system.solve(tests, t, max_step=DT / 10)
errors = {}
fig, ax = plt.subplots(figsize=(6, 4))
for name, model in models.items():
    paths = model.simulate(tests, t, method="avf")
    relative = (np.linalg.norm(paths - truths, axis=2)
                / np.linalg.norm(truths, axis=2))
    errors[name] = relative[:, -1].tolist()
    print(f"{name}: median error at T = 20 {np.median(relative[:, -1]):.2g}")
    ax.semilogy(t[1:], np.median(relative[:, 1:], axis=0), label=name)
ax.set_xlabel("time")
ax.set_ylabel("median relative state error")
ax.set_title("Pendulum from one record at small angles")
ax.legend(fontsize="small")
fig.tight_layout()
fig.savefig(FIGURES / "pruned_terms.png", dpi=120)

record = {
    name: {"terms": sorted(term.text for term in hamiltonian_terms(search.best_estimator_[-1])),
           "untied": search.judgement_["untied"], "pruned": search.judgement_["pruned"],
           "kind": search.judgement_["kind"]}
    for name, search in searches.items()
}
record.update(quick_mode=QUICK, errors_T20=errors)
(FIGURES / "pruned_terms.json").write_text(json.dumps(record, indent=2))
