"""Cost of sparse models: simulation follows the kept terms; the fit costs a few solves.

Hénon-Heiles with 2 % noise (500 trajectories of 41 samples, Q = 5), degree 6
(209 terms): the dense fit against ``threshold=0.03`` (the six true monomials).
Measured side by side in one run, one BLAS thread, best of ``--repeats``:

* simulation: 16 initial states near the paper's, 2 000 RK4 steps of 0.01
  (``max_step=0.01``), on each kernel path (numpy, and numba when it is
  installed), CPU time of this thread (the work done, whatever the load; the
  wall clock is printed beside it);
* fit: the dense fit against the thresholded one (every STLSQ solve included).

The sparse model's kept monomials need their Legendre companions on the box
(11 basis functions for the six monomials); small spaces like it are
contracted flat (one product per function, see
``sk_hamiltonian/_space/flat.py``), which is what makes the cost follow the
kept terms.

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

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, config_context  # noqa: E402
from sk_hamiltonian._numba import numba_available  # noqa: E402
from sk_hamiltonian.datasets import henon_heiles, make_trajectories  # noqa: E402


def best_time(function, repeats, clock=time.perf_counter):
    times = []
    for _ in range(repeats):
        start = clock()
        function()
        times.append(clock() - start)
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
        paths = ["numpy"] + (["numba"] if numba_available() else [])
        simulations = {}
        for kernels in paths:
            with config_context(kernels=kernels):
                for name, model in models.items():
                    run = lambda m=model: m.simulate(x0, t, max_step=0.01)  # noqa: E731
                    run()  # warm up (the compiled path loads its kernels)
                    simulations[kernels, name] = (
                        best_time(run, args.repeats, time.thread_time),
                        best_time(run, args.repeats),
                    )
    load = " ".join(open("/proc/loadavg").read().split()[:3])
    print(f"# load average {load}; repeats {args.repeats}, one BLAS thread")
    for name, model in models.items():
        print(f"{name:6s}: {model.n_terms_:3d} terms ({int(model.support_.sum())} basis "
              f"functions evaluated), fit {fits[name]:.3f} s ({model.n_iter_} solves)")
    for kernels in paths:
        (dense, dense_wall), (sparse, sparse_wall) = (
            simulations[kernels, "dense"], simulations[kernels, "sparse"])
        print(f"[{kernels}] simulate 16 x 2000 RK4 steps, CPU s (wall): dense {dense:.3f} "
              f"({dense_wall:.3f}), sparse {sparse:.3f} ({sparse_wall:.3f}); sparse / dense "
              f"{sparse / dense:.2f} (wall {sparse_wall / dense_wall:.2f})")
    print(f"fit time sparse / dense: {fits['sparse'] / fits['dense']:.2f}")


if __name__ == "__main__":
    main()
