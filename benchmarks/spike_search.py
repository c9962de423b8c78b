"""How the spike search of the search's stage 0 does on the robustness study's short records.

For each scene (pendulum, spring, Henon-Heiles, coupled pendula; many short
records, ``benchmarks/robustness_study.py``'s data), noise (none, 0.5, 2
and 8 % additive, 2 and 20 % multiplicative) and seed (0, 1), the samples
:func:`sk_hamiltonian._spikes.find_spikes` marks: on the records as they
are, with 1 % of the samples set to 1e6, and with the same samples moved by
half of each variable's standard deviation (a sign per variable). The counts
are summed over the datasets, cumulatively by scene::

    python benchmarks/spike_search.py

``marked_clean``: samples marked in records without spikes; ``missed`` and
``false`` (1e6): spikes not marked and other samples marked; ``half_found``
of ``half_total`` moved samples marked, and ``half_false`` others marked.
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import robustness_study  # noqa: E402

from sk_hamiltonian._spikes import find_spikes  # noqa: E402


def main():
    counts = dict(marked_clean=0, missed=0, false=0, half_found=0, half_total=0, half_false=0)
    for name in ["pendulum", "spring", "henon_heiles", "coupled_pendula"]:
        for noise in ["0", "add0.5", "add2", "add8", "mult2", "mult20"]:
            for seed in (0, 1):
                cfg, _, X = robustness_study.scene_data(name, "many", noise, seed)
                X = np.asarray(X)
                times = [cfg["dt"] * np.arange(X.shape[1])] * len(X)
                counts["marked_clean"] += int(np.sum(find_spikes(times, list(X))))
                rng = np.random.default_rng(1000 + seed)
                mask = rng.random(X.shape[:2]) < 0.01
                Z = X.copy()
                Z[mask] = 1e6
                found = np.array(find_spikes(times, list(Z)))
                counts["missed"] += int(np.sum(mask & ~found))
                counts["false"] += int(np.sum(found & ~mask))
                sd = X.reshape(-1, X.shape[-1]).std(axis=0)
                Z = X.copy()
                Z[mask] += 0.5 * sd * np.sign(rng.standard_normal((int(mask.sum()), X.shape[-1])))
                found = np.array(find_spikes(times, list(Z)))
                counts["half_found"] += int(np.sum(found & mask))
                counts["half_total"] += int(mask.sum())
                counts["half_false"] += int(np.sum(found & ~mask))
        print(name, counts, flush=True)


if __name__ == "__main__":
    main()
