"""Which held-out comparison selects the de-noising and model degrees best?

For noisy trajectory data, a grid over the de-noising degree ``Q``
(``derivativetransformer__degree``) and the polynomial degree ``n``
(``hamiltonianregressor__degree``) is cross-validated (5 folds of whole
trajectories) with several held-out scores, all computed from the same fits:

``rollout``
    The default ``score``: one rollout per held-out trajectory from its first
    observation over its whole window, compared with the observations.
``k-step``
    Predictions ``k`` sampling steps ahead from *every* observation, compared
    with the observations ``1..k`` steps later (``--steps`` sets ``k``).
``restart``
    One rollout per trajectory restarted at the observation every ``k`` steps:
    the same comparisons as ``k-step`` from every ``k``-th start only, at the
    cost of the single rollout.
``derivative R2``
    What PySINDy does: R² of the predicted derivatives against the held-out
    derivatives produced by the same smoother, at the smoothed states.

Every grid pair is then refitted on all the data and judged against the
*true* system: mean relative trajectory error (capped at 1, failures count 1)
from fresh initial states drawn in the domain, over the training window
``J dt`` and over ``T = 20``. The table gives, per score, the true error of
its pick divided by the best true error on the grid (1 is perfect), as the
geometric mean over seeds, the worst seed, and the share of seeds within
1.5x; ``+1SE`` rows apply the one-standard-error rule to the same scores.

Run (about 30 minutes on one core)::

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/cv_scoring_study.py

``--quick`` runs the Morse setting only, on the coarse grid of the test
(``Q = 2, 4, .., 12``, ``n = 3, 5, 7``), one seed unless ``--seeds`` is given.
``--henon-heiles DT NOISE`` instead tabulates, per seed, the cross-validated
score, its standard error and the true error of every degree ``n = 1..8`` on
the paper's Henon-Heiles set-up (finite differences, ``M = 500``, ``J = 2``),
and what the one-standard-error rule picks.
"""

import argparse
import time
import warnings

import numpy as np
from sklearn.base import clone
from sklearn.metrics import r2_score
from sklearn.model_selection import GridSearchCV, KFold
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    SimulationError,
    unpack_derivatives,
)
from sk_hamiltonian._integrate import integrate
from sk_hamiltonian.datasets import (
    HamiltonianSystem,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian.model_selection import multistep_scorer, one_standard_error_rule

N_FRESH = 100
LONG_HORIZON = 20.0
# Output spacing of the long-horizon comparison, and the integration steps of
# the learned and true systems there: far finer than any learning error.
LONG_SPACING = 0.1
MODEL_STEP = 0.01
REFERENCE_STEP = 0.001


def morse_oscillator(depth=1.0, width=1.0):
    """``H = p**2 / 2 + depth * (1 - exp(-width * q))**2``, bound orbits only.

    The domain keeps every energy below ``depth`` (0.32 + 0.40 < 1), so no
    trajectory escapes; its period is about 4.4 at low energy.
    """

    def hamiltonian(X):
        p, q = X[..., 0], X[..., 1]
        return 0.5 * p**2 + depth * (1.0 - np.exp(-width * q)) ** 2

    def gradient(X):
        p, q = X[..., :1], X[..., 1:]
        e = np.exp(-width * q)
        return np.concatenate([p, 2.0 * depth * width * e * (1.0 - e)], axis=-1)

    return HamiltonianSystem(
        "morse", hamiltonian, gradient,
        domain=[[-0.8, 0.8], [-0.4, 1.0]], initial_state=[0.3, 0.2],
        params=dict(depth=depth, width=width),
    )


def derivative_r2(estimator, X, y=None):
    """PySINDy's score: R² against the smoother's own held-out derivatives."""
    data = unpack_derivatives(estimator[:-1].transform(X))
    states = data.states.reshape(-1, data.states.shape[-1])
    return r2_score(data.derivatives.reshape(states.shape), estimator[-1].predict(states))


def rollout_score(estimator, X, y=None):
    return estimator.score(X)


def true_errors(system, model, x0, t, reference):
    """Mean relative error of the learned system from ``x0``; failures count 1."""
    Y, failed_at = integrate(model._integrator("rk4"), x0, t, MODEL_STEP)
    Y = np.swapaxes(Y, 0, 1)
    errors = np.linalg.norm(Y - reference, axis=(1, 2)) / np.linalg.norm(reference, axis=(1, 2))
    errors[failed_at < t.shape[0]] = 1.0
    return float(np.mean(np.minimum(errors, 1.0)))


SETTINGS = {
    "morse": dict(system=morse_oscillator, dt=0.1, n_intervals=40, noise=0.10),
    "pendulum": dict(system=single_pendulum, dt=0.01, n_intervals=40, noise=0.08),
}


def run_one(setting, seed, Qs, ns, n_trajectories, n_steps):
    config = SETTINGS[setting]
    system, dt, J = config["system"](), config["dt"], config["n_intervals"]
    X = make_trajectories(system, n_trajectories, J, dt, noise=config["noise"], random_state=seed)
    rng = np.random.default_rng(1000 + seed)
    x0 = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(N_FRESH, 2))
    horizons = {"window": (J * dt, dt), "T=20": (LONG_HORIZON, LONG_SPACING)}
    references = {}
    for name, (T, spacing) in horizons.items():
        t = spacing * np.arange(int(round(T / spacing)) + 1)
        references[name] = (t, system.solve(x0, t, max_step=REFERENCE_STEP))

    pipe = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())
    scoring = {
        "rollout": rollout_score,
        f"{n_steps}-step": multistep_scorer(n_steps),
        "restart": multistep_scorer(n_steps, stride=n_steps),
        "derivative R2": derivative_r2,
    }
    grid = {"derivativetransformer__degree": Qs, "hamiltonianregressor__degree": ns}
    search = GridSearchCV(
        pipe, grid, scoring=scoring, refit=False,
        cv=KFold(5, shuffle=True, random_state=seed), error_score=-np.inf,
    ).fit(X)
    results = search.cv_results_
    params = results["params"]
    truth = {name: np.empty(len(params)) for name in horizons}
    for i, p in enumerate(params):
        model = pipe.set_params(**p).fit(X)[-1]
        for name, (t, reference) in references.items():
            truth[name][i] = true_errors(system, model, x0, t, reference)

    picks = {}
    for score in scoring:
        picks[score] = int(np.nanargmax(results[f"mean_test_{score}"]))
        rule = one_standard_error_rule(pipe, n_states=2, metric=score)
        picks[score + " +1SE"] = rule(results)
    ratios = {
        name: {k: truth[name][i] / truth[name].min() for k, i in picks.items()}
        for name in horizons
    }
    best = {name: params[int(np.argmin(truth[name]))] for name in horizons}
    return ratios, {k: params[i] for k, i in picks.items()}, best


def henon_heiles_table(dt, noise, seed, degrees=range(1, 9)):
    """The one-standard-error rule on the paper's Henon-Heiles set-up, degree by degree."""
    system = henon_heiles()
    X = make_trajectories(system, 500, 2, dt, noise=noise, random_state=seed)
    pipe = make_pipeline(
        DerivativeTransformer(dt=dt, method="finite_difference"), HamiltonianRegressor()
    )
    key = "hamiltonianregressor__degree"
    search = GridSearchCV(
        pipe, {key: list(degrees)}, cv=5, refit=one_standard_error_rule(pipe, n_states=4)
    ).fit(X)
    results = search.cv_results_
    t = dt * np.arange(int(round(LONG_HORIZON / dt)) + 1)
    truth = system.solve(system.initial_state, t, max_step=min(dt, 0.01) / 10)[-1]
    print(
        f"\nHenon-Heiles, finite differences, M=500, J=2, dt={dt:g}, noise={noise:.0%}, "
        f"seed {seed}, 5-fold CV\n{'n':>3s}{'terms':>7s}{'1 - score':>12s}{'SE':>10s}"
        f"{'error at T=20 from u0*':>25s}"
    )
    for i, p in enumerate(results["params"]):
        model = clone(pipe).set_params(**p).fit(X)[-1]
        try:
            end = model.simulate(system.initial_state, t)[-1]
            error = f"{np.linalg.norm(end - truth) / np.linalg.norm(truth):25.2e}"
        except SimulationError:
            error = f"{'blew up':>25s}"
        print(
            f"{p[key]:3d}{model.n_terms_:7d}{1 - results['mean_test_score'][i]:12.3e}"
            f"{results['std_test_score'][i] / np.sqrt(5):10.1e}{error}"
        )
    best = results["params"][int(np.argmax(results["mean_test_score"]))][key]
    print(f"best mean score: n={best}; one-standard-error rule: n={search.best_params_[key]}")


def short(p):
    return f"Q={p['derivativetransformer__degree']},n={p['hamiltonianregressor__degree']}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--settings", nargs="+", default=list(SETTINGS), choices=list(SETTINGS))
    parser.add_argument(
        "--seeds", type=int, default=None, help="seeds per setting (default 3; 1 with --quick)"
    )
    parser.add_argument("--trajectories", type=int, default=500, help="M (default 500)")
    parser.add_argument("--steps", type=int, default=5, help="k of the k-step score (default 5)")
    parser.add_argument(
        "--quick", action="store_true",
        help="Morse only, on the coarse grid of tests/test_model_selection.py",
    )
    parser.add_argument(
        "--henon-heiles", nargs=2, type=float, metavar=("DT", "NOISE"),
        help="instead, tabulate the one-standard-error rule on Henon-Heiles (n = 1..8)",
    )
    args = parser.parse_args()
    if args.henon_heiles:
        warnings.simplefilter("ignore")
        for seed in range(args.seeds):
            henon_heiles_table(*args.henon_heiles, seed)
        return
    Qs, ns = list(range(1, 13)), list(range(3, 8))
    if args.seeds is None:
        args.seeds = 1 if args.quick else 3
    if args.quick:
        args.settings = ["morse"]
        Qs, ns = [2, 4, 6, 8, 10, 12], [3, 5, 7]
    warnings.simplefilter("ignore")  # domain and conditioning warnings of poor candidates
    print(f"grid Q={Qs}, n={ns}; M={args.trajectories}, 5-fold CV, k={args.steps}")
    for setting in args.settings:
        rows = {}
        for seed in range(args.seeds):
            start = time.perf_counter()
            ratios, picks, best = run_one(
                setting, seed, Qs, ns, args.trajectories, args.steps
            )
            print(
                f"  {setting} seed {seed} ({time.perf_counter() - start:.0f} s): best "
                f"{short(best['window'])} (window), {short(best['T=20'])} (T=20); picks "
                + ", ".join(
                    f"{k}: {short(p)} ({ratios['window'][k]:.2f}/{ratios['T=20'][k]:.2f})"
                    for k, p in picks.items()
                ),
                flush=True,
            )
            for horizon, values in ratios.items():
                for score, ratio in values.items():
                    rows.setdefault(score, {}).setdefault(horizon, []).append(ratio)
        config = SETTINGS[setting]
        print(
            f"\n{setting}: dt={config['dt']}, J={config['n_intervals']}, "
            f"noise={config['noise']:.0%}; true error of the pick / best on the grid"
        )
        header = f"{'score':22s}" + "".join(
            f"{h + ' gmean':>14s}{'worst':>8s}{'<=1.5x':>8s}" for h in ("window", "T=20")
        )
        print(header)
        for score, by_horizon in rows.items():
            line = f"{score:22s}"
            for horizon in ("window", "T=20"):
                r = np.array(by_horizon[horizon])
                line += f"{np.exp(np.log(r).mean()):14.2f}{r.max():8.2f}{np.mean(r <= 1.5):8.0%}"
            print(line)
        print()


if __name__ == "__main__":
    main()
