"""The README's and the docs front page's code runs as pasted, warning-free, and CI matches.

Each snippet runs on its own in a fresh interpreter (as a reader pastes it),
with every warning turned into an error: a snippet that expects a warning
must handle it in its own code, with the reason beside it. That takes half a
minute on two cores (the first snippet's reference solution alone takes most
of it), so those runs are marked slow (run with ``--runslow``; CI does). In the
default run the snippets are checked to find the package's names they import.

The numbers the README quotes from runs (the first example's, the command's)
are measured again by ``benchmarks/readme_numbers.py`` and compared with the
text, in a slow test too; the default run checks that they can be read.
"""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from import_check import unresolved_imports

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
INDEX = ROOT / "docs" / "index.rst"
CI = ROOT / ".ci" / "run"

sys.path.insert(0, str(ROOT / "benchmarks"))
import readme_numbers  # noqa: E402


def code_blocks(language):
    return re.findall(rf"```{language}\n(.*?)```", README.read_text(), flags=re.S)


def rst_python_blocks(path):
    blocks = re.findall(
        r"^\.\. code-block:: python\n\n((?:(?:    .*)?\n)+)", path.read_text(), flags=re.M
    )
    return [textwrap.dedent(block) for block in blocks]


def run_fresh(code, cwd):
    """Run ``code`` in a new interpreter with warnings as errors; return its stdout."""
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    result = subprocess.run(
        [sys.executable, "-W", "error", "-c", code], capture_output=True, text=True,
        cwd=cwd, env=env, timeout=600,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == "", result.stderr
    return result.stdout


def check_hamiltonian_example(printed, largest_error=1e-2):
    error = float(re.search(r"max relative error (\S+),", printed).group(1))
    drift = float(re.search(r"energy drift (\S+)", printed).group(1))
    assert error < largest_error and drift < 1e-12


def check_search_example(printed):
    # The pendulum's two terms from 8 % noise; measured 9.5e-3 as the largest
    # relative error over [0, 20] with the coefficients refined on the
    # trajectories (4.4e-2 with the least-squares ones).
    assert printed.startswith("H~ = -9.7"), printed
    assert re.match(r"H~ = -9\.\d+ cos\(q\) \+ 0\.\d+ p\^2 \+ const\n", printed), printed
    check_hamiltonian_example(printed, largest_error=0.03)


def test_readme_snippets_find_what_they_import():
    blocks = code_blocks("python")
    assert len(blocks) == 6
    for i, block in enumerate(blocks):
        assert not unresolved_imports(block), (i, unresolved_imports(block))


@pytest.fixture(scope="module")
def first_example_printed(tmp_path_factory):
    # Run once for the two slow tests that read it (the search takes ~20 s).
    return run_fresh(code_blocks("python")[0], tmp_path_factory.mktemp("first_example"))


@pytest.mark.slow
def test_readme_snippets_run_as_pasted(tmp_path, first_example_printed):
    blocks = code_blocks("python")
    assert len(blocks) == 6
    check_search_example(first_example_printed)
    check_hamiltonian_example(run_fresh(blocks[1], tmp_path))
    printed = run_fresh(blocks[2], tmp_path)
    # The trajectory fit in a pipeline: accepted, the two terms with their
    # intervals, and the noise it estimated (uniform 8 %: 0.08 / sqrt(3)).
    assert re.match(r"refined H~ = -9\.\d+ \(±[\d.]+\) cos\(q\) \+ 0\.\d+ \(±[\d.]+\) "
                    r"p\^2 \+ const \(90% intervals of the trajectory fit\)\n", printed), printed
    assert "noise (relative sd): [0.046 0.046]" in printed, printed
    blocks = blocks[:2] + blocks[3:]
    printed = run_fresh(blocks[2], tmp_path)
    chosen = re.search(r"\{'derivativetransformer__degree': (\d+), "
                       r"'hamiltonianregressor__degree': (\d+)\} (\d+) terms", printed)
    assert chosen, printed
    n, n_terms = int(chosen.group(2)), int(chosen.group(3))
    assert n_terms == (n + 2) * (n + 1) // 2 - 1
    printed = run_fresh(blocks[3], tmp_path)
    # The sparse pendulum: two terms, the formula of its Hamiltonian.
    assert printed.startswith("2 terms: H~ = -9.81 cos(q) + 0.4991 p^2"), printed
    printed = run_fresh(blocks[4], tmp_path)
    assert printed.strip() == "identical predictions: True"
    assert (tmp_path / "oscillator.skh").exists()


def test_readme_quotes_its_numbers_where_they_can_be_checked():
    claims = readme_numbers.readme_claims(README.read_text())
    # Every run the README quotes, with what the slow test below compares.
    assert {name: sorted(quoted) for name, quoted in claims.items()} == {
        "first-example": ["drift", "error", "formula"],
        "default": ["drift", "error", "formula", "horizon"],
        "paper-grid": ["Q", "error", "horizon", "n", "terms"],
    }
    for name in ("first-example", "default"):
        assert readme_numbers.formula_terms(claims[name]["formula"]), claims[name]


def test_readme_numbers_comparison_finds_a_stale_digit():
    claims = {"first-example": {"formula": "H~ = -9.795 cos(q) + 0.5007 p^2 + const",
                                "error": "9.5e-03", "drift": "1.5e-13"}}
    printed = {"formula": "H~ = -9.7951 cos(q) + 0.5007 p^2 + const",
               "error": "0.009512", "drift": "3.1e-14"}
    assert readme_numbers.disagreements(claims, {"first-example": printed}) == []
    # Two units off in a written digit, a term more, a drift beyond round-off:
    # each is found.
    for key, value, expected in [
        ("formula", "H~ = -9.797 cos(q) + 0.5007 p^2 + const", "coefficient of cos(q)"),
        ("formula", "H~ = -9.795 cos(q) + 0.5007 p^2 + 0.01 q^2 + const", "terms"),
        ("error", "0.0097", "error 9.5e-03 quoted"),
        ("drift", "2e-12", "drift 1.5e-13 quoted"),
    ]:
        found = readme_numbers.disagreements(claims, {"first-example": {**printed, key: value}})
        assert len(found) == 1 and expected in found[0], found


@pytest.mark.slow
def test_readme_numbers_are_what_the_runs_print(tmp_path, first_example_printed):
    claims = readme_numbers.readme_claims(README.read_text())
    measured = {"first-example": readme_numbers.read_first_example(first_example_printed)}
    for name, arguments in readme_numbers.COMMANDS.items():
        printed, _ = readme_numbers.run_command(arguments, tmp_path)
        measured[name] = readme_numbers.read_command(printed)
    found = readme_numbers.disagreements(claims, measured)
    assert not found, ("README.md's numbers are stale; run python benchmarks/readme_numbers.py "
                       "and copy what it prints:\n" + "\n".join(found))


def test_docs_front_page_shows_the_readme_first_example():
    (block,) = rst_python_blocks(INDEX)
    # The front page shows the README's first example, not a variant of it.
    assert block.strip() == code_blocks("python")[0].strip()


@pytest.mark.slow
def test_docs_front_page_snippet_runs_as_pasted(tmp_path):
    (block,) = rst_python_blocks(INDEX)
    check_search_example(run_fresh(block, tmp_path))


@pytest.mark.skipif(not CI.exists(), reason="no .ci/run in this checkout")
def test_ci_runs_the_readme_test_command():
    test_command = code_blocks("bash")[1].strip().split("&&")[-1].strip()
    assert test_command.endswith("python -m pytest")
    # CI runs everything: the same command with the slow tests, which the
    # README gives beside the default one.
    assert re.search(r"^python -m pytest --runslow$", CI.read_text(), flags=re.M)
    assert "python -m pytest --runslow" in README.read_text()


def test_no_path_outside_the_repository_is_committed():
    # Machine paths (home and work directories, temporary folders, files beside
    # the checkout) mean nothing in another checkout; state the fact instead.
    listing = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True)
    if listing.returncode != 0:
        pytest.skip("not a git checkout")
    pattern = re.compile("|".join(["/" + "work/", r"\.\./" + "shared", "/" + "home/",
                                   "/" + "root/", "/" + "tmp/"]))
    found = []
    for name in listing.stdout.splitlines():
        path = ROOT / name
        if not path.is_file() or path.suffix in {".png", ".npz", ".npy", ".inv", ".pickle"}:
            continue
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue
        found += [f"{name}:{i}" for i, line in enumerate(text.splitlines(), 1)
                  if pattern.search(line)]
    assert not found, found
