"""Few long records: the default search beside the same records cut by hand.

Before the search segmented long records itself, a user had to cut them:
``segment_trajectories(X, 200, n_groups=5)`` and ``GroupKFold(5)`` (blocked
folds of contiguous stretches). This script runs that route and the default
``HamiltonianSearchCV(dt=dt).fit(X)`` on the same records of the robustness
study (``robustness_study.py``: the pendulum as one record of 4 001 samples,
Henon-Heiles as three of 2 001, 2 % additive noise, seeds 0 to 4), and
measures both with its error (the median relative state error at ``T = 20``
from its fixed fresh states)::

    python benchmarks/hand_cut.py
    python benchmarks/hand_cut.py --scenes pendulum --seeds 0 --output rows

Rows are saved beside the robustness study's and reused (the default's rows
are the study's own ``search`` rows); CPU seconds, BLAS on one thread.
"""

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from sklearn.model_selection import GroupKFold  # noqa: E402

from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms  # noqa: E402
from sk_hamiltonian.model_selection import HamiltonianSearchCV, segment_trajectories  # noqa: E402
from robustness_study import case, compute, geometric_mean, model_error, scene_data  # noqa: E402

CASES = [("pendulum", "one", "add2"), ("henon_heiles", "three", "add2")]
SEGMENT = 200
N_FOLDS = 5


def run_hand_cut(name, shape, noise, seed):
    """The search on the records cut into segments of 200 samples, blocked folds."""
    cfg, _, X = scene_data(name, shape, noise, seed)
    segments, groups = segment_trajectories(X, SEGMENT, n_groups=N_FOLDS)
    start = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = HamiltonianSearchCV(dt=cfg["dt"], cv=GroupKFold(N_FOLDS)).fit(
            segments, groups=groups)
    seconds = time.process_time() - start
    model = search.best_estimator_[-1]
    kept = {term.text for term in hamiltonian_terms(model)}
    return dict(seconds=seconds, error=model_error(model, name, long=True),
                exact_support=kept == cfg["terms"], n_terms=int(model.n_terms_),
                formula=format_hamiltonian(model), refinement=search.refinement_["status"])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", nargs="+", default=[name for name, _, _ in CASES],
                        choices=[name for name, _, _ in CASES])
    parser.add_argument("--seeds", nargs="+", type=int, default=list(range(5)))
    parser.add_argument("--output", type=Path, default=HERE / "results" / "robustness_study")
    args = parser.parse_args(argv)
    args.output.mkdir(parents=True, exist_ok=True)
    print(f"{'scene':14s} {'records':8s} {'seed':>4s}  {'default':>9s} {'exact':>5s}  "
          f"{'by hand':>9s} {'exact':>5s}")
    for name, shape, noise in (c for c in CASES if c[0] in args.scenes):
        errors = {"default": [], "hand": []}
        for seed in args.seeds:
            default = case(name, shape, noise, seed, "search", args.output)
            hand = compute((name, shape, noise, seed, "search-hand"), args.output,
                           lambda: run_hand_cut(name, shape, noise, seed))
            errors["default"].append(default["error"])
            errors["hand"].append(hand["error"])
            print(f"{name:14s} {shape:8s} {seed:4d}  {default['error']:9.2g} "
                  f"{str(default['exact_support']):>5s}  {hand['error']:9.2g} "
                  f"{str(hand['exact_support']):>5s}", flush=True)
        print(f"{name:14s} {shape:8s} {'geo':>4s}  {geometric_mean(errors['default']):9.2g} "
              f"{'':5s}  {geometric_mean(errors['hand']):9.2g}")


if __name__ == "__main__":
    main()
