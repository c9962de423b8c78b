"""One or two BLAS threads for the Gram update ``A^T A`` (``dsyrk``), by size.

The measurement behind the thread choice of ``sk_hamiltonian._threads``:
best of 3 wall-clock times of one rank-k update with 1 and with 2 BLAS
threads, for designs of 20 000 rows (40 000 for the largest), with the
machine's load average before and after. Run ``python benchmarks/bench_threads.py``
(under a minute on an idle machine).
"""

import time

import numpy as np
from scipy.linalg import blas
from threadpoolctl import threadpool_limits

SHAPES = [(20000, 30), (20000, 100), (20000, 200), (20000, 400), (20000, 800), (40000, 1000)]


def load():
    with open("/proc/loadavg") as handle:
        return " ".join(handle.read().split()[:3])


def main():
    rng = np.random.default_rng(0)
    print(f"load average {load()}")
    print(f"{'rows':>6} {'columns':>7} {'multiply-adds':>13} {'1 thread':>10} {'2 threads':>10} ratio")
    for rows, columns in SHAPES:
        A = np.asfortranarray(rng.random((rows, columns)))
        best = {}
        for threads in (1, 2):
            with threadpool_limits(threads, user_api="blas"):
                C = np.zeros((columns, columns), order="F")
                times = []
                for _ in range(3):
                    start = time.perf_counter()
                    blas.dsyrk(1.0, A, beta=1.0, c=C, trans=1, lower=0, overwrite_c=1)
                    times.append(time.perf_counter() - start)
                best[threads] = min(times)
        print(f"{rows:>6} {columns:>7} {0.5 * rows * columns**2:>13.2g} {best[1] * 1e3:>8.1f}ms "
              f"{best[2] * 1e3:>8.1f}ms {best[2] / best[1]:.2f}")
    print(f"load average {load()}")


if __name__ == "__main__":
    main()
