"""CPU time of the default search on the search study's four scenes, one process per run.

To compare two versions of the package, run it under each (e.g. with
``PYTHONPATH`` set to another checkout) on the same seeds, one after the
other or alternating, on the same machine::

    python benchmarks/search_time.py --seeds 0 1 2
    PYTHONPATH=/path/to/other/checkout python benchmarks/search_time.py --seeds 0 1 2

Each line gives the package's location, the scene, the seed, the CPU seconds
of ``HamiltonianSearchCV(dt=dt, cv=KFold(5, shuffle=True,
random_state=seed)).fit(X)`` on the data of ``benchmarks/search_study.py``
(BLAS on one thread), and whether it kept the scene's exact terms.
"""

import argparse
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import search_study  # noqa: E402


def run_one(scene, seed):
    from threadpoolctl import threadpool_limits

    import sk_hamiltonian
    from sk_hamiltonian.inspection import hamiltonian_terms
    from sk_hamiltonian.model_selection import HamiltonianSearchCV

    cfg, _, X, cv = search_study.scene_data(scene, seed)
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.process_time()
        search = HamiltonianSearchCV(dt=cfg["dt"], cv=cv).fit(X)
        seconds = time.process_time() - start
    terms = {term.text for term in hamiltonian_terms(search.best_estimator_[-1])}
    print(f"{Path(sk_hamiltonian.__file__).parents[1]}  {scene}  seed {seed}  "
          f"cpu {seconds:.1f} s  exact {terms == cfg['terms']}", flush=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    scenes = list(search_study.SCENES)
    parser.add_argument("--scenes", nargs="+", default=scenes, choices=scenes)
    parser.add_argument("--seeds", nargs="+", type=int, default=[0])
    parser.add_argument("--one", nargs=2, metavar=("SCENE", "SEED"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:
        run_one(args.one[0], int(args.one[1]))
        return
    for seed in args.seeds:
        for scene in args.scenes:
            subprocess.run([sys.executable, str(Path(__file__).resolve()), "--one", scene,
                            str(seed)], check=True)


if __name__ == "__main__":
    main()
