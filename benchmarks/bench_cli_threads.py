"""The default ``sk-hamiltonian`` run beside a CPU-bound process: default BLAS threads against one.

Issue 19 asks that the default run, timed with the BLAS's default threads
while a second CPU-bound process runs, take at most 1.3 times its time with
the BLAS pinned to one thread. This script starts the competitor (a Python
busy loop), waits for it to be scheduled, then runs ``python -m
sk_hamiltonian`` (the built-in example) alternately with default threads and
with ``OPENBLAS_NUM_THREADS=1`` (and the other BLAS variables), ``--repeats``
times each, and prints the wall times and their ratios. Outputs of the runs go
to a temporary directory.

Run: ``PYTHONPATH=. python benchmarks/bench_cli_threads.py`` (about 2 minutes
on 2 cores with the default 2 repeats).
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

PINNED = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def load():
    with open("/proc/loadavg") as handle:
        return " ".join(handle.read().split()[:3])


def run_cli(env, output):
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "sk_hamiltonian", "--output", output], env=env,
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args(argv)
    default = {k: v for k, v in os.environ.items() if k not in PINNED}
    pinned = dict(default, **{k: "1" for k in PINNED})
    competitor = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(5)
        print(f"# {os.cpu_count()} cores, a busy loop beside the runs; load average {load()}")
        times = {"default": [], "pinned": []}
        with tempfile.TemporaryDirectory() as folder:
            for k in range(args.repeats):
                for name, env in (("default", default), ("pinned", pinned)):
                    seconds = run_cli(env, os.path.join(folder, name))
                    times[name].append(seconds)
                    print(f"{name:8s} run {k + 1}: {seconds:6.1f} s wall (load {load()})",
                          flush=True)
    finally:
        competitor.kill()
    ratios = [d / p for d, p in zip(times["default"], times["pinned"])]
    print("default / pinned, run by run: " + ", ".join(f"{r:.2f}" for r in ratios)
          + f"; best against best {min(times['default']) / min(times['pinned']):.2f}")


if __name__ == "__main__":
    main()
