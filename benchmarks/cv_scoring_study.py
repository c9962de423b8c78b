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

``--folds [K ...]`` instead compares the number of folds (default 3, 5 and
10) and the refit rule (best mean score, or the one-standard-error rule) with
the default score, as ``sk-hamiltonian`` searches: shuffled folds of whole
trajectories, the same fold seed as the data seed. Scenes: the Morse
oscillator with 120 trajectories of 41 samples (``dt = 0.1``) at 5 % and
10 % noise over ``Q = 1..12`` by ``n = 3..7``; the paper's noisy pendulum
(Example 1: ``dt = 0.01``, ``J = 40``, 8 % noise, ``M = 500``, or
``--pendulum-trajectories``) over the command's default grid (finite
differences or ``Q = 3, 5, 8``, by ``n = 4, 6, 8, 10``). Per scene it prints
each seed's picks, then per ``(K, rule)`` the same ratios as above, the mean
degree ``n`` of the picks and the wall time of one search (all candidates, all
folds; the two rules share it). Five seeds (``--seeds``, from
``--first-seed``); ``--folds --quick`` runs the 10 % Morse scene on the
test's coarse grid and the pendulum with ``M = 200`` over finite differences
or ``Q = 3`` by ``n = 6, 8, 10``, two seeds.

``--scores [SCENE ...]`` instead compares candidate default scores (the
turn-1 relative error, rollouts from the first observation, shooting from a
least-squares initial state, per-trajectory scale-free weighting about the
centre of the training box, root-mean-square over trajectories, energy
consistency of ``H~``) from the same fits (``--cv`` folds, 10 by default,
``--seeds`` data seeds, 10 by default), judged by the true error from 100
states drawn in the data's own box up to ``T = 3``, relative and
origin-free. Scenes: the Morse oscillator at 5 % and 10 % noise, the
paper's noisy pendulum, and two coupled Morse oscillators (``morse-pair-5%``,
4-D, bound: every energy of its box is below dissociation). Other
aggregations of the same per-trajectory errors (the root-mean-square of the
errors in excess of the noise floor, the median, ...) are candidates too.
``--dump DIR`` also pickles each fold's per-trajectory errors and the true
errors, and ``--reaggregate FILE ...`` judges every candidate again from
them (and the one-standard-error rule on four of them) without refitting.

``--pendulum-threshold`` searches the sparsity threshold on the
paper's noisy pendulum and prints every threshold's mean score, standard
error and paired difference to the dense fit, for the new, the old default,
the turn-1 relative and two root-mean-square scores (all from the same
fits), and the true error at ``T = 20`` from ``u0*`` and its median over 20
fresh states. These modes read private functions of
``sk_hamiltonian._scoring`` to compute the candidates that are not the
default.
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
from sk_hamiltonian.datasets import (
    HamiltonianSystem,
    henon_heiles,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian._scoring import (
    multistep_errors,
    noise_floor,
    scaled_difference,
    shooting_errors,
)
from sk_hamiltonian.model_selection import (
    candidate_table,
    multistep_scorer,
    one_standard_error_rule,
)

N_FRESH = 100
LONG_HORIZON = 20.0
# Output spacing of the long-horizon comparison, and the integration steps of
# the learned and true systems there: far finer than any learning error (RK4
# steps of 0.025 instead of 0.01 changed the true errors of a Morse and a
# pendulum model at T = 20 by less than 2e-6 relative, at 2.5x less time).
LONG_SPACING = 0.1
MODEL_STEP = 0.025
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


def morse_pair(coupling=0.2):
    """Two Morse oscillators coupled by a spring: bound, non-polynomial, 4-D.

    ``H = (p1**2 + p2**2) / 2 + V(q1) + V(q2) + coupling (q1 - q2)**2 / 2``
    with ``V(q) = (1 - exp(-q))**2``. Every energy in the domain is at most
    ``0.25 + 2 V(0.7) + 0.1 = 0.86``, below the dissociation energy 1 of
    either oscillator (the coupling energy is never negative), so no orbit
    escapes.
    """

    def V(q):
        return (1.0 - np.exp(-q)) ** 2

    def dV(q):
        e = np.exp(-q)
        return 2.0 * e * (1.0 - e)

    def hamiltonian(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        return 0.5 * (p1**2 + p2**2) + V(q1) + V(q2) + 0.5 * coupling * (q1 - q2) ** 2

    def gradient(X):
        p1, p2, q1, q2 = np.moveaxis(X, -1, 0)
        spring = coupling * (q1 - q2)
        return np.stack([p1, p2, dV(q1) + spring, dV(q2) - spring], axis=-1)

    return HamiltonianSystem(
        "morse_pair", hamiltonian, gradient,
        domain=[[-0.5, 0.5], [-0.5, 0.5], [-0.3, 0.7], [-0.3, 0.7]],
        initial_state=[0.2, -0.1, 0.1, 0.3], params=dict(coupling=coupling),
    )


def derivative_r2(estimator, X, y=None):
    """PySINDy's score: R² against the smoother's own held-out derivatives."""
    data = unpack_derivatives(estimator[:-1].transform(X))
    states = data.states.reshape(-1, data.states.shape[-1])
    return r2_score(data.derivatives.reshape(states.shape), estimator[-1].predict(states))


def rollout_score(estimator, X, y=None):
    return estimator.score(X)


def true_errors(model, x0, t, reference):
    """Mean relative error of the learned system from ``x0``; failures count 1.

    Per initial state, ``||X_hat - X||_F / ||X||_F`` over the whole time grid
    (Frobenius norms), capped at 1; a simulation that fails (NaN from
    ``on_failure="nan"``) counts 1.
    """
    Y = model.simulate(x0, t, method="rk4", max_step=MODEL_STEP, on_failure="nan")
    errors = np.linalg.norm(Y - reference, axis=(1, 2)) / np.linalg.norm(reference, axis=(1, 2))
    return float(np.mean(np.where(np.isnan(errors), 1.0, np.minimum(errors, 1.0))))


def fresh_references(system, J, dt, seed):
    """Fresh initial states in the domain and the true solutions from them.

    Returns ``x0`` and, per horizon (``"window"``: the training window ``J dt``
    at the sampling step; ``"T=20"``), the output times and true solutions.
    """
    rng = np.random.default_rng(1000 + seed)
    x0 = rng.uniform(system.domain[:, 0], system.domain[:, 1], size=(N_FRESH, 2))
    references = {}
    for name, (T, spacing) in {"window": (J * dt, dt), "T=20": (LONG_HORIZON, LONG_SPACING)}.items():
        t = spacing * np.arange(int(round(T / spacing)) + 1)
        references[name] = (t, system.solve(x0, t, max_step=REFERENCE_STEP))
    return x0, references


def grid_truth(pipe, params, X, x0, references):
    """True errors of every grid pair refitted on all of ``X``, per horizon."""
    truth = {name: np.empty(len(params)) for name in references}
    for i, p in enumerate(params):
        model = clone(pipe).set_params(**p).fit(X)[-1]
        for name, (t, reference) in references.items():
            truth[name][i] = true_errors(model, x0, t, reference)
    return truth


SETTINGS = {
    "morse": dict(system=morse_oscillator, dt=0.1, n_intervals=40, noise=0.10),
    "pendulum": dict(system=single_pendulum, dt=0.01, n_intervals=40, noise=0.08),
}


def run_one(setting, seed, Qs, ns, n_trajectories, n_steps):
    config = SETTINGS[setting]
    system, dt, J = config["system"](), config["dt"], config["n_intervals"]
    X = make_trajectories(system, n_trajectories, J, dt, noise=config["noise"], random_state=seed)
    x0, references = fresh_references(system, J, dt, seed)
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
    truth = grid_truth(pipe, params, X, x0, references)

    picks = {}
    for score in scoring:
        picks[score] = int(np.nanargmax(results[f"mean_test_{score}"]))
        rule = one_standard_error_rule(pipe, n_states=2, metric=score)
        picks[score + " +1SE"] = rule(results)
    ratios = {
        name: {k: truth[name][i] / truth[name].min() for k, i in picks.items()}
        for name in references
    }
    best = {name: params[int(np.argmin(truth[name]))] for name in references}
    return ratios, {k: params[i] for k, i in picks.items()}, best


# The number of folds and the refit rule (``--folds``). Morse: the scenes of
# issue 11 (120 trajectories of 41 samples); pendulum: the paper's Example 1,
# searched over the default grid of the ``sk-hamiltonian`` command.
Q_KEY, N_KEY = "derivativetransformer__degree", "hamiltonianregressor__degree"
METHOD_KEY = "derivativetransformer__method"
FOLD_SCENES = {
    "morse-5%": dict(system=morse_oscillator, dt=0.1, n_intervals=40, noise=0.05, M=120),
    "morse-10%": dict(system=morse_oscillator, dt=0.1, n_intervals=40, noise=0.10, M=120),
    "pendulum-8%": dict(system=single_pendulum, dt=0.01, n_intervals=40, noise=0.08, M=500),
}
FOLD_GRIDS = {
    "morse": [{Q_KEY: list(range(1, 13)), N_KEY: [3, 4, 5, 6, 7]}],
    # sk-hamiltonian's default grid: finite differences or Q = 3, 5, 8, by n.
    "pendulum": [
        {METHOD_KEY: ["finite_difference"], N_KEY: [4, 6, 8, 10]},
        {METHOD_KEY: ["polynomial"], Q_KEY: [3, 5, 8], N_KEY: [4, 6, 8, 10]},
    ],
}
QUICK_FOLD_GRIDS = {
    "morse": [{Q_KEY: [2, 4, 6, 8, 10, 12], N_KEY: [3, 5, 7]}],
    "pendulum": [
        {METHOD_KEY: ["finite_difference"], N_KEY: [6, 8, 10]},
        {METHOD_KEY: ["polynomial"], Q_KEY: [3], N_KEY: [6, 8, 10]},
    ],
}
FOLD_RULES = ("best mean", "1SE")


def folds_one(scene, seed, folds, grid, n_trajectories):
    """Pick with every number of folds and both refit rules; judge by the truth.

    Returns, per ``(k, rule)``, the ratios of the pick's true error to the
    best on the grid (per horizon) and the pick's degree ``n``; the CV wall
    time per ``k``; and the best pairs per horizon.
    """
    config = FOLD_SCENES[scene]
    system, dt, J = config["system"](), config["dt"], config["n_intervals"]
    X = make_trajectories(system, n_trajectories, J, dt, noise=config["noise"], random_state=seed)
    x0, references = fresh_references(system, J, dt, seed)
    pipe = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())
    picks, seconds, params = {}, {}, None
    for k in folds:
        # As the command does: shuffled folds of whole trajectories, the
        # default (rollout) score, a failed fit scoring NaN.
        search = GridSearchCV(pipe, grid, cv=KFold(k, shuffle=True, random_state=seed), refit=False)
        start = time.perf_counter()
        search.fit(X)
        seconds[k] = time.perf_counter() - start
        results = search.cv_results_
        params = results["params"]
        picks[k, "best mean"] = int(np.nanargmax(results["mean_test_score"]))
        picks[k, "1SE"] = one_standard_error_rule(pipe, n_states=2)(results)
    truth = grid_truth(pipe, params, X, x0, references)
    ratios = {
        key: ({name: truth[name][i] / truth[name].min() for name in references},
              params[i][N_KEY])
        for key, i in picks.items()
    }
    best = {name: params[int(np.argmin(truth[name]))] for name in references}
    return ratios, seconds, best, {key: params[i] for key, i in picks.items()}


def folds_study(scenes, seeds, folds, quick, pendulum_trajectories):
    """Tabulate ``folds_one`` over the data seeds ``seeds`` (a range), per scene."""
    grids = QUICK_FOLD_GRIDS if quick else FOLD_GRIDS
    for scene in scenes:
        config = FOLD_SCENES[scene]
        kind = scene.split("-")[0]
        M = pendulum_trajectories if kind == "pendulum" else config["M"]
        grid = grids[kind]
        n_candidates = sum(int(np.prod([len(v) for v in g.values()])) for g in grid)
        print(
            f"\n{scene}: dt={config['dt']}, J={config['n_intervals']}, M={M}, "
            f"{n_candidates} candidates, seeds {seeds[0]}-{seeds[-1]}",
            flush=True,
        )
        ratios, times, degrees = {}, {}, {}
        for seed in seeds:
            start = time.perf_counter()
            seed_ratios, seconds, best, picks = folds_one(scene, seed, folds, grid, M)
            print(
                f"  seed {seed} ({time.perf_counter() - start:.0f} s): best {short(best['window'])}"
                f" (window), {short(best['T=20'])} (T=20); "
                + ", ".join(
                    f"{k}/{rule}: {short(picks[k, rule])} "
                    f"({seed_ratios[k, rule][0]['window']:.2f}/"
                    f"{seed_ratios[k, rule][0]['T=20']:.2f})"
                    for k in folds for rule in FOLD_RULES
                ),
                flush=True,
            )
            for key, (by_horizon, n) in seed_ratios.items():
                for horizon, r in by_horizon.items():
                    ratios.setdefault(key, {}).setdefault(horizon, []).append(r)
                degrees.setdefault(key, []).append(n)
            for k, s in seconds.items():
                times.setdefault(k, []).append(s)
        print(
            f"{scene}: true error of the pick / best on the grid over {len(seeds)} seeds; "
            f"CV wall time per seed"
        )
        print(
            f"{'folds':>5s}  {'refit':10s}"
            + "".join(f"{h + ' gmean':>14s}{'worst':>8s}{'<=1.5x':>8s}" for h in ("window", "T=20"))
            + f"{'mean n':>8s}{'CV time':>9s}"
        )
        for k in folds:
            for rule in FOLD_RULES:
                line = f"{k:5d}  {rule:10s}"
                for horizon in ("window", "T=20"):
                    r = np.array(ratios[k, rule][horizon])
                    line += f"{np.exp(np.log(r).mean()):14.2f}{r.max():8.2f}{np.mean(r <= 1.5):8.0%}"
                line += f"{np.mean(degrees[k, rule]):8.1f}{np.mean(times[k]):8.1f}s"
                print(line, flush=True)


# --------------------------------------------------------------------------
# Candidate scores (``--scores``): which held-out comparison chooses best?
# Every candidate is computed from the same fits and the same rollouts (one
# multi-metric scorer), then the picks are judged against the true system.


def _errors_table(model, Xt):
    """Per-trajectory quantities every candidate score is made of (shared rollouts)."""
    data = unpack_derivatives(Xt)
    observed = list(data.observed)
    shot, (Y, failed) = shooting_errors(model, Xt, return_first=True)
    # From the first observation: the origin-free error (today's default
    # score, in units of the training spread) and the relative error of the
    # turn-1 score, ||X_hat - X|| / ||X|| about the origin; and each
    # trajectory's size about the centre of the training box, for the
    # origin-free relative variants.
    center = model.domain_.mean(axis=1)
    first, rel0, size_c = [], [], []
    for k, O in enumerate(observed):
        if failed[k]:
            first.append(np.inf)
            rel0.append(np.inf)
        else:
            first.append(np.sqrt(np.mean(scaled_difference(model, Y[k], O) ** 2)))
            rel0.append(np.linalg.norm(Y[k] - O) / np.linalg.norm(O))
        scaled = model._space.wrap_difference(O - center) / model.state_scale_
        size_c.append(np.sqrt(np.mean(scaled**2)))
    # Energy consistency: the spread of H~ along the observations, in units of
    # the state error it corresponds to.
    energy = []
    for O in observed:
        H = model.hamiltonian(O)
        G = model.gradient(O) * model.state_scale_
        energy.append(np.std(H) / np.sqrt(np.mean(np.sum(G**2, axis=1))))
    # Shooting with the initial state fitted to the first SHORT_FITS
    # intervals only: the rest of the window is then a forecast, which a
    # frequency error cannot hide in a shifted initial state.
    short = {
        f"shot{k}": shooting_errors(model, Xt, fit_intervals=k) for k in SHORT_FITS
    }
    return dict(
        first=np.array(first), shot=shot, floor=noise_floor(model, Xt), rel0=np.array(rel0),
        size_c=np.array(size_c), energy=np.array(energy), **short,
    )


SHORT_FITS = (5, 10, 20)


def _capped(e):
    return 1.0 - float(np.mean(np.minimum(e, 1.0)))


def _rms_finished(e):
    """A failed rollout costs 1, as in the mean; the finished ones count by their RMS.

    ``1 - (share failed + share finished * RMS of the finished, capped at 1)``:
    the root-mean-square weights the large errors (where models differ) more
    than the mean does, while one failure moves the score by ``1 / n`` only,
    as in the mean form, instead of ``sqrt(1 / n)``.
    """
    c = np.minimum(e, 1.0)
    done = np.isfinite(e)
    if not done.any():
        return 0.0
    share = done.mean()
    return 1.0 - float((1.0 - share) + share * np.sqrt(np.mean(c[done] ** 2)))


def _trimmed_mean(x, share):
    """Mean of ``x`` without its ``share`` smallest and ``share`` largest values."""
    x = np.sort(x)
    cut = int(share * x.size)
    return float(np.mean(x[cut : x.size - cut]))


# Raw per-trajectory quantities of every scored fold, for aggregations
# computed after the run (``--dump``); off unless a list is put here.
RECORD = None


def candidate_scores(estimator, X, y=None):
    """All candidate scores of one fitted pipeline on held-out ``X`` (a dict)."""
    model, Xt = estimator[-1], estimator[:-1].transform(X)
    e = _errors_table(model, Xt)
    if RECORD is not None:
        params = estimator.get_params()
        RECORD.append(dict(
            params={k: params[k] for k in (METHOD_KEY, Q_KEY, N_KEY)},
            fold=float(np.asarray(X[0])[0, 0]), **e,
        ))
    return aggregate(e)


def aggregate(e):
    """Every candidate score from the per-trajectory table of ``_errors_table``."""
    shot, floor = e["shot"], e["floor"]
    c = np.minimum(shot, 1.0)
    return {
        "relative (turn 1)": _capped(e["rel0"]),
        "default (first obs)": _capped(e["first"]),
        "first obs, about mean": _capped(e["first"] / e["size_c"]),
        "shooting": _capped(shot),
        "shooting, about mean": _capped(shot / e["size_c"]),
        "shooting, pooled": 1.0 - float(np.sqrt(np.mean(c**2))),
        "shooting - floor": _capped(shot) + float(np.mean(floor)),
        "RMS finished, fail 1": _rms_finished(shot),
        "RMS of excess": 1.0 - float(np.sqrt(np.mean(np.maximum(c**2 - floor**2, 0.0)))),
        "mean square excess": 1.0 - float(np.mean(c**2 - floor**2)),
        "median - floor": 1.0 - float(np.median(c - floor)),
        "trimmed (10 %) - floor": 1.0 - _trimmed_mean(c - floor, 0.1),
        "mean of excess/floor": 1.0 - float(np.mean(np.minimum(
            np.maximum(c - floor, 0.0) / np.maximum(floor, 1e-12), 1e3))),
        "energy": _capped(e["energy"]),
        **{
            f"shooting on {k} - floor": _capped(e[f"shot{k}"]) + float(np.mean(floor))
            for k in SHORT_FITS if f"shot{k}" in e
        },
    }


SCORE_SCENES = {
    "morse-5%": dict(system=morse_oscillator, dt=0.1, n_intervals=40, noise=0.05, M=120,
                     grid=[{Q_KEY: list(range(1, 13)), N_KEY: [3, 4, 5, 6, 7]}]),
    "morse-10%": dict(system=morse_oscillator, dt=0.1, n_intervals=40, noise=0.10, M=120,
                      grid=[{Q_KEY: [3, 6, 9, 12], N_KEY: [4, 5, 6, 7]}]),
    "pendulum-8%": dict(system=single_pendulum, dt=0.01, n_intervals=40, noise=0.08, M=200,
                        grid=[{METHOD_KEY: ["finite_difference"], N_KEY: [6, 8, 10]},
                              {METHOD_KEY: ["polynomial"], Q_KEY: [3, 5, 8], N_KEY: [6, 8, 10]}]),
    # Henon-Heiles escapes from parts of the data's box: its test states are
    # noise-free states of the data instead. (Did not run: some orbits from
    # the paper's box [-1, 1]**4 escape, and the truth blows up before T = 3.)
    "henon-heiles-2%": dict(system=henon_heiles, dt=0.05, n_intervals=20, noise=0.02, M=200,
                            grid=[{Q_KEY: [3, 5, 8], N_KEY: [3, 4, 5, 6]}], bounded=True),
    # Bound Henon-Heiles: initial states in [-0.25, 0.25]**4, where every
    # energy is at most 2 * 0.25**2 + 4 * 0.25**3 / 3 = 0.146, below the
    # escape energy 1/6; test states are drawn in the data's box and kept
    # below the data's largest energy (rejection), so no orbit escapes.
    # Two coupled Morse oscillators (4-D, not a polynomial): test states in
    # the data's box, kept below the data's largest energy (< 1, so bound).
    "morse-pair-5%": dict(
        system=morse_pair, dt=0.1, n_intervals=30, noise=0.05, M=120, energy_capped=True,
        grid=[{Q_KEY: [2, 4, 6, 8, 10], N_KEY: [3, 4, 5, 6]}],
    ),
    "henon-heiles-low-5%": dict(
        system=henon_heiles, dt=0.1, n_intervals=30, noise=0.05, M=120,
        domain=[[-0.25, 0.25]] * 4, energy_capped=True,
        grid=[{Q_KEY: [2, 4, 6, 8, 10], N_KEY: [3, 4, 5, 6]}],
    ),
}
BOX_HORIZON = 3.0


def box_truth(pipe, params, X, system, dt, seed, clean=None, max_energy=None):
    """True errors from states drawn in the data's own box, to ``T = 3``.

    Two measures per grid pair, mean over 100 states (capped at 1, failures
    1): the relative error ``||X_hat - X||_F / ||X||_F`` (about the origin)
    and the origin-free one, RMS of the error over the data's standard
    deviation per variable.
    """
    states = np.concatenate([np.asarray(T) for T in X])
    rng = np.random.default_rng(2000 + seed)
    if clean is None and max_energy is not None:
        # Uniform in the box, kept below the data's largest true energy.
        kept = np.empty((0, states.shape[1]))
        while kept.shape[0] < N_FRESH:
            draw = rng.uniform(states.min(axis=0), states.max(axis=0), size=(N_FRESH, states.shape[1]))
            kept = np.concatenate([kept, draw[system.hamiltonian(draw) <= max_energy]])
        x0 = kept[:N_FRESH]
    elif clean is None:
        x0 = rng.uniform(states.min(axis=0), states.max(axis=0), size=(N_FRESH, states.shape[1]))
    else:
        # Scenes whose orbits escape from parts of the box: noise-free states
        # of the data, drawn at random.
        pool = np.concatenate(list(clean))
        x0 = pool[rng.choice(pool.shape[0], N_FRESH, replace=False)]
    t = dt * np.arange(int(round(BOX_HORIZON / dt)) + 1)
    reference = system.solve(x0, t, max_step=REFERENCE_STEP)
    spread = states.std(axis=0)
    truth = {"relative": np.empty(len(params)), "origin-free": np.empty(len(params))}
    for i, p in enumerate(params):
        model = clone(pipe).set_params(**p).fit(X)[-1]
        Y = model.simulate(x0, t, method="rk4", max_step=MODEL_STEP, on_failure="nan")
        rel = np.linalg.norm(Y - reference, axis=(1, 2)) / np.linalg.norm(reference, axis=(1, 2))
        free = np.sqrt(np.mean(((Y - reference) / spread) ** 2, axis=(1, 2)))
        for name, e in (("relative", rel), ("origin-free", free)):
            truth[name][i] = float(np.mean(np.where(np.isnan(e), 1.0, np.minimum(e, 1.0))))
    return truth


def scene_data(scene, seed):
    """A scene's system and its noisy and noise-free trajectories for one data seed."""
    config = SCORE_SCENES[scene]
    system = config["system"]()
    X, clean = make_trajectories(
        system, config["M"], config["n_intervals"], config["dt"], noise=config["noise"],
        random_state=seed, return_clean=True, domain=config.get("domain"),
    )
    return system, X, clean


def largest_energy(system, clean):
    """The largest true energy along the noise-free trajectories."""
    return float(max(system.hamiltonian(np.asarray(C)).max() for C in clean))


def dump_name(path):
    """``(scene, seed)`` of a file written by ``--dump``."""
    import os
    import re

    name = os.path.basename(path)
    match = re.fullmatch(r"(.+)-seed(\d+)-cv\d+\.pkl", name)
    return match.group(1), int(match.group(2))


def scores_one(scene, seed, folds, dump=None):
    """Pick with every candidate score (best mean) on one data seed; judge by the truth.

    With ``dump`` (a directory), the per-trajectory errors of every scored
    fold and the true errors are pickled there, one file per scene and seed,
    so that other aggregations can be judged without refitting
    (``--reaggregate``).
    """
    global RECORD
    config = SCORE_SCENES[scene]
    dt = config["dt"]
    system, X, clean = scene_data(scene, seed)
    RECORD = [] if dump else None
    pipe = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())
    search = GridSearchCV(
        pipe, config["grid"], scoring=candidate_scores, refit=False,
        cv=KFold(folds, shuffle=True, random_state=seed),
    )
    start = time.perf_counter()
    search.fit(X)
    seconds = time.perf_counter() - start
    results = search.cv_results_
    params = results["params"]
    max_energy = largest_energy(system, clean) if config.get("energy_capped") else None
    truth = box_truth(
        pipe, params, X, system, dt, seed, clean if config.get("bounded") else None, max_energy
    )
    if dump:
        import os
        import pickle

        os.makedirs(dump, exist_ok=True)
        with open(os.path.join(dump, f"{scene}-seed{seed}-cv{folds}.pkl"), "wb") as f:
            pickle.dump(dict(params=params, truth=truth, record=RECORD), f)
        RECORD = None
    names = [key[len("mean_test_"):] for key in results if key.startswith("mean_test_")]
    picks = {name: int(np.nanargmax(results[f"mean_test_{name}"])) for name in names}
    ratios = {
        name: {kind: truth[kind][i] / truth[kind].min() for kind in truth}
        for name, i in picks.items()
    }
    return ratios, {name: params[i] for name, i in picks.items()}, seconds


def rejudge(paths, out):
    """Add the true errors below the data's largest energy to ``--dump`` files.

    For each file (one scene and seed) the data are made again from the seed,
    every grid pair is refitted on all of them, and the two measures of
    :func:`box_truth` are computed again from 100 states drawn in the data's
    box and kept below the data's largest true energy, where the learned
    models are inside the data; they are stored as ``"relative, bound"`` and
    ``"origin-free, bound"`` beside the original ones, and the file is
    written to ``out``. (The plain box of the Morse scenes puts a fifth of its
    states above every energy of the data, some above dissociation; there
    the truth measures extrapolation, which no held-out score can see.)
    """
    import os
    import pickle

    os.makedirs(out, exist_ok=True)
    for path in sorted(paths):
        with open(path, "rb") as f:
            run = pickle.load(f)
        scene, seed = dump_name(path)
        config = SCORE_SCENES[scene]
        start = time.perf_counter()
        if config.get("energy_capped") or config.get("bounded"):
            bound = run["truth"]  # drawn inside the data's energies already
        else:
            system, X, clean = scene_data(scene, seed)
            dt = config["dt"]
            pipe = make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())
            bound = box_truth(
                pipe, run["params"], X, system, dt, seed, None, largest_energy(system, clean)
            )
        for kind in ("relative", "origin-free"):
            run["truth"][f"{kind}, bound"] = bound[kind]
        with open(os.path.join(out, os.path.basename(path)), "wb") as f:
            pickle.dump(run, f)
        print(f"{os.path.basename(path)}: {time.perf_counter() - start:.0f} s", flush=True)


def scores_study(scenes, seeds, folds, dump=None):
    for scene in scenes:
        config = SCORE_SCENES[scene]
        print(
            f"\n{scene}: M={config['M']}, J={config['n_intervals']}, dt={config['dt']}, "
            f"{folds} folds, seeds {seeds[0]}-{seeds[-1]}", flush=True,
        )
        rows = {}
        for seed in seeds:
            start = time.perf_counter()
            ratios, picks, cv_seconds = scores_one(scene, seed, folds, dump)
            print(
                f"  seed {seed} ({time.perf_counter() - start:.0f} s, CV {cv_seconds:.0f} s): "
                + "; ".join(
                    f"{name}: {short(picks[name])} {r['relative']:.2f}/{r['origin-free']:.2f}"
                    for name, r in ratios.items()
                ),
                flush=True,
            )
            for name, r in ratios.items():
                for kind, value in r.items():
                    rows.setdefault(name, {}).setdefault(kind, []).append(value)
        print(
            f"{scene}: true error of the pick / best on the grid (states from the data's box, "
            f"T = {BOX_HORIZON:g}), {len(seeds)} seeds"
        )
        print(f"{'score':24s}" + "".join(
            f"{k + ' gmean':>19s}{'worst':>8s}" for k in ("relative", "origin-free")
        ))
        for name, by_kind in rows.items():
            line = f"{name:24s}"
            for kind in ("relative", "origin-free"):
                r = np.array(by_kind[kind])
                line += f"{np.exp(np.log(r).mean()):19.3f}{r.max():8.2f}"
            print(line, flush=True)


ONE_SE_SCORES = ("relative (turn 1)", "default (first obs)", "shooting - floor", "shooting, pooled")


def reaggregate(paths):
    """Judge every aggregation of ``aggregate`` from pickles written by ``--dump``.

    Per file (one scene and seed): each candidate's fold scores are
    recomputed from the recorded per-trajectory errors, the best mean picks,
    and the pick's true error over the grid's best is tabulated per scene, as
    ``--scores`` prints it. A candidate with a fold missing (a failed fit)
    is left out, as ``GridSearchCV`` leaves out its NaN mean.
    """
    import pickle

    rows = {}
    for path in sorted(paths):
        with open(path, "rb") as f:
            run = pickle.load(f)
        scene, _ = dump_name(path)
        folds = {}
        for r in run["record"]:
            i = next(i for i, p in enumerate(run["params"])
                     if all(r["params"][k] == v for k, v in p.items()))
            folds.setdefault(i, []).append(aggregate(r))
        n_folds = max(len(v) for v in folds.values())
        n_cand = len(run["params"])
        means, ses = {}, {}
        for i in range(n_cand):
            scored = folds.get(i, [])
            for name in (scored[0] if scored else {}):
                values = np.array([s[name] for s in scored])
                full = len(scored) == n_folds
                means.setdefault(name, np.full(n_cand, np.nan))[i] = values.mean() if full else np.nan
                ses.setdefault(name, np.full(n_cand, np.nan))[i] = values.std() / np.sqrt(n_folds)
        degrees = np.array([p[N_KEY] for p in run["params"]])
        picks = {}
        for name, m in means.items():
            picks[name] = int(np.nanargmax(m))
            if name in ONE_SE_SCORES:
                # The one-standard-error rule: the fewest terms (smallest n)
                # within one SE of the best mean, ties by the mean.
                best = picks[name]
                within = np.flatnonzero(m >= m[best] - ses[name][best])
                fewest = within[degrees[within] == degrees[within].min()]
                picks[name + " +1SE"] = int(fewest[np.argmax(m[fewest])])
        for name, i in picks.items():
            for kind, truth in run["truth"].items():
                rows.setdefault(scene, {}).setdefault(name, {}).setdefault(kind, []).append(
                    truth[i] / truth.min()
                )
    for scene, by_name in rows.items():
        n_seeds = len(next(iter(next(iter(by_name.values())).values())))
        kinds = list(next(iter(by_name.values())))
        print(f"\n{scene}: true error of the pick / best on the grid, {n_seeds} seeds")
        widths = [max(19, len(k) + 8) for k in kinds]
        print(f"{'score':24s}" + "".join(
            f"{k + ' gmean':>{w}s}{'worst':>8s}" for k, w in zip(kinds, widths)
        ))
        for name, by_kind in by_name.items():
            line = f"{name:24s}"
            for kind, w in zip(kinds, widths):
                r = np.array(by_kind[kind])
                line += f"{np.exp(np.log(r).mean()):{w}.3f}{r.max():8.2f}"
            print(line, flush=True)


# Scores tabulated by ``--pendulum-threshold`` (names of ``aggregate``).
THRESHOLD_SCORES = {
    "new": "shooting - floor",
    "old": "default (first obs)",
    "relative": "relative (turn 1)",
    "RMS": "shooting, pooled",
    "RMS excess": "RMS of excess",
    "MS excess": "mean square excess",
}
N_FRESH_PENDULUM = 20


def threshold_study(seed, folds=5):
    """The paper's noisy pendulum: GridSearchCV over the sparsity threshold.

    Example 1 data (``M = 500``, ``J = 40``, ``dt = 0.01``, 8 % noise), ``Q = 3``,
    the periodic mechanical space (``periodic=[False, True]``,
    ``momentum_degree=2``) of degree 8; thresholds 0 (dense, 44 terms) to 0.1.
    Prints each threshold's terms, the true error at ``T = 20`` from ``u0*``
    and its median over 20 fresh states (``_common.test_states``, as the
    benchmarks draw them), and per score of ``THRESHOLD_SCORES`` (all from
    the same fits): the mean score, its standard error and the paired
    difference to the dense fit with its standard error; then each score's
    pick against the grid's best by both true errors.
    """
    import _common

    system = single_pendulum()
    X = make_trajectories(system, 500, 40, 0.01, noise=0.08, random_state=seed)
    pipe = make_pipeline(
        DerivativeTransformer(dt=0.01, degree=3),
        HamiltonianRegressor(degree=8, periodic=[False, True], momentum_degree=2),
    )
    grid = {"hamiltonianregressor__threshold": [0.0, 1e-3, 1e-2, 3e-2, 0.1]}
    search = GridSearchCV(
        pipe, grid, scoring=candidate_scores, refit=False,
        cv=KFold(folds, shuffle=True, random_state=seed),
    ).fit(X)
    x0, t, truth = _common.test_states(system, N_FRESH_PENDULUM, LONG_HORIZON, 0.01, seed=seed + 1)
    end = truth[:, -1]
    tables = {
        label: candidate_table(search, metric=name) for label, name in THRESHOLD_SCORES.items()
    }
    print(
        f"\nnoisy pendulum, seed {seed}, {folds} folds: threshold, terms, error at T=20 from u0*"
        f" and median over {x0.shape[0] - 1} fresh states; per score: mean, SE, paired"
        f" difference to the dense fit +- its SE"
    )
    errors, medians = [], []
    for i, p in enumerate(search.cv_results_["params"]):
        model = clone(pipe).set_params(**p).fit(X)[-1]
        Y = model.simulate(x0, t, on_failure="nan")[:, -1]
        e = np.linalg.norm(Y - end, axis=1) / np.linalg.norm(end, axis=1)
        e = np.where(np.isnan(e), np.inf, e)
        errors.append(e[0])
        medians.append(float(np.median(e[1:])))
        line = (f"{p['hamiltonianregressor__threshold']:8g}{model.n_terms_:6d}"
                f"{errors[-1]:9.3f}{medians[-1]:9.3f}")
        for label, table in tables.items():
            name = THRESHOLD_SCORES[label]
            folds_m = np.column_stack(
                [search.cv_results_[f"split{k}_test_{name}"] for k in range(folds)]
            )
            diff = folds_m[i] - folds_m[0]
            line += (
                f"  {label}: {table['mean'][i]:.6f} +- {table['se'][i]:.6f}"
                f" ({diff.mean():+.6f} +- {diff.std() / np.sqrt(folds):.6f})"
                + (" tied" if table["tied"][i] else "")
            )
        print(line, flush=True)
    errors, medians = np.array(errors), np.array(medians)
    for label, table in tables.items():
        pick = int(np.argmax(table["mean"]))
        print(f"  {label}: picks threshold "
              f"{search.cv_results_['params'][pick]['hamiltonianregressor__threshold']:g}, "
              f"u0* error {errors[pick]:.3f} = {errors[pick] / errors.min():.2f}x the grid's best,"
              f" median {medians[pick]:.3f} = {medians[pick] / medians.min():.2f}x", flush=True)


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
    if p.get(METHOD_KEY) == "finite_difference":
        return f"fd,n={p[N_KEY]}"
    return f"Q={p[Q_KEY]},n={p[N_KEY]}"


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
    parser.add_argument(
        "--folds", nargs="*", type=int, metavar="K",
        help="instead, compare K-fold CV (default 3 5 10) x {best mean score, "
        "one-standard-error rule} on the Morse and pendulum scenes (5 seeds; "
        "2 with --quick)",
    )
    parser.add_argument(
        "--scenes", nargs="+", choices=list(FOLD_SCENES), default=None,
        help="scenes of --folds (default: all; morse-10%% and pendulum-8%% with --quick)",
    )
    parser.add_argument(
        "--first-seed", type=int, default=0,
        help="first data seed of --folds (default 0): seeds run from it on",
    )
    parser.add_argument(
        "--pendulum-trajectories", type=int, default=None,
        help="M of the pendulum scene of --folds (default 500; 200 with --quick)",
    )
    parser.add_argument(
        "--scores", nargs="*", choices=list(SCORE_SCENES), metavar="SCENE",
        help="instead, compare candidate scores on these scenes (default: all)",
    )
    parser.add_argument("--cv", type=int, default=10, help="folds of --scores (default 10)")
    parser.add_argument(
        "--pendulum-threshold", action="store_true",
        help="instead, search the sparsity threshold on the paper's noisy pendulum",
    )
    parser.add_argument(
        "--dump", metavar="DIR", default=None,
        help="with --scores, also pickle every fold's per-trajectory errors and the true "
        "errors to DIR, one file per scene and seed",
    )
    parser.add_argument(
        "--reaggregate", nargs="+", metavar="PICKLE",
        help="instead, judge every candidate score again from files written by --dump",
    )
    parser.add_argument(
        "--rejudge", nargs="+", metavar="PICKLE",
        help="instead, add the true errors below the data's largest energy to files "
        "written by --dump, writing them to the --dump directory",
    )
    args = parser.parse_args()
    if args.rejudge:
        if args.dump is None:
            parser.error("--rejudge writes to the --dump directory: give --dump DIR")
        warnings.simplefilter("ignore")
        rejudge(args.rejudge, args.dump)
        return
    if args.reaggregate:
        reaggregate(args.reaggregate)
        return
    if args.pendulum_threshold:
        warnings.simplefilter("ignore")
        for seed in range(args.first_seed, args.first_seed + (args.seeds or 1)):
            threshold_study(seed)
        return
    if args.scores is not None:
        warnings.simplefilter("ignore")
        seeds = range(args.first_seed, args.first_seed + (args.seeds or 10))
        scores_study(args.scores or list(SCORE_SCENES), seeds, args.cv, args.dump)
        return
    if args.henon_heiles:
        warnings.simplefilter("ignore")
        for seed in range(args.seeds or 1):
            henon_heiles_table(*args.henon_heiles, seed)
        return
    if args.folds is not None:
        warnings.simplefilter("ignore")  # domain and conditioning warnings of poor candidates
        folds = args.folds or [3, 5, 10]
        scenes = args.scenes or (
            ["morse-10%", "pendulum-8%"] if args.quick else list(FOLD_SCENES)
        )
        seeds = range(args.first_seed, args.first_seed + (args.seeds or (2 if args.quick else 5)))
        M = args.pendulum_trajectories or (200 if args.quick else 500)
        print(f"folds {folds}, {'quick' if args.quick else 'full'} grids", flush=True)
        folds_study(scenes, seeds, folds, args.quick, M)
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
