"""AVF without numba: a long run warns once that the ``fast`` extra removes its cost."""

import warnings

import numpy as np

import sk_hamiltonian._numba
from sk_hamiltonian import HamiltonianRegressor
from sk_hamiltonian._integrate import simulation


def _slow_avf_warnings(method, t, max_step):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        simulation.warn_slow_avf(method, t, max_step)
    return [w for w in caught if "sk_hamiltonian[fast]" in str(w.message)]


def test_the_threshold_counts_steps_not_output_times(monkeypatch):
    monkeypatch.setattr(sk_hamiltonian._numba, "_NUMBA", False)
    limit = simulation.SLOW_AVF_STEPS
    assert limit == 10_000  # as simulate's docstring, the docs and the CLI help say
    t = np.linspace(0.0, 1.0, 11)  # ten intervals of 0.1
    # A hair above 0.1 / n so that each interval takes exactly n steps.
    assert not _slow_avf_warnings("avf", t, 0.1 / 1000 * (1 + 1e-6))  # exactly the limit
    (warning,) = _slow_avf_warnings("avf", t, 0.1 / 1001 * (1 + 1e-6))
    message = str(warning.message)
    assert warning.category is UserWarning
    assert f"{limit + 10:,}" in message and "method='avf'" in message
    assert 'pip install "sk_hamiltonian[fast]"' in message
    # Other methods are compiled or not, and as cheap as RK4 either way.
    assert not _slow_avf_warnings("rk4", t, 1e-6)


def test_no_warning_with_numba(monkeypatch):
    monkeypatch.setattr(sk_hamiltonian._numba, "_NUMBA", True)
    assert not _slow_avf_warnings("avf", np.linspace(0.0, 1.0, 11), 1e-6)


def _oscillator():
    X = np.random.default_rng(0).uniform(-1, 1, size=(100, 2))
    return HamiltonianRegressor(degree=2).fit(X, np.column_stack([-X[:, 1], X[:, 0]]))


def test_simulate_warns_once_per_call_at_its_caller(monkeypatch):
    monkeypatch.setattr(sk_hamiltonian._numba, "_NUMBA", False)
    # A lower limit keeps the run short; the limit itself is tested above.
    monkeypatch.setattr(simulation, "SLOW_AVF_STEPS", 20)
    model = _oscillator()
    t = np.linspace(0.0, 1.0, 11)
    for _ in range(2):  # "once per call": the second call warns again
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model.simulate([[0.1, 0.2], [0.3, 0.0]], t, method="avf", max_step=0.02)
        slow = [w for w in caught if "sk_hamiltonian[fast]" in str(w.message)]
        assert len(slow) == 1 and slow[0].filename == __file__
        assert "50 integration steps" in str(slow[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.simulate([0.1, 0.2], t, method="avf", max_step=0.1)  # 10 steps: quiet
        model.simulate([0.1, 0.2], t, method="rk4", max_step=0.02)



def test_the_command_line_simulate_prints_the_warning_as_a_note(monkeypatch, tmp_path, capsys):
    from sk_hamiltonian import save
    from sk_hamiltonian.__main__ import main

    monkeypatch.setattr(sk_hamiltonian._numba, "_NUMBA", False)
    monkeypatch.setattr(simulation, "SLOW_AVF_STEPS", 20)
    save(_oscillator(), tmp_path / "model.skh")
    argv = ["simulate", str(tmp_path / "model.skh"), "--x0", "0.1", "0.2", "--t-end", "1",
            "--dt", "0.1", "--max-step", "0.02", "-o", str(tmp_path / "run.csv")]
    assert main([*argv, "--method", "avf"]) == 0
    notes = [line for line in capsys.readouterr().out.splitlines()
             if line.startswith("note: method='avf' takes 50 integration steps")]
    assert len(notes) == 1 and 'pip install "sk_hamiltonian[fast]"' in notes[0]
    assert main([*argv, "--method", "rk4"]) == 0
    assert "sk_hamiltonian[fast]" not in capsys.readouterr().out
