"""The scene examples run on their own and show what their model spaces are for.

Each example of ``examples/scenes/`` runs in quick mode as a subprocess, as
``python examples/scenes/plot_*.py`` would, writing its figures and a JSON file
of measured numbers into a temporary directory; the tests then check the files
and the claims the example makes. They run concurrently in one fixture
(about 20 s of CPU time each, a minute on two idle cores), so these tests
are marked slow (run with ``--runslow``; CI does, and its documentation build
runs the examples too).

Fast tests elsewhere check the same kinds of claim on smaller problems:

- the Fourier-mechanical space against total degree on the double pendulum:
  tests/test_model_spaces.py (full-circle angles, exact gradients);
- the lattice's pairwise and nearest-neighbour spaces, their rollouts with
  leapfrog, Yoshida and RK4, and leapfrog's bounded energy error:
  tests/test_model_spaces.py; the Simpson fit of a chain: tests/test_simpson_fit.py;
- the sparse pendulum's formula and better rollout: tests/test_sparse.py; the
  chain's true monomials from one record: tests/test_simpson_fit.py.

Only here: the double pendulum's learned terms against the true ones, the
rollout outside the momentum box of the data, and the 16-particle chain.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "examples" / "scenes"
EXAMPLES = {
    "plot_angles_double_pendulum": ("angles_double_pendulum",
                                    ["angles_error_vs_terms", "angles_rollouts"]),
    "plot_lattice_fput": ("lattice_fput", ["lattice_rollouts", "lattice_energy"]),
    "plot_sparse_hamiltonians": ("sparse_hamiltonians",
                                 ["sparse_threshold_path", "sparse_pendulum_errors"]),
    "plot_search": ("search", ["search_rollouts"]),
    "plot_intervals": ("intervals", ["intervals_band"]),
    "plot_one_record": ("one_record", ["one_record"]),
    "plot_coupled_long_records": ("coupled_long_records", ["coupled_long_records"]),
    "plot_pruned_terms": ("pruned_terms", ["pruned_terms"]),
    "plot_lab_records": ("lab_records", ["lab_records"]),
}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    figures = tmp_path_factory.mktemp("scene_figures")
    env = dict(os.environ, SK_HAMILTONIAN_QUICK="1", SK_HAMILTONIAN_FIGURES=str(figures),
               MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    # Two examples side by side on few cores: one BLAS thread each.
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[var] = "1"
    processes = {
        name: subprocess.Popen([sys.executable, str(SCENES / f"{name}.py")], cwd=SCENES,
                               env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True)
        for name in EXAMPLES
    }
    outputs = {}
    for name, process in processes.items():
        try:
            # Generous: a loaded machine can stretch 40 s of CPU into minutes.
            outputs[name], _ = process.communicate(timeout=900)
        except subprocess.TimeoutExpired:
            process.kill()
            outputs[name], _ = process.communicate()
            pytest.fail(f"{name} did not finish:\n{outputs[name]}")
        assert process.returncode == 0, f"{name} failed:\n{outputs[name]}"
    results = {name: json.loads((figures / f"{stem}.json").read_text())
               for name, (stem, _) in EXAMPLES.items()}
    return figures, outputs, results


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_scene_example_writes_its_figures(runs, name):
    figures, outputs, results = runs
    for figure in EXAMPLES[name][1]:
        path = figures / f"{figure}.png"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", (figure, outputs[name])
    assert results[name]["quick_mode"] is True


def test_angles_fourier_mechanical_beats_total_degree_per_term(runs):
    spaces = runs[2]["plot_angles_double_pendulum"]["spaces"]
    fourier, total = spaces["Fourier-mechanical"], spaces["total degree"]
    for row in total:
        # The Fourier-mechanical model nearest in size to this total-degree one.
        nearest = min(fourier, key=lambda r: abs(math.log(r["n_terms"] / row["n_terms"])))
        assert nearest["h_error"] < row["h_error"] / 2, (nearest, row)
    # Its best is more than ten times better than the best total-degree model.
    assert min(r["h_error"] for r in fourier) < min(r["h_error"] for r in total) / 10
    # Errors fall with the number of terms in the Fourier-mechanical space.
    errors = [r["h_error"] for r in sorted(fourier, key=lambda r: r["n_terms"])]
    assert errors == sorted(errors, reverse=True), errors
    # Trigonometric columns stay well conditioned.
    assert all(r["cond"] < 10 for r in fourier)


def test_angles_learned_hamiltonian_reads_like_the_true_one(runs):
    best = runs[2]["plot_angles_double_pendulum"]["best"]
    assert best["space"] == "Fourier-mechanical"
    # The potential -2 cos q1 - cos q2 is in the space exactly; the kinetic
    # means 1/(2 sqrt 2) and 1/sqrt 2 are truncation-limited. Quick mode
    # measured 1e-4 to 2e-4 relative on each.
    for name, exact in best["exact_terms"].items():
        assert best["terms"][name] == pytest.approx(exact, rel=2e-3), name


def test_angles_mechanical_models_extrapolate_in_the_momenta(runs):
    spaces = runs[2]["plot_angles_double_pendulum"]["spaces"]
    # The orbit from u0* leaves the momentum box of the data. The largest
    # Fourier-mechanical model follows it; the largest total-degree one does
    # not (measured in quick mode: 6e-2 against a failed rollout).
    assert spaces["Fourier-mechanical"][-1]["rollout_error"] < 0.2
    assert spaces["total degree"][-1]["rollout_error"] > 0.5


def test_lattice_pairwise_model_follows_the_chain(runs):
    result = runs[2]["plot_lattice_fput"]
    pairwise = result["models"]["pairwise separable, degree 4"]
    assert pairwise["n_terms"] == 400
    errors = {method: r["max_error"] for method, r in pairwise["rollouts"].items()}
    assert set(errors) == {"leapfrog", "yoshida4", "rk4"}
    # Measured 1.9e-4 for each: the model's error, not the integrator's.
    assert all(e < 1e-3 for e in errors.values()), errors
    assert max(errors.values()) < 1.1 * min(errors.values()), errors
    # Total degree 3 has more terms and cannot hold the quartic bonds.
    total = result["models"]["total degree 3"]
    assert total["n_terms"] > pairwise["n_terms"]
    assert total["rollouts"]["rk4"]["max_error"] > 100 * max(errors.values())


def test_lattice_leapfrog_energy_error_is_bounded(runs):
    energy = runs[2]["plot_lattice_fput"]["long_run"]["energy"]
    leapfrog = energy["leapfrog"]
    # Bounded oscillation: no growth from the first tenth of the run to the last.
    assert 0 < leapfrog["last_tenth"] < 1.5 * leapfrog["first_tenth"]
    # RK4's error is smaller at this step but grows (measured 13x over T = 200).
    assert energy["rk4"]["last_tenth"] > 3 * energy["rk4"]["first_tenth"]


def test_lattice_large_chain(runs):
    large = runs[2]["plot_lattice_fput"]["large"]
    assert large["n_particles"] == 16 and large["total_degree_terms"] == 58904
    pairs, neighbours = large["models"]["every pair"], large["models"]["neighbours"]
    # 1 568 terms with every pair; neighbours: 32 x 4 + 15 bonds x 6 = 218.
    assert pairs["n_terms"] == 1568 and neighbours["n_terms"] == 218
    assert pairs["max_error"] < 1e-2
    # Measured in quick mode: every pair 1.3e-3, neighbours 8.5e-3 (no spare
    # terms for the finite differences' bias), neighbours fitted on the steps
    # by Simpson's rule 7.5e-7 (no such bias).
    assert neighbours["max_error"] < 5e-2
    simpson = large["models"]["neighbours, simpson"]
    assert simpson["n_terms"] == 218
    assert simpson["max_error"] < 1e-2 * pairs["max_error"]


def test_sparse_pendulum_reads_as_its_formula(runs):
    pendulum = runs[2]["plot_sparse_hamiltonians"]["pendulum"]
    # The path shrinks the model as the threshold grows.
    assert pendulum["n_terms"] == sorted(pendulum["n_terms"], reverse=True)
    assert pendulum["chosen"] > 0
    terms = pendulum["terms"]
    assert set(terms) == {"(2, 0)", "(0, 1)"}
    assert terms["(2, 0)"] == pytest.approx(0.5, rel=0.01)
    assert terms["(0, 1)"] == pytest.approx(-9.8, rel=0.01)
    # Measured 0.024 against 0.104 (the issue asks for at most half).
    assert pendulum["error_T20"]["sparse"] < 0.5 * pendulum["error_T20"]["dense"]


def test_sparse_chain_keeps_the_true_monomials(runs):
    chain = runs[2]["plot_sparse_hamiltonians"]["chain"]
    names = [f"p{i}^2" for i in range(1, 6)] + [f"q{i}^2" for i in range(1, 6)]
    couplings = [f"q{i}*q{i + 1}" for i in range(1, 5)]
    assert set(chain["terms"]) == set(names + couplings)
    for name in names:
        exact = 0.5 if name.startswith("p") else 1.0
        # Noise 1e-3 on one record, Simpson fit: measured within 0.04 %.
        assert chain["terms"][name] == pytest.approx(exact, rel=0.003), name
    for name in couplings:
        assert chain["terms"][name] == pytest.approx(-1.0, rel=0.003), name
    errors = chain["held_out_error"]
    # Measured: 0.49x (the bound is 0.7x).
    assert errors["sparse"] < 0.7 * errors["dense"], errors


def test_search_finds_the_laws_in_their_spaces(runs):
    results = runs[2]["plot_search"]
    # The pendulum: a periodic angle and exactly p^2 and cos q.
    assert results["pendulum"]["terms"] == ["cos(q)", "p^2"]
    assert all(space.get("periodic") == [False, True]
               for space in results["pendulum"]["kept_spaces"])
    # The torsion pendulum: a mixed space and exactly its three terms, each
    # within 2 % (quick mode measured 0.8 %, 0.06 % and 0.14 %).
    assert results["torsion"]["terms"] == ["cos(q)", "p^2", "q^2"]
    assert all(space.get("mixed") == [False, True] for space in results["torsion"]["kept_spaces"])
    for term, exact in (("cos(q)", -4.0), ("p^2", 0.5), ("q^2", 0.5)):
        assert results["torsion"]["coefficients"][term] == pytest.approx(exact, rel=0.02), term
    # The averaged-vector-field rollouts keep H~ to round-off.
    assert results["pendulum"]["drift"] < 1e-10 and results["torsion"]["drift"] < 1e-10


def test_one_record_is_said_to_lie_on_one_level_and_five_records_are_not(runs):
    results = runs[2]["plot_one_record"]
    # Both searches keep the pendulum's law (quick mode: -9.797 cos q + 0.5001 p^2
    # from one record, -9.802 cos q + 0.4998 p^2 from five).
    assert results["one_record"]["terms"] == ["cos(q)", "p^2"]
    assert results["five_records"]["terms"] == ["cos(q)", "p^2"]
    # Only the one record is said to lie on one energy level.
    assert results["one_record"]["one_level"] is True
    assert results["five_records"]["one_level"] is False
    # Both models stay close to the truth off the recorded levels (quick mode:
    # at most 0.0099 and 0.019 at T = 20).
    assert max(results["one_record"]["errors_T20"]) < 0.05
    assert max(results["five_records"]["errors_T20"]) < 0.05


def test_long_records_of_coupled_pendula_give_the_cosine_law_over_its_series(runs):
    results = runs[2]["plot_coupled_long_records"]
    cosine_law = ["cos(q1)", "cos(q2)", "p1^2", "p2^2", "q1*q2", "q1^2", "q2^2"]
    # The search keeps the cosine law, offered in stage 3 and judged on the
    # trajectories (quick mode: gain 93 with a standard error of 19).
    assert results["terms"] == cosine_law
    assert results["stage"] == "cosine"
    judgement = results["judgement"]
    assert judgement["kind"] == "cosine law" and judgement["best"] == 1
    assert judgement["gain"] > 2 * judgement["gain_se"]
    # The named fits keep exactly their terms.
    assert results["named_terms"]["cosine law"] == cosine_law
    assert results["named_terms"]["Taylor series"] == [
        "p1^2", "p2^2", "q1*q2", "q1^2", "q1^4", "q2^2", "q2^4"]
    # Off the records the cosine law is ahead of the series fitted to the same
    # derivatives (quick mode: median errors 0.0064 and 0.018 at T = 20; the
    # search's refined law 0.001).
    errors = {name: np.median(values) for name, values in results["errors_T20"].items()}
    assert errors["cosine law"] < errors["Taylor series"]
    assert errors["search"] < errors["Taylor series"]


def test_one_record_at_small_angles_is_pruned_to_its_cosine_law_under_both_folds(runs):
    results = runs[2]["plot_pruned_terms"]
    for folds in ("default folds", "shuffled folds"):
        found = results[folds]
        assert found["terms"] == ["cos(q)", "p^2"], folds
        assert sorted(found["pruned"]) == ["p^2*q^2", "p^2*q^4", "q^6"], folds
        assert found["kind"] == "cosine law", folds
    # Under the shuffled folds the six-term finalist was not tied: it is the
    # richer finalist the trajectories took (the default folds tied it).
    assert results["default folds"]["untied"] is None
    assert sorted(results["shuffled folds"]["untied"]) == [
        "p^2", "p^2*q^2", "p^2*q^4", "q^2", "q^4", "q^6"]
    # The search's law is ahead of both sets of terms on its path (measured:
    # median errors 0.00081, 0.1 and 0.28 at T = 20).
    errors = {name: np.median(values) for name, values in results["errors_T20"].items()}
    assert errors["search"] < errors["pruned: p^2, q^2, q^4"] < errors["six terms"]


def test_intervals_keep_the_pendulum_terms_and_band_the_refits(runs):
    results = runs[2]["plot_intervals"]
    n = results["n_resamples"]
    terms = results["terms"]
    # Both true terms in every refit, each fitted coefficient inside its interval.
    for text in ("cos(q)", "p^2"):
        assert terms[text]["kept"] == n, text
        assert terms[text]["low"] < terms[text]["coefficient"] < terms[text]["high"], text
    # Any other term in at most 20 % of the refits (quick mode measured 2 of 50).
    assert all(v["kept"] <= 0.2 * n for k, v in terms.items() if k not in ("cos(q)", "p^2"))
    # The p^2 interval holds the truth 0.5 (quick mode: [0.4979, 0.5023]).
    assert terms["p^2"]["low"] < 0.5 < terms["p^2"]["high"]
    # The band starts at the one initial state and widens (quick mode: 0.56 at T = 20).
    assert results["band_start_width"] == 0.0 and results["band_width_T20"] > 0.01



def test_lab_records_in_their_own_units_with_logger_faults_give_the_law(runs):
    results = runs[2]["plot_lab_records"]
    assert results["terms"] == ["p^2", "q^2", "q^4"]
    # Positions in millimetres: the law is 500 p^2 + 0.0005 q^2 + 2.5e-10 q^4
    # (quick mode: 500.06, 0.00049979, 2.5024e-10).
    coefficients = [results["coefficients"][term] for term in ("p^2", "q^2", "q^4")]
    np.testing.assert_allclose(coefficients, [500, 5e-4, 2.5e-10], rtol=0.01)
    # The momenta were brought to the positions' spread for the search, by
    # the power of ten that gives back the numbers of SI units.
    assert results["momentum_scale"] == 1000
    # Each fault named where it was put: lost readings, the spike, and the
    # two readings moved off at the ends of records.
    assert results["missing"] == {"4": [12], "9": [30], "20": [0]}
    assert results["left_out"] == {"4": [12], "9": [30], "20": [0], "30": [25]}
    assert results["outliers"] == {"50": [0], "70": [40]}
    # Quick mode: at most 0.013 at T = 20 from the three fresh states.
    assert max(results["errors_T20"]) < 0.05
