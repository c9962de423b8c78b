"""Smoke test of the benchmark scripts: ``--quick`` runs, outputs and their shape.

Speed is not asserted here (the benchmarks report same-run ratios instead).
PySINDy is blocked on purpose, so the run also checks that the scripts skip the
optional baseline gracefully wherever pysindy happens to be installed.

The ``--quick`` runs take over a minute on two cores, so they are marked slow
(run with ``--runslow``; CI does). In the default run, every script is checked
to find the package's names it imports (many use private modules), and
PySINDy-best's pieces run on small data.
"""

import ast
import csv
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from import_check import unresolved_imports

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
SPEED_COLUMNS = [
    "scene", "method", "n_params", "cond", "fit_s", "sim_s", "total_s", "select_s",
    "sim_vectorized_s",
    "err_T10", "err_T20", "fresh_err_T10", "fresh_err_T20", "fresh_failed", "n_fresh",
    "fail_time", "energy_drift", "model_energy_drift", "note",
]
STABILITY_COLUMNS = [
    "experiment", "method", "param", "value", "status", "error", "horizon", "n_test",
    "n_failed", "fail_time", "n_escaped", "escape_time", "blowup_time", "cond", "n_params",
    "n_equations", "note",
]


def _read(path):
    with open(path, newline="") as handle:
        reader = csv.DictReader(handle)
        return reader.fieldnames, list(reader)


def _finite(row, *keys):
    return all(math.isfinite(float(row[key])) for key in keys)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Run both scripts with --quick, side by side, pysindy made unimportable."""
    tmp = tmp_path_factory.mktemp("bench")
    blocker = tmp / "blocker" / "pysindy"
    blocker.mkdir(parents=True)
    (blocker / "__init__.py").write_text('raise ImportError("blocked by the smoke test")\n')
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = os.pathsep.join(
        [str(blocker.parent)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else [])
    )
    procs = {}
    for name in ("bench_speed_accuracy", "bench_stability"):
        out = tmp / name
        procs[name] = (out, subprocess.Popen(
            [sys.executable, str(BENCHMARKS / f"{name}.py"), "--quick", "--output", str(out)],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env,
        ))
    results = {}
    for name, (out, proc) in procs.items():
        try:
            # Generous: the machine running the suite may be shared.
            stdout, _ = proc.communicate(timeout=900)
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, _ = proc.communicate()
            pytest.fail(f"{name} --quick timed out:\n{stdout[-3000:]}")
        results[name] = (out, proc.returncode, stdout)
    return results


@pytest.mark.slow
def test_speed_accuracy_quick(runs):
    out, code, stdout = runs["bench_speed_accuracy"]
    assert code == 0, stdout[-3000:]
    assert "PySINDy rows skipped" in stdout
    for name in ("speed_accuracy.csv", "speed_ratios.csv", "speed_vs_accuracy.png"):
        assert (out / name).stat().st_size > 0, name
    assert (out / "speed_vs_accuracy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    columns, rows = _read(out / "speed_accuracy.csv")
    assert columns == SPEED_COLUMNS
    assert not any(r["method"].startswith("PySINDy") for r in rows)
    sp = [r for r in rows if r["method"].startswith("SP-")]
    # Leapfrog only for the separable scene (the FPUT chain).
    assert {r["method"] for r in sp} == {"SP-RK4", "SP-AVF", "SP-LEAPFROG", "SP-sparse-RK4",
                                         "SP-simpson-RK4"}
    assert {r["scene"] for r in sp if r["method"] == "SP-LEAPFROG"} == {"FPUT chain 4"}
    assert len({r["scene"] for r in sp}) >= 3
    for r in sp:
        assert _finite(r, "cond", "fit_s", "sim_s", "total_s", "err_T10", "err_T20",
                       "fresh_err_T20", "energy_drift", "model_energy_drift"), r
        assert float(r["fit_s"]) > 0 and float(r["sim_s"]) > 0
        assert 0 <= float(r["err_T10"]) < 10
    # The averaged vector field conserves the learned Hamiltonian to round-off.
    for r in sp:
        if r["method"] == "SP-AVF":
            assert float(r["model_energy_drift"]) < 1e-8, r

    # The sparse rows: one of each per scene, the threshold from the searched
    # grid, no more kept terms than the dense fit in the same space has.
    from sk_hamiltonian.model_selection import count_terms  # noqa: PLC0415
    from sk_hamiltonian import HamiltonianRegressor, VectorFieldRegressor  # noqa: PLC0415

    for scene in {r["scene"] for r in rows}:
        here = {r["method"]: r for r in rows if r["scene"] == scene}
        for method, cls in (("SP-sparse-RK4", HamiltonianRegressor),
                            ("non-SP-STLSQ-RK4", VectorFieldRegressor)):
            r = here[method]
            assert _finite(r, "fit_s", "select_s", "err_T20", "fresh_err_T20"), r
            assert float(r["select_s"]) > 0, r
            chosen = float(r["note"].split("threshold=")[1].split(" ")[0])
            assert chosen in (0.0, 0.01, 0.1), r["note"]
            space = ast.literal_eval(r["note"].split("space ")[1])  # as the script printed it
            degree = int(r["note"].split("degree ")[1].split(",")[0])
            n_states = 2 * (4 if scene.startswith("FPUT") else 1 if "pendulum" in scene else 2)
            dense = count_terms(cls(degree, **space), n_states)
            assert 1 <= int(float(r["n_params"])) <= dense, (r, dense)

    columns, ratios = _read(out / "speed_ratios.csv")
    assert columns == ["scene", "ratio", "value"]
    assert any(r["ratio"] == "fit: SP / non-SP" and _finite(r, "value") for r in ratios)
    assert any(r["ratio"] == "err T=20 u0*: SP-sparse / SP" and _finite(r, "value")
               for r in ratios)
    assert any(r["ratio"] == "err T=20 u0*: SP-simpson / SP" and _finite(r, "value")
               for r in ratios)


@pytest.mark.slow
def test_stability_quick(runs):
    out, code, stdout = runs["bench_stability"]
    assert code == 0, stdout[-3000:]
    assert "PySINDy rows skipped" in stdout
    assert (out / "stability.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Each panel also alone, for the documentation.
    for panel in ("noise", "trajectories", "conditioning", "degree", "long_horizon", "cherry"):
        assert (out / f"stability_{panel}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", panel

    columns, rows = _read(out / "stability.csv")
    assert columns == STABILITY_COLUMNS
    assert {r["experiment"] for r in rows} == {
        "noise", "n_trajectories", "degree", "long_horizon", "cherry_blowup"}
    assert not any(r["method"].startswith("PySINDy") for r in rows)
    statuses = {r["status"] for r in rows}
    assert statuses <= {"ok", "failed", "escaped", "unfit", "blows up", "bounded"}
    # Failures are recorded, not dropped: the quick sweep goes below the number
    # of unknowns, where no method can be fitted.
    assert "unfit" in statuses
    for r in rows:
        if r["method"] == "SP-RK4" and r["experiment"] == "noise":
            assert _finite(r, "error", "cond"), r
        if r["status"] == "failed":
            assert _finite(r, "fail_time"), r
    # The sparse rows with the cubic smoothing: only where the data are noisy.
    for method in ("SP-sparse-Q3-RK4", "SP-CV-RK4"):
        noisy = [r for r in rows if r["method"] == method]
        assert noisy and all(r["experiment"] in ("noise", "long_horizon")
                             and float(r["value"]) > 0 for r in noisy), noisy
    truth = [r for r in rows if r["experiment"] == "cherry_blowup" and r["method"] == "truth"]
    assert len(truth) == 1 and 27 < float(truth[0]["blowup_time"]) < 29


@pytest.mark.slow
def test_speed_front_quick(tmp_path):
    """``--front``: one row per method and knob, failures kept, chart redrawn by ``--replot``."""
    out = tmp_path / "front"
    env = dict(os.environ, MPLBACKEND="Agg")
    command = [sys.executable, str(BENCHMARKS / "bench_speed_accuracy.py"), "--quick", "--front",
               "--no-sindy", "--output", str(out)]
    proc = subprocess.run(command, capture_output=True, text=True, env=env, timeout=240)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    columns, rows = _read(out / "speed_front.csv")
    assert columns == ["scene", "method", "knob", "n_params", "fit_s", "sim_s", "total_s",
                       "err_T20", "fresh_err_T20", "fresh_failed", "n_fresh", "note"]
    assert {r["method"] for r in rows} == {"SP-RK4", "non-SP-RK4"}
    for scene in {r["scene"] for r in rows}:
        for method in ("SP-RK4", "non-SP-RK4"):
            assert len([r for r in rows if r["scene"] == scene and r["method"] == method]) == 5
    for r in rows:
        # A failed rollout is a row with infinite error, drawn at its fit time.
        assert _finite(r, "fit_s", "total_s"), r
        assert float(r["err_T20"]) > 0, r
    png = out / "speed_vs_accuracy_front.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    png.unlink()
    proc = subprocess.run(command + ["--replot"], capture_output=True, text=True, env=env,
                          timeout=120)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    assert png.stat().st_size > 0


@pytest.mark.slow
def test_scale_quick(tmp_path):
    out = tmp_path / "scale"
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run(
        [sys.executable, str(BENCHMARKS / "bench_scale.py"), "--quick", "--output", str(out)],
        capture_output=True, text=True, env=env, timeout=240,
    )
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    assert (out / "scale.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "machine.txt").read_text().count("cores") == 1
    columns, rows = _read(out / "scale.csv")
    assert columns == ["group", "measure", "value", "unit", "target", "met", "note"]
    assert {r["group"] for r in rows} == {"evaluation", "simulation", "fit", "solver choice",
                                          "scaling"}
    for r in rows:
        assert math.isfinite(float(r["value"])), r
        # Times and ratios are positive; a fitted slope of timings at the quick
        # mode's tiny sizes is noise and may have either sign.
        assert r["unit"] == "slope" or float(r["value"]) > 0, r
        # A target is either reported met or not, never silently dropped.
        assert (r["target"] == "") == (r["met"] == ""), r
        assert r["met"] in ("", "yes", "no"), r
    assert sum(r["target"] != "" for r in rows) >= 4
    _, fits = _read(out / "scale_fit.csv")
    assert {r["sweep"] for r in fits} == {"samples", "terms"}


@pytest.mark.parametrize("path", sorted(BENCHMARKS.glob("*.py")), ids=lambda p: p.name)
def test_benchmark_scripts_find_what_they_import(path):
    assert not unresolved_imports(path.read_text(encoding="utf-8"))


def test_sindy_best_pieces():
    """PySINDy-best's pieces on small data: CV threshold, bagged fit, smoothed derivatives.

    The smoke runs above block pysindy; this checks the configuration they
    skip, where pysindy is installed.
    """
    ps = pytest.importorskip("pysindy")
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import _common as C  # noqa: PLC0415
    finally:
        sys.path.remove(str(BENCHMARKS))
    import numpy as np  # noqa: PLC0415

    # Pendulum, clean: sines and cosines of q times 1, p, p^2.
    scene = C.Scene("pendulum", "single_pendulum", 6, 40, 10)
    system, Xt, _, X = C.make_data(scene, raw=True)
    states, derivatives, _, how = C.sindy_best_data(ps, scene, X, Xt)
    assert "finite differences" in how
    periodic = [False, True]
    threshold, scores = C.cv_sindy_threshold(ps, states, derivatives, scene.dt, 2, 1, periodic,
                                             thresholds=(0.0, 0.1), folds=2)
    assert threshold in scores and set(scores) == {0.0, 0.1}
    model = C.fit_sindy_best(ps, states, derivatives, scene.dt, 0.1, 2, 1, periodic, n_models=3)
    # SindyField checks itself against predict; here also against the truth.
    field = C.SindyField(model, np.concatenate(states)[:50], fourier=1, periodic=periodic)
    S = np.concatenate(states)
    truth = system.vector_field(S)
    assert np.max(np.abs(field(S) - truth)) < 1e-2 * np.max(np.abs(truth))
    assert field.n_params == 2  # dp/dt = -g sin q, dq/dt = p

    # Noisy: PySINDy's smoothed finite differences over the whole trajectory
    # beat raw finite differences of the noisy states.
    noisy = C.Scene("pendulum", "single_pendulum", 6, 20, 20, noise=0.05)
    system, Xt, _, X = C.make_data(noisy, raw=True)
    states, derivatives, _, how = C.sindy_best_data(ps, noisy, X, Xt)
    assert "window 21" in how
    smoothed = np.concatenate(derivatives) - system.vector_field(np.concatenate(states))
    raw = np.gradient(X, noisy.dt, axis=1).reshape(-1, 2) - system.vector_field(
        X.reshape(-1, 2))
    assert np.sqrt(np.mean(smoothed ** 2)) < 0.5 * np.sqrt(np.mean(raw ** 2))


@pytest.mark.slow
def test_scale_study_quick_on_the_oscillator_network(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    script = str(BENCHMARKS / "scale_study.py")

    def run(*args):
        proc = subprocess.run([sys.executable, script, *args, "--output", str(tmp_path)],
                              capture_output=True, text=True, env=env, timeout=600)
        assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
        return proc.stdout

    run("--quick", "--chain", "network", "--methods", "search")
    columns, rows = _read(tmp_path / "quick" / "scale_study_network.csv")
    assert {"d", "seed", "method", "exact", "error", "cpu_s", "peak_mb"} <= set(columns)
    assert sorted(int(r["d"]) for r in rows) == [2, 3]
    for r in rows:
        assert r["method"] == "search" and r["exact"] in ("True", "False"), r
        assert _finite(r, "error", "cpu_s", "peak_mb") and float(r["cpu_s"]) > 0, r
    png = tmp_path / "chart.png"
    assert "wrote" in run("--quick", "--chart", str(png))
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_robustness_study_quick_reports_its_tables_and_the_check_rules():
    proc = subprocess.run([sys.executable, str(BENCHMARKS / "robustness_study.py"), "--quick"],
                          capture_output=True, text=True, env=dict(os.environ, MPLBACKEND="Agg"),
                          timeout=600)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    out = proc.stdout
    assert "* - spring, many, add2" in out and "* - spring, add1" in out
    rules = out.split("The held-out check's rule:")[1].split("Losses:")[0]
    # One case under six rules; never accepting the refinement is refine=None
    # itself, so it is never worse than refine=None.
    assert rules.count(" of 1\n") == 12
    never = rules.split("never accept (refine=None)")[1]
    assert never.split("\n")[1].strip() == "- 0 of 1"


def test_scale_study_cpu_limit_stops_a_fit_and_lifts_after():
    """``--sindy-cpu-limit``: a fit past its CPU seconds stops; the limit is gone afterwards."""
    import resource  # noqa: PLC0415
    import time  # noqa: PLC0415

    sys.path.insert(0, str(BENCHMARKS))
    try:
        import scale_study  # noqa: PLC0415
    finally:
        sys.path.remove(str(BENCHMARKS))
    before = resource.getrlimit(resource.RLIMIT_CPU)
    start = time.process_time()
    with pytest.raises(scale_study.CPULimitReached):
        with scale_study.cpu_limit(1.0):
            while time.process_time() - start < 30:
                sum(range(10_000))
    # The kernel counts CPU time by its clock ticks and the limit is whole
    # seconds from the start's: it may fire a tick before process_time
    # reads the second full (measured: 0.998 s), never much earlier.
    assert 0.9 <= time.process_time() - start < 10
    assert resource.getrlimit(resource.RLIMIT_CPU) == before
    with scale_study.cpu_limit(None):
        pass


@pytest.mark.slow
def test_hand_cut_runs_the_default_and_the_hand_cut_route_on_the_same_record(tmp_path):
    proc = subprocess.run([sys.executable, str(BENCHMARKS / "hand_cut.py"), "--scenes",
                           "pendulum", "--seeds", "0", "--output", str(tmp_path)],
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-3000:]
    # The table's lines (a computed row is also printed as it finishes).
    rows = [line.split() for line in proc.stdout.splitlines() if line.startswith("pendulum")]
    assert [row[:3] for row in rows] == [["pendulum", "one", "0"], ["pendulum", "one", "geo"]]
    # Both routes keep the pendulum's two terms on this record.
    assert rows[0][4] == "True" and rows[0][6] == "True"
    assert 0 < float(rows[0][3]) < 0.1 and 0 < float(rows[0][5]) < 0.1
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "pendulum_one_add2_0_search-hand.pkl", "pendulum_one_add2_0_search.pkl"]
