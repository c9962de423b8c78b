"""How long and how much memory ``sk_hamiltonian.load`` takes on hostile model files.

Issue 32's hostile files (a 257 KB file whose unknown attributes all refer
to one 250 MiB member, ``degree`` 10**8 and 3000 in a small file, bad
``time_scale_`` and ``dt_``, unsigned ``powers_``), each loaded in a fresh
process beside the valid file it was made from: wall time of ``load`` and
the process's peak resident memory above what the imports took, and the
time as a ratio to loading the valid file in the same run.

Run: ``python benchmarks/bench_model_files.py [--output DIR]`` (about a
minute; writes ``model_files.csv`` in ``DIR``, default a temporary folder).
"""

import argparse
import csv
import io
import json
import os
import subprocess
import sys
import tempfile
import warnings
import zipfile

import numpy as np

MEASURE = """
import json, resource, sys, time
import sk_hamiltonian
from sk_hamiltonian import ModelFileError, load
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.perf_counter()
try:
    load(sys.argv[1])
    outcome = "loaded"
except ModelFileError as error:
    outcome = "refused: " + str(error).split(": ", 1)[-1][:200]  # without the file's name
seconds = time.perf_counter() - start
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({"seconds": seconds, "extra_mb": (peak - base) / 1024,
                  "peak_mb": peak / 1024, "outcome": outcome}))
"""


def valid_file():
    from sklearn.pipeline import make_pipeline

    from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, save
    from sk_hamiltonian.datasets import make_trajectories

    X = make_trajectories("single_pendulum", 20, 20, 0.02, noise=0.01, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pipe = make_pipeline(DerivativeTransformer(dt=0.02), HamiltonianRegressor(degree=3)).fit(X)
    buffer = io.BytesIO()
    save(pipe, buffer)
    return buffer.getvalue()


def write(path, valid, change, big=None):
    """``valid`` with ``change(manifest, parts)``; ``big``: (name, bytes) of zeros streamed in."""
    with zipfile.ZipFile(io.BytesIO(valid)) as archive:
        parts = {name: archive.read(name) for name in archive.namelist()}
    manifest = json.loads(parts["manifest.json"])
    change(manifest, parts)
    parts["manifest.json"] = json.dumps(manifest).encode()
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, content in parts.items():
            archive.writestr(name, content)
        if big is not None:
            name, size = big
            header = io.BytesIO()
            np.lib.format.write_array_header_1_0(
                header, {"descr": "<f8", "fortran_order": False, "shape": (size // 8,)})
            with archive.open(name, "w", force_zip64=True) as stream:
                stream.write(header.getvalue())
                for _ in range(size // 2**20):
                    stream.write(b"\0" * 2**20)
    return path


def regressor(manifest):
    return manifest["model"]["steps"][1]["model"]


def hostile_files(folder, valid):
    size = 250 * 2**20

    def bomb(manifest, parts):
        for k in range(13):  # 13 x 250 MiB: the 3.4 GB of the issue
            regressor(manifest)["fitted"][f"evil{k}_"] = {
                "array": "arrays/9000.npy", "shape": [size // 8], "dtype": "<f8",
                "as": "ndarray"}

    def degree(value):
        def change(manifest, parts):
            spec = regressor(manifest)
            spec["params"]["degree"] = value
            ref = spec["fitted"]["powers_"]
            powers = np.load(io.BytesIO(parts[ref["array"]]))
            powers[-1] = [0, value]
            buffer = io.BytesIO()
            np.save(buffer, powers)
            parts[ref["array"]] = buffer.getvalue()

        return change

    def fitted(key, value):
        return lambda manifest, parts: regressor(manifest)["fitted"].update({key: value})

    def unsigned(manifest, parts):
        ref = regressor(manifest)["fitted"]["powers_"]
        powers = np.load(io.BytesIO(parts[ref["array"]])).astype(np.uint64)
        powers[-1] = [2**63, 0]
        buffer = io.BytesIO()
        np.save(buffer, powers)
        parts[ref["array"]], ref["dtype"] = buffer.getvalue(), "<u8"

    cases = {
        "valid": (lambda manifest, parts: None, None),
        "reference bomb (250 MiB member, 13 references)": (bomb, ("arrays/9000.npy", size)),
        "degree 10**8": (degree(10**8), None),
        "degree 3000": (degree(3000), None),
        "time_scale_ = 1e-9": (fitted("time_scale_", 1e-9), None),
        "time_scale_ = -1": (fitted("time_scale_", -1.0), None),
        "dt_ = 1e-300": (fitted("dt_", 1e-300), None),
        "powers_ uint64 with 2**63": (unsigned, None),
    }
    return {name: write(os.path.join(folder, f"{k}.skh"), valid, change, big)
            for k, (name, (change, big)) in enumerate(cases.items())}


def measure(path):
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [root] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])))
    out = subprocess.run([sys.executable, "-c", MEASURE, path], capture_output=True, text=True,
                         env=env, check=True).stdout
    return json.loads(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", help="folder for model_files.csv (default: temporary)")
    args = parser.parse_args(argv)
    folder = args.output or tempfile.mkdtemp()
    os.makedirs(folder, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        files = hostile_files(scratch, valid_file())
        reference = measure(files["valid"])
        for name, path in files.items():
            result = reference if name == "valid" else measure(path)
            rows.append({
                "file": name, "file_kb": round(os.path.getsize(path) / 1024, 1),
                "seconds": round(result["seconds"], 4),
                "time_ratio_to_valid": round(result["seconds"] / reference["seconds"], 2),
                "extra_mb": round(result["extra_mb"], 1), "peak_mb": round(result["peak_mb"], 1),
                "outcome": result["outcome"],
            })
    path = os.path.join(folder, "model_files.csv")
    with open(path, "w", newline="") as stream:
        writer = csv.DictWriter(stream, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    for row in rows:
        print(f"{row['file']:48s} {row['file_kb']:>7} KB {row['seconds']:>7} s "
              f"(x{row['time_ratio_to_valid']:<5}) +{row['extra_mb']:>5} MB  {row['outcome']}")
    print(f"written: {path}")


if __name__ == "__main__":
    main()
