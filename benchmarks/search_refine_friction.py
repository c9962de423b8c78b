"""The search's refinement with friction: the damped pendulum, with and without it.

``HamiltonianSearchCV(dt, damping=True)`` on the pendulum with linear
friction ``gamma = 0.3`` (200 trajectories x 41 samples, dt = 0.02, 3 %
relative noise, as ``make_trajectories`` draws it), with its default
refinement on the raw trajectories (``refine="trajectories"``) and without
it (``refine=None``), for data seeds 0-4 (folds shuffled by the seed). For
each: the fitted friction, the kept terms, and the error at ``T = 10`` of
the study's protocol (``search_study.py``: the median over 10 fresh states
drawn uniformly from the domain of the relative state error, angles compared
the short way round; truth by RK4 with steps of 1e-3).

Run::

    python benchmarks/search_refine_friction.py            # about 2 min
"""

import os
import sys
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from sklearn.model_selection import KFold  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import search_study as study  # noqa: E402

from sk_hamiltonian.datasets import make_trajectories, single_pendulum  # noqa: E402
from sk_hamiltonian.inspection import hamiltonian_terms  # noqa: E402
from sk_hamiltonian.model_selection import HamiltonianSearchCV  # noqa: E402

T_END = 10.0


def main():
    system = single_pendulum(damping=0.3)
    rng = np.random.default_rng(12345)
    low, high = system.domain[:, 0], system.domain[:, 1]
    x0 = rng.uniform(low, high, size=(study.N_FRESH, 2))
    truth = system.solve(x0, np.linspace(0.0, T_END, 101), max_step=1e-3)[:, -1]
    errors = {None: [], "trajectories": []}
    for seed in range(5):
        X = make_trajectories(system, 200, 40, 0.02, noise=0.03, random_state=seed)
        line = []
        for refine in errors:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                search = HamiltonianSearchCV(
                    dt=0.02, damping=True, refine=refine,
                    cv=KFold(5, shuffle=True, random_state=seed),
                ).fit(X)
            model = search.best_estimator_[-1]
            error = study.fresh_error(
                lambda x: model.simulate(x, [0.0, T_END], on_failure="nan")[:, -1],
                x0, truth, [1])
            errors[refine].append(error)
            terms = sorted(term.text for term in hamiltonian_terms(model))
            line.append(f"refine={refine}: gamma {model.damping_[0]:.4f}, {terms}, "
                        f"error {error:.3g}")
        print(f"seed {seed}: " + " | ".join(line), flush=True)
    for refine, values in errors.items():
        print(f"refine={refine}: geometric mean error {study.geometric_mean(values):.3g}")


if __name__ == "__main__":
    main()
