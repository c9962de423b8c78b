"""Cost of a threshold path: one assembly per fold against one fit per threshold.

Hénon-Heiles with 2 % noise (500 trajectories of 41 samples, Q = 5), at
degree 6 (209 terms, the ``"lstsq"`` solver) and degree 10 (1 000 terms, the
``"normal"`` solver): the fits of ``model_selection.threshold_path`` over the
thresholds (0, 1e-3, 1e-2, 3e-2, 0.1), which share one design (and its QR
factorization or Gram matrix), against a separate ``fit`` per threshold. CPU
time (the process's), one BLAS thread, two repeats each, side by side.

Run: ``PYTHONPATH=. python benchmarks/bench_threshold_path.py`` (about a minute).
"""

import os
import time
import warnings

for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

from sklearn.base import clone  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.model_selection._threshold_path import fit_along_path  # noqa: E402
from sk_hamiltonian.datasets import henon_heiles, make_trajectories  # noqa: E402

THRESHOLDS = [0.0, 1e-3, 1e-2, 3e-2, 0.1]


def main():
    warnings.simplefilter("ignore")
    X = make_trajectories(henon_heiles(), 500, 40, 0.01, noise=0.02, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, degree=5).fit_transform(X)
    with threadpool_limits(1):
        for degree in (6, 10):
            estimator = HamiltonianRegressor(degree=degree)
            for _ in range(2):
                start = time.process_time()
                fit_along_path(clone(estimator), Xt, THRESHOLDS)
                path = time.process_time() - start
                start = time.process_time()
                for threshold in THRESHOLDS:
                    clone(estimator).set_params(threshold=threshold).fit(Xt)
                separate = time.process_time() - start
                print(f"degree {degree}: one assembly {path:.2f} s CPU, separate fits "
                      f"{separate:.2f} s CPU, ratio {path / separate:.2f}", flush=True)


if __name__ == "__main__":
    main()
