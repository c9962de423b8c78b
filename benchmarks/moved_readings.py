"""Readings moved far off, which the spike screen misses at the ends of records.

The robustness study's pendulum (500 records of 41 samples, ``dt = 0.01``,
2 % additive noise; ``benchmarks/robustness_study.py``) with 1 % of its
samples moved by ``k`` noise levels (each variable's noise standard
deviation, a random sign per variable), ``k = 10`` and ``30``, seeds 0 to 3.
Per case: how many moved samples the search's preparation leaves out as
spikes, how many the trajectory fit leaves out (``refinement_["outliers"]``)
and how many other samples either leaves out; the error at ``T = 20`` of
the default search, of the same search with ``refine=None``, and of the
default search on the records before the readings were moved; and the
largest relative error of the two coefficients, in the same order. BLAS on
one thread::

    python benchmarks/moved_readings.py
    python benchmarks/moved_readings.py --seeds 0 --levels 30
"""

import argparse
import os
import sys
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from sk_hamiltonian.model_selection import HamiltonianSearchCV  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness_study import coefficient_error, model_error, scene_data  # noqa: E402

FRACTION = 0.01
NOISE = 0.02


def moved(X, level, seed):
    """``X`` with :data:`FRACTION` of its samples moved by ``level`` noise levels, and which."""
    rng = np.random.default_rng(1000 + seed)
    which = rng.random(X.shape[:2]) < FRACTION
    sd = NOISE * np.sqrt(np.mean(X.reshape(-1, X.shape[-1]) ** 2, axis=0))
    Y = X.copy()
    Y[which] += level * sd * rng.choice([-1.0, 1.0], size=(int(which.sum()), X.shape[-1]))
    return Y, which


def search(X, **params):
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return HamiltonianSearchCV(dt=0.01, **params).fit(X)


def marked(left_out, shape):
    """The samples of a ``{trajectory: sample indices}`` dict, as a boolean array."""
    flags = np.zeros(shape, dtype=bool)
    for k, samples in (left_out or {}).items():
        flags[k, samples] = True
    return flags


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3])
    parser.add_argument("--levels", nargs="+", type=float, default=[10.0, 30.0])
    args = parser.parse_args()
    for seed in args.seeds:
        _, _, X = scene_data("pendulum", "many", "add2", seed)
        unmoved = search(X).best_estimator_[-1]
        clean = model_error(unmoved, "pendulum", False)
        clean_coef = coefficient_error(unmoved, "pendulum")
        for level in args.levels:
            Y, which = moved(X, level, seed)
            default = search(Y)
            plain = search(Y, refine=None)
            screen = marked(default.preparation_["left_out"], which.shape)
            fit = marked(default.refinement_.get("outliers"), which.shape)
            errors = [model_error(s.best_estimator_[-1], "pendulum", False)
                      for s in (default, plain)]
            coefs = [coefficient_error(s.best_estimator_[-1], "pendulum") for s in (default, plain)]
            print(f"seed {seed}  moved by {level:g}  {which.sum()} moved: {np.sum(screen & which)} "
                  f"left out as spikes, {np.sum(fit & which)} by the trajectory fit, "
                  f"{np.sum(~which & (screen | fit))} others  error {errors[0]:.3g}  "
                  f"refine=None {errors[1]:.3g}  unmoved {clean:.3g}  coefficients "
                  f"{coefs[0]:.2g}, {coefs[1]:.2g}, {clean_coef:.2g}", flush=True)


if __name__ == "__main__":
    main()
