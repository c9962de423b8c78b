"""Two variants of the search's pick, tried on the study's data (docs/search_study.rst).

``--windows``
    The weak form's window: the search's default of 21 samples (stride 5)
    against one window of the whole 41-sample trajectory, for the weak fit at
    degree 4, threshold 0.01, in the scene's own space (the one the search
    keeps), de-noising ``Q = 8``. The window is a module constant of the
    package (``sk_hamiltonian._training_data.WEAK_WINDOW``), set here for the
    experiment only.
``--coefficients``
    The learned coefficients side by side: the package's fit targets (weak,
    Simpson, steps) on finite differences and on ``Q = 8``, in the scene's
    own space (degree 4, threshold 0.01), and PySINDy's weak form as the
    study cross-validates it (its nonzero coefficients, equation by equation).
``--vector-field``
    The same weak fit without the Hamiltonian's constraint: a
    ``VectorFieldRegressor`` (each equation its own coefficients, as PySINDy
    fits them) of degree 3, threshold 0.01, on finite differences and on
    ``Q = 8``.
``--reweight``
    Henon-Heiles' weak fit (``Q = 8``, degree 4, threshold 0.01, mechanical)
    with the ``dp2/dt`` rows weighted by ``a`` and the ``dq2/dt`` rows by
    ``1 / a``: fitted in the coordinates ``(p1, a p2, q1, q2 / a)``, a
    canonical rescaling in which the polynomial space is the same, and
    simulated there.
``--average``
    The finalists the cross-validation cannot tell apart (``tied`` in the
    search's ``cv_results_``), refitted on all the data, their vector fields
    averaged and integrated by RK4 (step 2e-3) to ``T``; its fresh-state
    error against the search's pick.

Both read the search's saved rows from ``search_study.py`` (run that first)
and judge by the same fresh states and error. Run::

    python benchmarks/search_study_variants.py --windows henon_heiles 1 2 3
    python benchmarks/search_study_variants.py --windows torsion_pendulum 0
    python benchmarks/search_study_variants.py --average pendulum 0 1 2 3 4 5 6 7 8 9
    python benchmarks/search_study_variants.py --average torsion_pendulum 0 1 2 3 4
"""

import argparse
import os
import pickle
import sys
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from sklearn.base import clone  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import search_study as study  # noqa: E402

import sk_hamiltonian._training_data as training_data  # noqa: E402

SPACES = {
    "pendulum": dict(momentum_degree=2, periodic=[False, True]),
    "henon_heiles": dict(momentum_degree=2),
    "torsion_pendulum": dict(momentum_degree=2, mixed=[False, True]),
    "double_well": dict(momentum_degree=2),
}


def windows(scene, seed):
    cfg, system, X, _ = study.scene_data(scene, seed)
    x0, truth = study.fresh_states(system, cfg["angles"])
    errors = {}
    default = training_data.WEAK_WINDOW, training_data.WEAK_OVERLAP
    try:
        for length, overlap in [default, (41, 1)]:
            training_data.WEAK_WINDOW, training_data.WEAK_OVERLAP = length, overlap
            model = study.pipeline(cfg["dt"]).set_params(
                derivativetransformer__method="polynomial", derivativetransformer__degree=8,
                hamiltonianregressor__degree=4, hamiltonianregressor__threshold=0.01,
                hamiltonianregressor__fit_on="weak",
                **{f"hamiltonianregressor__{k}": v for k, v in SPACES[scene].items()},
            ).fit(X)[-1]
            errors[f"window {length}"] = (study.model_error(model, x0, truth, cfg["angles"]),
                                          int(model.n_terms_))
    finally:
        training_data.WEAK_WINDOW, training_data.WEAK_OVERLAP = default
    return errors


def coefficients(scene, seed):
    from sindy_anchor import fit_sindy_cv

    from sk_hamiltonian.inspection import format_hamiltonian

    cfg, system, X, cv = study.scene_data(scene, seed)
    x0, truth = study.fresh_states(system, cfg["angles"])
    for Q in ("fd", 8):
        layout = (dict(derivativetransformer__method="finite_difference") if Q == "fd" else
                  dict(derivativetransformer__method="polynomial", derivativetransformer__degree=Q))
        for fit_on in ("weak", "simpson", "steps"):
            model = study.pipeline(cfg["dt"]).set_params(
                **layout, hamiltonianregressor__degree=4, hamiltonianregressor__threshold=0.01,
                hamiltonianregressor__fit_on=fit_on,
                **{f"hamiltonianregressor__{k}": v for k, v in SPACES[scene].items()},
            ).fit(X)[-1]
            error = study.model_error(model, x0, truth, cfg["angles"])
            print(f"Q={Q} {fit_on:8s} error {error:.4f}  {format_hamiltonian(model)}", flush=True)
    folds = [test for _, test in cv.split(X)]
    anchor = fit_sindy_cv(X, cfg["dt"], library=cfg["sindy"], folds=folds, weak=True, seed=seed)
    for i, j in zip(*np.nonzero(anchor.coef)):
        print(f"PySINDy weak: d x{i}/dt  {anchor.coef[i, j]:+.5f} {anchor.feature_names[j]}")


def vector_field(scene, seed):
    from sk_hamiltonian import VectorFieldRegressor

    cfg, system, X, _ = study.scene_data(scene, seed)
    x0, truth = study.fresh_states(system, cfg["angles"])
    errors = {}
    for Q in ("fd", 8):
        layout = (dict(derivativetransformer__method="finite_difference") if Q == "fd" else
                  dict(derivativetransformer__method="polynomial", derivativetransformer__degree=Q))
        pipe = study.pipeline(cfg["dt"]).set_params(**layout)
        pipe.steps[-1] = ("vectorfieldregressor",
                          VectorFieldRegressor(degree=3, threshold=0.01, fit_on="weak"))
        model = pipe.fit(X)[-1]
        errors[f"Q={Q}"] = (study.model_error(model, x0, truth, cfg["angles"]),
                            int(model.n_terms_))
    return errors


def reweight(scene, seed):
    if scene != "henon_heiles":
        raise SystemExit("--reweight is written for henon_heiles (p1, p2, q1, q2)")
    cfg, system, X, _ = study.scene_data(scene, seed)
    x0, truth = study.fresh_states(system, cfg["angles"])
    errors = {}
    for a in (1.0, 0.5, 0.25, 2.0):
        scale = np.array([1.0, a, 1.0, 1.0 / a])
        model = study.pipeline(cfg["dt"]).set_params(
            derivativetransformer__method="polynomial", derivativetransformer__degree=8,
            hamiltonianregressor__degree=4, hamiltonianregressor__momentum_degree=2,
            hamiltonianregressor__threshold=0.01, hamiltonianregressor__fit_on="weak",
        ).fit(X * scale)[-1]
        errors[f"a={a:g}"] = (study.fresh_error(
            lambda x: model.simulate(x * scale, [0.0, study.T_END], on_failure="nan")[:, -1]
            / scale, x0, truth, cfg["angles"]), int(model.n_terms_))
    return errors


def average(scene, seed, output):
    cfg, system, X, _ = study.scene_data(scene, seed)
    x0, truth = study.fresh_states(system, cfg["angles"])
    row = pickle.loads((output / f"{scene}_{seed}_search.pkl").read_bytes())
    results = row["cv_results"]
    tied = [i for i in row["finalist_errors"] if results["tied"][i]]
    models = [clone(study.pipeline(cfg["dt"])).set_params(**results["params"][i]).fit(X)[-1]
              for i in tied]

    def field(x):
        return np.mean([model.predict(x) for model in models], axis=0)

    h, x = 2e-3, x0.copy()
    for _ in range(int(round(study.T_END / h))):
        k1 = field(x)
        k2 = field(x + h / 2 * k1)
        k3 = field(x + h / 2 * k2)
        k4 = field(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    averaged = study.fresh_error(lambda _: x, x0, truth, cfg["angles"])
    return {"pick": row["error"], "average of the tied": averaged, "n_tied": len(tied)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    which = parser.add_mutually_exclusive_group(required=True)
    which.add_argument("--windows", action="store_true")
    which.add_argument("--average", action="store_true")
    which.add_argument("--coefficients", action="store_true")
    which.add_argument("--vector-field", action="store_true")
    which.add_argument("--reweight", action="store_true")
    parser.add_argument("scene", choices=list(study.SCENES))
    parser.add_argument("seeds", nargs="+", type=int)
    parser.add_argument("--output", type=Path, default=study.HERE / "results" / "search_study")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    ratios = []
    for seed in args.seeds:
        if args.windows:
            print(args.scene, seed, windows(args.scene, seed), flush=True)
        elif args.coefficients:
            coefficients(args.scene, seed)
        elif args.reweight:
            print(args.scene, seed, reweight(args.scene, seed), flush=True)
        elif args.vector_field:
            print(args.scene, seed, vector_field(args.scene, seed), flush=True)
        else:
            result = average(args.scene, seed, args.output)
            ratios.append(result["pick"] / result["average of the tied"])
            print(args.scene, seed, result, flush=True)
    if ratios:
        print(f"pick / average, geometric mean: {study.geometric_mean(ratios):.3f}")


if __name__ == "__main__":
    main()
