"""The README's code runs as written, and its set-up commands match CI."""

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
CI = Path(__file__).resolve().parents[1] / ".ci" / "run"


def code_blocks(language):
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_python_examples_run(capsys):
    namespace = {}
    blocks = code_blocks("python")
    assert len(blocks) >= 2
    # Blocks build on each other, as a reader would run them.
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    printed = capsys.readouterr().out
    error = float(re.search(r"max relative error (\S+),", printed).group(1))
    drift = float(re.search(r"energy drift (\S+)", printed).group(1))
    assert error < 1e-2 and drift < 1e-12
    assert set(namespace["search"].best_params_) == {
        "derivativetransformer__degree",
        "hamiltonianregressor__degree",
    }


@pytest.mark.skipif(not CI.exists(), reason="no .ci/run in this checkout")
def test_ci_runs_the_readme_test_command():
    test_command = code_blocks("bash")[1].strip().split("&&")[-1].strip()
    assert test_command.endswith("python -m pytest")
    assert "python -m pytest" in CI.read_text()
