"""Cost of sparse models: simulation follows the kept terms; the fit costs a few solves.

Hénon-Heiles with 2 % noise (500 trajectories of 41 samples, Q = 5), degree 6
(209 terms): the dense fit against ``threshold=0.03`` (the six true monomials).
Measured side by side in one run, one BLAS thread, best of ``--repeats``:

* simulation: 16 initial states near the paper's, 2 000 RK4 steps of 0.01 (``max_step=0.01``);
* fit: the dense fit against the thresholded one (every STLSQ solve included).

Run: ``PYTHONPATH=. python benchmarks/bench_sparse.py`` (about a minute).
"""

import argparse
import os
import time
import warnings

for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

import numpy as np  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.datasets import henon_heiles, make_trajectories  # noqa: E402


def best_time(function, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    system = henon_heiles()
    X = make_trajectories(system, 500, 40, dt=0.01, noise=0.02, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, degree=5).fit_transform(X)
    # Bounded orbits: the paper's initial state, perturbed.
    x0 = system.initial_state + 0.02 * np.random.default_rng(1).standard_normal((16, 4))
    t = 0.01 * np.arange(2001)
    with threadpool_limits(1):
        models, fits = {}, {}
        for name, threshold in (("dense", 0.0), ("sparse", 0.03)):
            def fit(threshold=threshold, name=name):
                models[name] = HamiltonianRegressor(degree=6, threshold=threshold).fit(Xt)
            fits[name] = best_time(fit, args.repeats)
        simulations = {
            name: best_time(lambda m=model: m.simulate(x0, t, max_step=0.01), args.repeats)
            for name, model in models.items()
        }
    print(f"# load before/after: see uptime; repeats {args.repeats}, one BLAS thread")
    for name, model in models.items():
        print(f"{name:6s}: {model.n_terms_:3d} terms ({int(model.support_.sum())} basis "
              f"functions evaluated), fit {fits[name]:.3f} s ({model.n_iter_} solves), "
              f"simulate 16 x 2000 RK4 steps {simulations[name]:.3f} s")
    print(f"simulation time sparse / dense: {simulations['sparse'] / simulations['dense']:.2f}")
    print(f"fit time sparse / dense: {fits['sparse'] / fits['dense']:.2f}")


if __name__ == "__main__":
    main()
