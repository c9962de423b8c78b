"""The ``sk-hamiltonian`` command, run in-process (``main(argv)``)."""

import contextlib
import io
import re
import subprocess
import sys

import joblib
import numpy as np
import pytest

from sk_hamiltonian.__main__ import main
from sk_hamiltonian.datasets import make_trajectories

pytest.importorskip("matplotlib")


def run(argv, capsys):
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def number(pattern, text):
    match = re.search(pattern, text)
    assert match, f"{pattern!r} not in:\n{text}"
    return float(match.group(1))


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    # --quick: the built-in example with 60 trajectories, 4 candidates, T = 5
    # (the full default run takes about 40 s; its timing is in the docs).
    out_dir = tmp_path_factory.mktemp("demo")
    # A module-scoped fixture cannot use capsys: capture by hand.
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(["--quick", "--output", str(out_dir)])
    return status, stdout.getvalue(), stderr.getvalue(), out_dir


def test_default_example_report(demo):
    status, out, err, out_dir = demo
    assert status == 0
    assert "single pendulum" in out and "60 trajectories x 41 samples" in out
    # A progress line per candidate (2 derivative options x 2 degrees).
    assert len(re.findall(r"^\s+\[\d/4\] .* score \d\.\d{4} \+- \d\.\d{4}$", err, re.M)) == 4
    chosen = re.search(r"chosen: (finite differences|Q=(\d+)), n=(\d+) -> (\d+) terms", out)
    assert chosen, out
    model = joblib.load(out_dir / "model.joblib")
    n, n_terms = int(chosen.group(3)), int(chosen.group(4))
    assert model[-1].degree == n and model[-1].n_terms_ == n_terms
    assert n_terms == (n + 2) * (n + 1) // 2 - 1
    if chosen.group(2):
        assert model[0].degree == int(chosen.group(2))
    else:
        assert model[0].method == "finite_difference"
    # The learned pendulum H~ leads with its harmonic part, g q^2 / 2 + p^2 / 2
    # (within the noise), ahead of the higher-order terms of 1 - cos q.
    assert 4.4 < number(r"H~ = (\S+) q\^2 ", out) < 5.4
    assert 0.4 < number(r"H~ = \S+ q\^2 \+ (\S+) p\^2 ", out) < 0.6
    sp = number(r"SP\s+relative error at T: (\S+)", out)
    non_sp = number(r"non-SP\s+relative error at T: (\S+)", out)
    assert 0 < sp < 1 and non_sp > 0
    rk4 = number(r"H~ drift max\|H~\(t\) - H~\(0\)\|, RK4: (\S+)", out)
    avf = number(r"H~ drift max\|H~\(t\) - H~\(0\)\|, AVF: (\S+)", out)
    assert avf < 1e-10 < rk4  # AVF conserves H~ to round-off, RK4 does not
    assert number(r"fit time: (\S+) s", out) > 0
    figure = out_dir / "report.png"
    assert f"figure: {figure}" in out
    assert figure.stat().st_size > 10_000
    assert "u0* = (-3.876, -1.193)" in out


def test_model_from_the_report_predicts(demo):
    *_, out_dir = demo
    model = joblib.load(out_dir / "model.joblib")
    X = make_trajectories("single_pendulum", 3, 40, 0.01, random_state=5)
    assert 0.5 < model.score(X) <= 1.0


@pytest.fixture(scope="module")
def pendulum_data():
    return make_trajectories("single_pendulum", 40, 30, 0.02, noise=0.01, random_state=3)


def test_npz_file(tmp_path, capsys, pendulum_data):
    path = tmp_path / "runs.npz"
    np.savez(path, trajectories=pendulum_data, other=np.zeros(3))
    out_dir = tmp_path / "out"
    status, out, err = run(
        [str(path), "--dt", "0.02", "--output", str(out_dir), "--degrees", "4", "6",
         "--denoise-degrees", "fd", "6"], capsys,
    )
    assert status == 0
    assert "40 trajectories x 31 samples, 2 states, dt=0.02" in out
    assert "relative error at T" not in out  # no true system to compare with
    assert "first observation of the first trajectory" in out
    assert (out_dir / "model.joblib").exists() and (out_dir / "report.png").exists()
    # Horizon: 10 trajectory lengths by default.
    assert "up to T = 6 " in out


def test_csv_file_with_unequal_lengths_and_names(tmp_path, capsys, pendulum_data):
    rows = ["trajectory,mom,angle"]
    for k, T in enumerate(pendulum_data):
        for p, q in T[: 20 + k % 11]:
            rows.append(f"{k},{float(p)!r},{float(q)!r}")
    path = tmp_path / "runs.csv"
    path.write_text("\n".join(rows) + "\n")
    status, out, _ = run(
        [str(path), "--dt", "0.02", "--output", str(tmp_path), "--degrees", "6",
         "--denoise-degrees", "fd", "--cv", "4", "--horizon", "2"], capsys,
    )
    assert status == 0
    assert "40 trajectories x 20-30 samples" in out
    assert re.search(r"H~ = \d\.\d+ angle\^2 \+ 0\.\d+ mom\^2 ", out), out
    assert "up to T = 2 " in out


def test_missing_matplotlib_skips_the_figure(tmp_path, capsys, monkeypatch, pendulum_data):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib -> ImportError
    path = tmp_path / "runs.npz"
    np.savez(path, pendulum_data)
    status, out, _ = run(
        [str(path), "--dt", "0.02", "--output", str(tmp_path), "--degrees", "6",
         "--denoise-degrees", "fd"], capsys,
    )
    assert status == 0
    assert "figure: skipped, matplotlib is not installed" in out
    assert not (tmp_path / "report.png").exists()
    assert (tmp_path / "model.joblib").exists()


def error_of(argv, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    out, err = capsys.readouterr()
    assert exit_info.value.code == 2
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("sk-hamiltonian: error: ")
    return lines[0]


def test_error_missing_file(tmp_path, capsys):
    line = error_of([str(tmp_path / "nope.npz"), "--dt", "0.1"], capsys)
    assert "file not found" in line and "nope.npz" in line


def test_error_missing_dt(tmp_path, capsys, pendulum_data):
    path = tmp_path / "runs.npz"
    np.savez(path, trajectories=pendulum_data)
    assert "--dt is required" in error_of([str(path)], capsys)


@pytest.mark.parametrize(
    "array,message",
    [
        (np.zeros((30, 2)), "expected (n_trajectories, n_times, 2d)"),
        (np.zeros((5, 30, 3)), "even"),
    ],
)
def test_error_wrong_layout(tmp_path, capsys, array, message):
    path = tmp_path / "bad.npz"
    np.savez(path, trajectories=array)
    assert message in error_of([str(path), "--dt", "0.1"], capsys)


def test_error_wrong_csv_header_and_file_type(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("p,q\n1,2\n")
    assert "header must read 'trajectory," in error_of([str(path), "--dt", "0.1"], capsys)
    other = tmp_path / "data.txt"
    other.write_text("1 2\n")
    assert "use .npz or .csv" in error_of([str(other), "--dt", "0.1"], capsys)


def test_error_bad_options(tmp_path, capsys, pendulum_data):
    path = tmp_path / "runs.npz"
    np.savez(path, trajectories=pendulum_data)
    assert "neither an integer nor 'fd'" in error_of(
        [str(path), "--dt", "0.02", "--denoise-degrees", "x"], capsys
    )
    assert "--dt must be positive" in error_of([str(path), "--dt", "-1"], capsys)
    assert "cannot fill 50 folds" in error_of([str(path), "--dt", "0.02", "--cv", "50"], capsys)


def test_help_documents_the_options(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    for option in ("--dt", "--output", "--degrees", "--denoise-degrees", "--cv", "--horizon",
                   "--seed", ".npz", ".csv", "model.joblib", "report.png", "exit status"):
        assert option in out
    assert "--quick" not in out


def test_python_dash_m_entry_point():
    result = subprocess.run(
        [sys.executable, "-m", "sk_hamiltonian", "--help"], capture_output=True, text=True,
        timeout=60,
    )
    assert result.returncode == 0
    assert result.stdout.startswith("usage: sk-hamiltonian")


def test_error_output_is_a_file(tmp_path, capsys, pendulum_data):
    path = tmp_path / "runs.npz"
    np.savez(path, trajectories=pendulum_data)
    blocker = tmp_path / "taken"
    blocker.write_text("")
    line = error_of([str(path), "--dt", "0.02", "--output", str(blocker)], capsys)
    assert "cannot create the output directory" in line


def test_short_trajectories_drop_impossible_candidates(tmp_path, capsys):
    # 4 samples per trajectory: Q=3 would interpolate the noise and Q=5 is
    # impossible; only finite differences and Q=2 remain.
    X = make_trajectories("single_pendulum", 200, 3, 0.01, random_state=0)
    path = tmp_path / "short.npz"
    np.savez(path, trajectories=X)
    status, out, err = run(
        [str(path), "--dt", "0.01", "--output", str(tmp_path), "--degrees", "4",
         "--denoise-degrees", "fd", "2", "3", "5"], capsys,
    )
    assert status == 0
    assert "note: dropped de-noising degrees [3, 5]: trajectories have 4 samples" in out
    assert len(re.findall(r"^\s+\[\d/2\]", err, re.M)) == 2
