"""
Learn a Hamiltonian from your own data
======================================

From a file of measured trajectories to a saved model: read the file, let
cross-validation choose how to smooth the data and how rich the model is,
read the learned Hamiltonian ``H~``, check that the learned system conserves
it, and save the model for later.

The file is a CSV with one row per sample: a ``trajectory`` column that
numbers the trajectories, then the momenta ``p..`` and the positions ``q..``
(first all momenta, then all positions; the last section reads positions
first, under names of your own), sampled every ``dt``. The rows of a
trajectory are contiguous and in time order; trajectories may have different
lengths.
"""

# %%
# A stand-in for your measurements
# --------------------------------
# So that this example runs anywhere, we first write such a file: noisy
# recordings of a pendulum of unknown length, 0.8, 1.2 or 1.6 seconds long,
# sampled every 0.02 s with 2 % noise. **With your own data, skip this cell**
# and point ``path`` at your file.
import shutil
import tempfile
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import DerivativeTransformer, DomainWarning, HamiltonianRegressor, load, save
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.inspection import format_hamiltonian
from sk_hamiltonian.metrics import hamiltonian_deviation
from sk_hamiltonian.model_selection import count_terms, one_standard_error_rule
from sk_hamiltonian.plotting import plot_energy, plot_phase

DT = 0.02
workdir = Path(tempfile.mkdtemp(prefix="sk_hamiltonian_example_"))
path = workdir / "measurements.csv"

measured = make_trajectories(
    single_pendulum(length=1.3), 80, 80, DT, noise=0.02,
    domain=[[-2.5, 2.5], [-1.5, 1.5]], random_state=0,
)
lengths = np.random.default_rng(0).choice([41, 61, 81], len(measured))
rows = [
    np.column_stack([np.full(n, k), trajectory[:n]])
    for k, (trajectory, n) in enumerate(zip(measured, lengths))
]
np.savetxt(path, np.vstack(rows), delimiter=",", header="trajectory,p,q", comments="",
           fmt=["%d", "%.6f", "%.6f"])
print(path.read_text().splitlines()[:4])

# %%
# Read the file into a list of trajectories
# -----------------------------------------
# One array of shape ``(n_times, n_states)`` per trajectory, in the order of
# the file. With pandas, the same list is ``[group[state_names].to_numpy() for
# _, group in pandas.read_csv(path).groupby("trajectory", sort=False)]``.
data = np.genfromtxt(path, delimiter=",", names=True)
state_names = list(data.dtype.names[1:])  # ["p", "q"]
ids = data["trajectory"]
states = np.column_stack([data[name] for name in state_names])
starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
X = np.split(states, starts[1:])
print(f"{len(X)} trajectories of {min(map(len, X))} to {max(map(len, X))} samples, "
      f"states {state_names}")

# %%
# Choose the smoothing and the model by cross-validation
# ------------------------------------------------------
# The pipeline estimates time derivatives by a least-squares polynomial of
# degree ``Q`` through each trajectory's samples (which also de-noises the
# states), then fits ``H~`` as a polynomial of degree ``n``. The search holds
# out whole trajectories (``KFold`` over the list) and scores each candidate
# by simulating it from an initial state fitted to every held-out trajectory's
# samples and comparing with them (the estimator's ``score``). Among the
# candidates whose score is within one standard error of the best, the
# one-standard-error rule refits the one with the fewest terms: a small model
# is easy to read. To get closest to the true system, keep scikit-learn's
# default ``refit=True`` (the best mean score), which did better in the
# fold-and-refit study of the cross-validation guide.
pipe = make_pipeline(DerivativeTransformer(dt=DT), HamiltonianRegressor())
grid = {
    "derivativetransformer__degree": [3, 5, 7],
    "hamiltonianregressor__degree": [2, 4, 6],
}
search = GridSearchCV(
    pipe, grid, cv=KFold(3, shuffle=True, random_state=0),
    refit=one_standard_error_rule(pipe, n_states=len(state_names)),
)
# Poor candidates simulate out of the region the data cover, and say so; the
# cross-validated score already ranks them low.
with warnings.catch_warnings():
    warnings.simplefilter("ignore", DomainWarning)
    search.fit(X)

results = search.cv_results_
for params, mean, std in zip(results["params"], results["mean_test_score"],
                             results["std_test_score"]):
    print(f"Q = {params['derivativetransformer__degree']}, "
          f"n = {params['hamiltonianregressor__degree']}: "
          f"{count_terms(pipe, len(state_names), params):2d} terms, "
          f"score {mean:.4f} +- {std:.4f}")
best = search.best_params_
print(f"chosen: Q = {best['derivativetransformer__degree']}, "
      f"n = {best['hamiltonianregressor__degree']}")

# %%
# The learned Hamiltonian
# -----------------------
# ``search.best_estimator_`` is the pipeline refitted on all the data with the
# chosen degrees; its last step is the fitted
# :class:`~sk_hamiltonian.HamiltonianRegressor`. ``H~`` is defined up to a
# constant. The stand-in pendulum has ``H = p**2 / (2 l**2) + g l (1 - cos q)``
# with ``l = 1.3``, ``g = 9.8``, whose Taylor expansion starts with
# ``0.296 p**2 + 6.37 q**2 - 0.53 q**4``: a degree-4 ``H~`` comes close (its
# ``q**4`` coefficient also stands in for the missing higher powers), and the
# small remaining terms are fitted noise.
model = search.best_estimator_
regressor = model[-1]
print(format_hamiltonian(regressor, state_names=state_names))

# %%
# Does the learned system conserve its energy?
# --------------------------------------------
# Simulate it from the first sample of the first trajectory, well past the
# length of any measured trajectory. The averaged vector field method
# (``method="avf"``) conserves ``H~`` to round-off at any step; the classical
# Runge-Kutta method drifts slightly.
t = np.arange(0.0, 10.0, DT)
x0 = X[0][0]
runs = {method: regressor.simulate(x0, t, method=method) for method in ("rk4", "avf")}
energy = {method.upper(): regressor.hamiltonian(U) for method, U in runs.items()}
for method, H in energy.items():
    print(f"{method}: max |H~(t) - H~(0)| = {hamiltonian_deviation(t, H)['linf']:.2e}")

fig, (ax_phase, ax_energy) = plt.subplots(1, 2, figsize=(11, 4))
plot_phase({"learned, AVF": runs["avf"]}, state_names=state_names, ax=ax_phase,
           scatter=np.vstack(X))
ax_phase.plot(X[0][:, 1], X[0][:, 0], "k.", ms=3, label="measured trajectory 0")
ax_phase.legend(fontsize="small")
ax_phase.set_title("Phase plane")
ax_energy.set_title("Drift of the learned energy")
plot_energy(t, energy, ax=ax_energy)
fig.tight_layout()

# %%
# Save the model, and load it back
# --------------------------------
# :func:`~sk_hamiltonian.save` writes the fitted pipeline as a zip of a JSON
# manifest and arrays, which cannot carry code (unlike a pickle or joblib
# file), with a note of where the model came from; :func:`~sk_hamiltonian.load`
# checks everything before giving the model back, identical bit for bit.
# ``sk-hamiltonian show model.skh`` prints it, ``sk-hamiltonian simulate``
# runs it from new initial states (see :ref:`sharing`).
save(model, workdir / "model.skh", provenance={"data": path.name})
loaded = load(workdir / "model.skh")
same = np.array_equal(loaded[-1].hamiltonian(runs["avf"]), energy["AVF"])
print(f"saved {workdir / 'model.skh'}; the loaded model gives the same H~: {same}")

# %%
# Columns in your own order, under your own names
# ------------------------------------------------
# Many lab files put the positions first. ``state_order="qp"`` reads the
# columns as ``(q, p)`` and gives every state-shaped output back in that
# order; ``state_names`` (in the columns' order) names the variables in
# formulas, reports and model files. The model inside is the same.
X_qp = [trajectory[:, ::-1] for trajectory in X]  # as a file "trajectory,theta,L" would give
named = make_pipeline(
    DerivativeTransformer(dt=DT, degree=best["derivativetransformer__degree"]),
    HamiltonianRegressor(degree=best["hamiltonianregressor__degree"], state_order="qp",
                         state_names=["theta", "L"]),
).fit(X_qp)
print(named[-1].equations())
print("the same coefficients:", np.allclose(named[-1].coef_, regressor.coef_))

shutil.rmtree(workdir)  # the stand-in file and the model; keep yours
