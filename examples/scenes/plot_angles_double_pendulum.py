"""
Angles: the double pendulum over full circles
=============================================

When the state holds angles that go all the way round, ``H`` is periodic in
them, and a polynomial basis spends most of its terms approximating that
periodicity. This example learns the double pendulum (unit masses and rods,
``g = 1``) with both angles over the whole circle ``[-pi, pi)`` and both
momenta in ``[-1, 1]``
(:func:`~sk_hamiltonian.datasets.double_pendulum` with ``full_circle=True``)
in three model spaces of :class:`~sk_hamiltonian.HamiltonianRegressor`:

* **total degree** (the default): Legendre polynomials of total degree
  ``degree`` in all four variables;
* **mechanical**: ``momentum_degree=2``, at most quadratic in the momenta
  (every ``p^T M(q) p / 2 + V(q)`` is), still Legendre in the angles;
* **Fourier-mechanical**: ``periodic=system.periodic, momentum_degree=2``,
  quadratic in the momenta and trigonometric (``cos k q``, ``sin k q``) in the
  angles.

For each space and a few degrees it measures the error of the learned ``H~``
against ``H`` over the whole domain, the error of a rollout from the test state
``u0* = (0, 0, 0, 2)`` and the fit time, against the number of terms.

The fits use the exact time derivatives at states drawn uniformly in the
domain (``fit(X, system.vector_field(X))``), so that what is compared is the
model space alone; the :ref:`lattice example <sphx_glr_auto_examples_scenes_plot_lattice_fput.py>`
learns from trajectories with finite differences instead.

The orbit from ``u0*`` reaches ``|p1| = 2.1``, outside the momentum range of
the data: the rollout also shows which models extrapolate in ``p``.

* Full mode: 20 000 training states; Fourier-mechanical degrees 4 to 20 (up to
  4 417 terms), mechanical 6 to 26, total degree 4 to 14 (3 059 terms). About
  ten minutes of CPU time; the fits at the largest sizes take minutes each.
* Quick mode (``SK_HAMILTONIAN_QUICK=1``, used by the documentation build):
  3 000 training states and models up to about 700 terms; the rollouts stop at
  ``T = 5`` instead of 10.

Run as a script, it writes its figures and a JSON file of the measured numbers
to ``figures/`` next to itself (``SK_HAMILTONIAN_FIGURES`` overrides the
folder).
"""

# %%
# Set-up
# ------
import json
import os
import time
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from threadpoolctl import threadpool_limits

from sk_hamiltonian import DomainWarning, HamiltonianRegressor
from sk_hamiltonian.datasets import double_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
try:
    HERE = Path(__file__).resolve().parent
except NameError:  # pasted into a notebook or an interpreter
    HERE = Path.cwd()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or HERE / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)

system = double_pendulum(g=1.0, full_circle=True)
low, high = system.domain[:, 0], system.domain[:, 1]
rng = np.random.default_rng(0)
n_train = 4_000 if QUICK else 20_000
X = rng.uniform(low, high, size=(n_train, 4))
y = system.vector_field(X)
X_test = rng.uniform(low, high, size=(5_000, 4))
H_test = system.hamiltonian(X_test)

SPACES = {
    "total degree": dict(),
    "mechanical": dict(momentum_degree=2),
    "Fourier-mechanical": dict(periodic=system.periodic, momentum_degree=2),
}
DEGREES = {
    "total degree": [4, 6, 8, 9] if QUICK else [4, 6, 8, 10, 12, 14],
    "mechanical": [6, 10, 14, 18] if QUICK else [6, 10, 14, 18, 22, 26],
    "Fourier-mechanical": [4, 6, 8, 10, 12] if QUICK else [4, 8, 12, 16, 20],
}

T_END = 5.0 if QUICK else 10.0
t = np.arange(0.0, T_END + 1e-9, 0.01)
truth = system.solve(system.initial_state, t)


def h_error(model):
    """Relative L2 error of H~ over the domain, up to the free constant of H~."""
    return float(np.std(model.hamiltonian(X_test) - H_test) / np.std(H_test))


def rollout_error(model):
    """Largest relative error ||u~(t) - u(t)|| / ||u(t)|| on [0, T_END], inf if it failed."""
    # The orbit leaves the momentum box of the data by design (see above).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DomainWarning)
        Y = model.simulate(system.initial_state, t, on_failure="nan")
    diff = Y - truth
    # A periodic model returns its angles wrapped into [-pi, pi); compare them
    # the short way round the circle.
    diff[:, 2:] = (diff[:, 2:] + np.pi) % (2 * np.pi) - np.pi
    error = np.linalg.norm(diff, axis=1) / np.linalg.norm(truth, axis=1)
    return (float(error.max()) if np.isfinite(error).all() else np.inf), Y


# %%
# Fits
# ----
# One BLAS thread, so that fit times compare between spaces on a shared
# machine (drop ``threadpool_limits`` to use every core). CPU seconds are
# recorded beside wall seconds: on a loaded machine the wall time also counts
# the time the process waited for a core.
results = {"quick_mode": QUICK, "n_train": n_train, "t_end": T_END, "spaces": {}}
models, rollouts = {}, {}
for space, params in SPACES.items():
    rows = results["spaces"][space] = []
    for degree in DEGREES[space]:
        model = HamiltonianRegressor(degree, domain=system.domain, **params)
        with threadpool_limits(limits=1, user_api="blas"):
            wall, cpu = time.perf_counter(), time.process_time()
            model.fit(X, y)
            fit_s, fit_cpu_s = time.perf_counter() - wall, time.process_time() - cpu
            wall = time.perf_counter()
            roll, Y = rollout_error(model)
            sim_s = time.perf_counter() - wall
        row = dict(degree=degree, n_terms=model.n_terms_, h_error=h_error(model),
                   rollout_error=roll, fit_s=fit_s, fit_cpu_s=fit_cpu_s, sim_s=sim_s,
                   cond=model.cond_)
        rows.append(row)
        models[space, degree], rollouts[space, degree] = model, Y
        print(f"{space:>18}  degree {degree:2d}  {model.n_terms_:5d} terms  "
              f"H error {row['h_error']:.2e}  rollout error {roll:.2e}  "
              f"fit {fit_s:6.1f} s ({fit_cpu_s:.1f} s CPU)  simulate {sim_s:5.1f} s  "
              f"cond {model.cond_:.3g}")

# %%
# Error against the number of terms
# ---------------------------------
# The Fourier-mechanical space converges fastest: its terms are the ones
# ``H`` is made of (``p_i p_j`` times periodic functions of the angles, plus a
# periodic potential), whereas Legendre polynomials in the angles spend many
# terms approximating periodic functions, and a total-degree basis spends most
# of its terms on powers of ``p`` that ``H`` does not have.
COLORS = {"total degree": "C3", "mechanical": "C1", "Fourier-mechanical": "C0"}
fig, axes = plt.subplots(1, 3, figsize=(13, 4))
for space, rows in results["spaces"].items():
    terms = [r["n_terms"] for r in rows]
    axes[0].loglog(terms, [r["h_error"] for r in rows], "o-", color=COLORS[space], label=space)
    finite = [(n, r["rollout_error"]) for n, r in zip(terms, rows)
              if np.isfinite(r["rollout_error"])]
    if finite:
        axes[1].loglog(*zip(*finite), "o-", color=COLORS[space], label=space)
    failed = [n for n, r in zip(terms, rows) if not np.isfinite(r["rollout_error"])]
    if failed:
        axes[1].scatter(failed, [3.0] * len(failed), marker="x", s=60, color=COLORS[space],
                        label=f"{space}: failed")
    axes[2].loglog(terms, [r["fit_s"] for r in rows], "o-", color=COLORS[space], label=space)
axes[0].set_title("error of $\\tilde H$ over the domain")
axes[0].set_ylabel("std$(\\tilde H - H)$ / std$(H)$")
axes[1].set_title(f"rollout from $u_0^*$, max relative error on [0, {T_END:g}]")
axes[2].set_title("fit time (one BLAS thread, shared machine)")
axes[2].set_ylabel("seconds")
for ax in axes:
    ax.set_xlabel("number of terms")
    ax.grid(True, which="both", alpha=0.3)
axes[1].legend(fontsize=8)
fig.tight_layout()
fig.savefig(FIGURES / "angles_error_vs_terms.png", dpi=110)

# %%
# Rollouts from ``u0*``
# ---------------------
# The outer angle ``q2`` of the largest model of each space against the truth.
# Models quadratic in ``p`` carry what they learned in ``|p| <= 1`` to the
# larger momenta of this orbit; the total-degree model has no reason to.
fig, ax = plt.subplots(figsize=(7, 3.5))
ax.plot(t, truth[:, 3], "k-", lw=2.5, alpha=0.4, label="exact")
for space in SPACES:
    degree = DEGREES[space][-1]
    ax.plot(t, rollouts[space, degree][:, 3], color=COLORS[space],
            label=f"{space}, {models[space, degree].n_terms_} terms")
ax.set_xlabel("t")
ax.set_ylabel("$q_2$")
ax.set_ylim(-np.pi, np.pi)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(FIGURES / "angles_rollouts.png", dpi=110)

# %%
# The learned Hamiltonian, readably
# ---------------------------------
# :func:`~sk_hamiltonian.inspection.format_hamiltonian` re-expands ``H~`` in the
# user's coordinates. The true ``H`` is
# ``(p1**2 + 2 p2**2 - 2 p1 p2 cos(q1 - q2)) / (2 (1 + sin(q1 - q2)**2)) - 2 cos q1 - cos q2``.
# Its potential ``-2 cos q1 - cos q2`` is a finite Fourier series, which the
# model finds to a few digits. Its kinetic part is an infinite Fourier series
# in ``q1 - q2``, which the model truncates; the basis is a tensor product in
# ``q1`` and ``q2``, so ``cos(q1 - q2)`` shows as the pair
# ``cos(q1)*cos(q2) + sin(q1)*sin(q2)`` with equal coefficients. The terms of
# ``p1**2`` and ``p2**2`` alone are the means over ``q1 - q2`` of their
# coefficients in ``H``: ``1 / (2 sqrt 2) = 0.35355`` and
# ``1 / sqrt 2 = 0.70711``.
best_space = min(results["spaces"], key=lambda s: min(r["h_error"] for r in results["spaces"][s]))
best_row = min(results["spaces"][best_space], key=lambda r: r["h_error"])
best = models[best_space, best_row["degree"]]
names = ["p1", "p2", "q1", "q2"]
text = format_hamiltonian(best, state_names=names, max_terms=10)
print(f"best: {best_space}, degree {best_row['degree']} ({best.n_terms_} terms)")
print(text)
terms = {term.text: term.coefficient for term in hamiltonian_terms(best, state_names=names)}
exact = {"cos(q1)": -2.0, "cos(q2)": -1.0, "p1^2": 1 / (2 * np.sqrt(2)), "p2^2": 1 / np.sqrt(2)}
for name, value in exact.items():
    print(f"{name:>8}: learned {terms.get(name, 0.0):+.6f}, exact {value:+.6f}")
results["best"] = dict(space=best_space, degree=best_row["degree"], n_terms=best.n_terms_,
                       text=text, terms={name: terms.get(name, 0.0) for name in exact},
                       exact_terms=exact)

(FIGURES / "angles_double_pendulum.json").write_text(
    json.dumps(results, indent=2, allow_nan=True)
)
