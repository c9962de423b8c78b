"""
Lattices: the FPUT chain with a pairwise, separable model
=========================================================

A chain of ``N`` unit masses joined by springs, with fixed walls at both ends
(:func:`~sk_hamiltonian.datasets.fput_chain`, the beta-FPUT chain):
``H = sum_i p_i**2 / 2 + sum_bonds V(q_{i+1} - q_i)``,
``V(r) = r**2 / 2 + r**4 / 4``. Its Hamiltonian is *separable* (kinetic plus
potential energy) and every term involves at most *two* variables. A
:class:`~sk_hamiltonian.HamiltonianRegressor` with ``separable=True`` and
``max_interaction=2`` learns exactly such functions: for ``N = 8`` (16 state
variables) and degree 4 it has 400 terms, where the total-degree basis has
4 844. Its terms grow like ``N**2``, the total degree's like ``N**4``.

The data are short trajectories: bursts of ``J = 2`` steps of ``dt = 0.01``
started uniformly in half the chain's default box (``|q_i|, |p_i| <= 0.5``,
where the test orbit lives), with second-order finite differences for the
derivatives. The example

1. fits the pairwise separable model and the total-degree one (degree 3, which
   cannot represent the quartic bonds, and in full mode degree 4, which
   can, at about 40 times the fit time);
2. simulates both from the smooth test state ``u0*`` (the longest standing
   wave, amplitude 0.4) with every integrator the model allows: the explicit
   symplectic ``"leapfrog"`` and ``"yoshida4"`` (separable models only) and
   ``"rk4"``;
3. follows the learned energy ``H~`` over a long leapfrog run;
4. learns a chain too long for the total-degree basis, with every pair of
   variables and with neighbouring positions only (``couplings``), the
   latter also from the observed steps (``fit_on="simpson"``).

* Full mode: the total-degree model of degree 4 too (4 844 terms; minutes),
  a leapfrog run to ``T = 1000``, and a chain of 32 particles (64 state
  variables, 6 208 terms with every pair, 442 with neighbours only) from 400
  bursts. About half an hour on two shared cores.
* Quick mode (``SK_HAMILTONIAN_QUICK=1``, used by the documentation build):
  total degree 3 only, the long run to ``T = 200``, and a chain of 16
  particles (1 568 and 218 terms) instead of 32.

Run as a script, it writes its figures and a JSON file of the measured numbers
to ``figures/`` next to itself (``SK_HAMILTONIAN_FIGURES`` overrides the
folder).
"""

# %%
# Data
# ----
import json
import os
import time
import tracemalloc
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from threadpoolctl import threadpool_limits

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
from sk_hamiltonian.datasets import fput_chain, make_trajectories
from sk_hamiltonian.model_selection import count_terms

QUICK = os.environ.get("SK_HAMILTONIAN_QUICK", "").strip().lower() not in ("", "0", "false")
try:
    HERE = Path(__file__).resolve().parent
except NameError:  # pasted into a notebook or an interpreter
    HERE = Path.cwd()
FIGURES = Path(os.environ.get("SK_HAMILTONIAN_FIGURES") or HERE / "figures")
FIGURES.mkdir(parents=True, exist_ok=True)

DT = 0.01


def bursts(chain, n_bursts, seed=0):
    """Bursts of two steps in half the default box, with their derivatives."""
    X = make_trajectories(chain, n_bursts, 2, DT, domain=chain.domain / 2, random_state=seed)
    return DerivativeTransformer(dt=DT, method="finite_difference").fit_transform(X)


def timed_fit(model, Xt):
    """Fit on one BLAS thread; wall and CPU seconds.

    One thread, so that fit times compare between models on a shared machine
    (drop ``threadpool_limits`` to use every core); CPU seconds beside wall
    seconds, because on a loaded machine the wall time also counts waiting.
    """
    with threadpool_limits(limits=1, user_api="blas"):
        wall, cpu = time.perf_counter(), time.process_time()
        model.fit(Xt)
        return model, time.perf_counter() - wall, time.process_time() - cpu


def max_relative_error(Y, truth):
    """Largest ``||u~(t) - u(t)|| / ||u(t)||`` over the run; inf if it failed."""
    error = np.linalg.norm(Y - truth, axis=-1) / np.linalg.norm(truth, axis=-1)
    return float(error.max()) if np.isfinite(error).all() else np.inf


chain = fput_chain(8)
Xt = bursts(chain, 3_000)
results = {"quick_mode": QUICK, "n_particles": 8, "n_bursts": 3_000, "dt": DT, "models": {}}

# %%
# Pairwise separable model against the total-degree basis
# --------------------------------------------------------
# ``count_terms`` gives the size of a space before fitting it.
pairwise = HamiltonianRegressor(degree=4, separable=True, max_interaction=2)
print(f"pairwise separable, degree 4: {count_terms(pairwise, n_states=16)} terms; "
      f"total degree 4: {count_terms(HamiltonianRegressor(degree=4), n_states=16)} terms")
candidates = {"pairwise separable, degree 4": pairwise,
              "total degree 3": HamiltonianRegressor(degree=3)}
if not QUICK:
    candidates["total degree 4"] = HamiltonianRegressor(degree=4)
models = {}
for label, model in candidates.items():
    models[label], fit_s, fit_cpu_s = timed_fit(model, Xt)
    results["models"][label] = dict(n_terms=model.n_terms_, fit_s=fit_s, fit_cpu_s=fit_cpu_s,
                                    cond=model.cond_, rollouts={})
    print(f"{label:>28}: {model.n_terms_:5d} terms, fit {fit_s:6.1f} s ({fit_cpu_s:.1f} s CPU), "
          f"cond {model.cond_:.3g}")

# %%
# Rollouts from ``u0*``
# ---------------------
# Every integrator the model allows, at its default step. The explicit
# symplectic methods need ``separable=True``; the total-degree model can only
# use ``"rk4"`` (or the implicit ``"avf"``). The three integrators of the
# pairwise model agree with each other far below the model's own error.
#
# That error is the bias of the finite differences, ``O(dt**2)``: the chain's
# ``H`` lies in the pairwise space, and the same fit with exact derivatives
# follows the truth to 6e-12 (with ``dt = 0.005``, 4 times closer than with
# 0.01). Total degree 3 cannot hold the quartic bonds. Total degree 4 (full
# mode) was measured 2.5 times *more* accurate than the pairwise model: its
# mixed terms absorb part of the derivative bias, which is not separable. It
# costs about 40 times the fit time of the pairwise model, and its RK4 rollout
# 4 times the time; the pairwise space is what scales (last section).
T_END = 10.0
t = np.arange(0.0, T_END + 1e-9, DT)
truth = chain.solve(chain.initial_state, t)
runs = [("pairwise separable, degree 4", m) for m in ("leapfrog", "yoshida4", "rk4")]
runs += [(label, "rk4") for label in models if label.startswith("total")]
fig, ax = plt.subplots(figsize=(7, 4))
for label, method in runs:
    wall = time.perf_counter()
    Y = models[label].simulate(chain.initial_state, t, method=method, on_failure="nan")
    sim_s = time.perf_counter() - wall
    error = np.linalg.norm(Y - truth, axis=1) / np.linalg.norm(truth, axis=1)
    results["models"][label]["rollouts"][method] = dict(
        max_error=max_relative_error(Y, truth), sim_s=sim_s)
    print(f"{label:>28} {method:>8}: max relative error on [0, {T_END:g}] "
          f"{max_relative_error(Y, truth):.2e}, simulate {sim_s:.1f} s")
    ax.semilogy(t, error, label=f"{label}, {method}",
                ls="--" if method == "yoshida4" else "-")
ax.set_xlabel("t")
ax.set_ylabel("$\\|\\tilde u(t) - u(t)\\| / \\|u(t)\\|$")
ax.set_title(f"FPUT chain, {chain.n_dof} particles: rollouts from $u_0^*$")
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(FIGURES / "lattice_rollouts.png", dpi=110)

# %%
# The learned energy over a long leapfrog run
# -------------------------------------------
# A symplectic method does not conserve ``H~`` exactly, but its error
# oscillates and stays bounded over arbitrarily long runs; RK4's is smaller at
# this step but drifts. One step ``h = 0.05`` per output (``max_step=np.inf``).
T_LONG = 200.0 if QUICK else 1_000.0
h = 0.05
t_long = h * np.arange(int(round(T_LONG / h)) + 1)
model = models["pairwise separable, degree 4"]
fig, ax = plt.subplots(figsize=(7, 4))
energy = {}
for method in ("leapfrog", "rk4"):
    Y = model.simulate(chain.initial_state, t_long, method=method, max_step=np.inf)
    deviation = np.abs(model.hamiltonian(Y) - model.hamiltonian(Y[:1]))
    tenth = t_long.size // 10
    energy[method] = dict(first_tenth=float(deviation[:tenth].max()),
                          last_tenth=float(deviation[-tenth:].max()),
                          true_h_deviation=float(np.ptp(chain.hamiltonian(Y))))
    ax.semilogy(t_long[1:], deviation[1:], label=method, lw=0.8)
    row = energy[method]
    print(f"{method:>8}: max |H~(t) - H~(0)| in the first tenth {row['first_tenth']:.2e}, "
          f"in the last tenth {row['last_tenth']:.2e}; "
          f"spread of the true H along it {row['true_h_deviation']:.2e}")
results["long_run"] = dict(t_end=T_LONG, step=h, energy=energy,
                           h_initial=float(chain.hamiltonian(chain.initial_state)))
ax.set_xlabel("t")
ax.set_ylabel("$|\\tilde H(\\tilde u(t)) - \\tilde H(u_0^*)|$")
ax.set_title(f"learned energy, step {h}, pairwise separable model")
ax.legend()
fig.tight_layout()
fig.savefig(FIGURES / "lattice_energy.png", dpi=110)

# %%
# A chain too long for the total-degree basis
# -------------------------------------------
# With ``N`` particles the total-degree-4 basis has ``C(2N + 4, 4) - 1`` terms,
# the pairwise separable one ``O(N**2)``. The pairwise space still holds every
# pair of variables, not only neighbours, so it grows quadratically; the
# chain's own ``H`` uses ``O(N)`` of its terms. ``couplings`` names the groups
# of variables that may share a basis function: here the bonds, the pairs of
# neighbouring positions (momenta come first in the state, so ``q_i`` is
# variable ``N + i``). That space grows like ``N`` and still holds the chain's
# ``H``. But it has no spare terms to absorb the finite differences' bias,
# which the other pairs partly do: fitted to the same derivatives it is less
# accurate. Fitted to the observed steps instead (``fit_on="simpson"``:
# Simpson's rule over each burst's two steps, no derivative estimate, no
# bias of that order), it follows the chain to round-off of the fit. Peak
# memory of each fit is traced by ``tracemalloc`` (NumPy reports its arrays
# to it).
N_LARGE = 16 if QUICK else 32
N_BURSTS_LARGE = 400
large = fput_chain(N_LARGE)
Xt_large = bursts(large, N_BURSTS_LARGE)
bonds = [(N_LARGE + i, N_LARGE + i + 1) for i in range(N_LARGE - 1)]
total_terms = count_terms(HamiltonianRegressor(degree=4), n_states=2 * N_LARGE)
t = np.arange(0.0, T_END + 1e-9, DT)
truth = large.solve(large.initial_state, t)
results["large"] = dict(n_particles=N_LARGE, n_bursts=N_BURSTS_LARGE,
                        total_degree_terms=total_terms, models={})
for label, model in (
    ("every pair", HamiltonianRegressor(degree=4, separable=True, max_interaction=2)),
    ("neighbours", HamiltonianRegressor(degree=4, separable=True, couplings=bonds)),
    ("neighbours, simpson", HamiltonianRegressor(
        degree=4, separable=True, couplings=bonds, fit_on="simpson")),
):
    tracemalloc.start()
    model, fit_s, fit_cpu_s = timed_fit(model, Xt_large)
    peak_mb = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    wall = time.perf_counter()
    # The Simpson fit's error is far below leapfrog's at this step: RK4.
    method = "rk4" if model.fit_on == "simpson" else "leapfrog"
    Y = model.simulate(large.initial_state, t, method=method)
    sim_s = time.perf_counter() - wall
    row = dict(n_terms=model.n_terms_, fit_s=fit_s, fit_cpu_s=fit_cpu_s, fit_peak_mb=peak_mb,
               sim_s=sim_s, max_error=max_relative_error(Y, truth), cond=model.cond_)
    results["large"]["models"][label] = row
    print(f"{N_LARGE} particles, {label}: {model.n_terms_} terms (total degree 4: "
          f"{total_terms}), fit {fit_s:.1f} s ({fit_cpu_s:.1f} s CPU, peak {peak_mb:.0f} MB "
          f"traced), {method} to T = {T_END:g} {sim_s:.1f} s, max relative error "
          f"{row['max_error']:.2e}, cond {model.cond_:.3g}")

(FIGURES / "lattice_fput.json").write_text(json.dumps(results, indent=2, allow_nan=True))
