"""The numbers README.md quotes from runs, measured again and compared with the text.

README.md quotes what three runs print:

``first-example``
    the README's first Python block (the search on the paper's noisy
    pendulum): the formula in its ``# H~ = ...`` comment and the line it
    prints, ``max relative error ..., energy drift ...``;
``default``
    ``sk-hamiltonian --no-resample``: the learned formula, the SP relative
    error at T and the H~ drift with AVF. The resampling changes neither the
    formula's point estimate nor the errors (the chosen model is refitted on
    all the data and refined again), only adds intervals, so the run skips it;
``paper-grid``
    ``sk-hamiltonian --paper-grid --no-resample``: the chosen Q and n, the
    number of terms and the SP relative error at T.

Each quote sits in README.md between ``<!-- numbers: NAME ... -->`` and
``<!-- /numbers -->`` (the first example's formula is the comment in its code
block). ``tests/test_readme.py`` parses them with :func:`readme_claims`,
measures with :func:`measure` and fails on every :func:`disagreements`. When
the program changes, run this script and copy what it prints into README.md
(and the first block's comment into docs/index.rst, which shows the same
block). Timings are printed for the text but not compared: they follow the
machine's load.

Run (3 minutes on two shared cores, measured under load)::

    python benchmarks/readme_numbers.py
"""

import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from decimal import Decimal
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
# The command's arguments for each quoted run (the first example is README code).
COMMANDS = {
    "default": ["--no-resample"],
    "paper-grid": ["--paper-grid", "--no-resample"],
}
NAMES = ("first-example", *COMMANDS)
# An energy drift is round-off: its digits change with the platform's BLAS and
# summation order, so a quote holds if it is round-off too (below
# ROUND_OFF) and within this factor of the measured drift.
ROUND_OFF, DRIFT_FACTOR = 1e-12, 10.0


def formula_terms(text):
    """``{"cos(q)": "-9.795", "p^2": "0.5007"}`` from ``"H~ = -9.795 cos(q) + 0.5007 p^2 + const"``.

    Intervals ``(±h)`` and the summary of smaller terms are dropped; the
    coefficients stay text, so that their written precision can be read.
    """
    body = text.strip().strip("`").split(";")[0]
    body = re.sub(r"^H~ = ", "", body)
    body = re.sub(r" \(±[^)]*\)", "", body)
    body = re.sub(r" \+ \.\.\. \(.*?\)", "", body)
    body = re.sub(r" \+ const$", "", body.strip())
    terms = {}
    for sign, value, term in re.findall(r"([+-]?) ?(\d[\d.]*(?:e[+-]?\d+)?) (\S+)", body):
        terms[term] = ("-" if sign == "-" else "") + value
    return terms


def readme_claims(text):
    """The numbers README.md quotes, as written: ``{run: {quantity: text}}``."""
    regions = dict(re.findall(r"<!-- numbers: ([\w-]+)[^>]*-->(.*?)<!-- /numbers -->",
                              text, flags=re.S))
    missing = [name for name in NAMES if name not in regions]
    if missing:
        raise ValueError(f"README.md has no marked numbers of {missing}")
    claims = {name: {} for name in NAMES}
    first_block = re.search(r"```python\n(.*?)```", text, flags=re.S).group(1)
    comment = re.search(r"# (H~ = .*)$", first_block, flags=re.M)
    claims["first-example"]["formula"] = comment and comment.group(1)
    printed = re.search(r"`max relative error (\S+), energy drift (\S+)`",
                        regions["first-example"])
    if printed:
        claims["first-example"].update(error=printed.group(1), drift=printed.group(2))
    default = regions["default"]
    claims["default"].update(
        formula=_group(r"`(H~ = [^`]*)`", default),
        error=_group(r"relative error of (\S+) at T = ", default),
        horizon=_group(r"relative error of \S+ at T = (\d+)", default),
        drift=_group(r"H~ to (\S+) with AVF", default),
    )
    grid = re.search(r"Q = (\d+), n = (\d+), (\d+) terms, error (\S+) at\s+T = (\d+)",
                     regions["paper-grid"])
    if grid:
        claims["paper-grid"].update(zip(("Q", "n", "terms", "error", "horizon"), grid.groups()))
    empty = [f"{name}: {key}" for name, quoted in claims.items()
             for key, value in quoted.items() if value is None]
    if empty or not all(claims.values()):
        raise ValueError(f"README.md's marked numbers cannot be read: {empty or claims}")
    return claims


def _group(pattern, text):
    match = re.search(pattern, text, flags=re.M)
    return match and match.group(1)


def run_first_example(cwd):
    """The README's first Python block in a fresh interpreter (warnings as errors): its stdout and CPU seconds."""
    block = re.search(r"```python\n(.*?)```", README.read_text(), flags=re.S).group(1)
    return _run([sys.executable, "-W", "error", "-c", block], cwd)


def run_command(arguments, cwd):
    """``python -m sk_hamiltonian ARGUMENTS`` writing into ``cwd``: its stdout and CPU seconds."""
    return _run([sys.executable, "-m", "sk_hamiltonian", *arguments, "--output",
                 str(Path(cwd) / "out")], cwd)


def _run(command, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    result = subprocess.run(command, capture_output=True, text=True, cwd=cwd, env=env,
                            timeout=1200)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if result.returncode != 0:
        raise RuntimeError(f"{command[1:3]} failed:\n{result.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return result.stdout, cpu


def read_first_example(printed):
    """What the first example printed, as ``{quantity: text}``."""
    line = re.search(r"max relative error (\S+), energy drift (\S+)", printed)
    return {"formula": printed.splitlines()[0], "error": line.group(1), "drift": line.group(2)}


def read_command(printed):
    """What a run of the command printed, as ``{quantity: text}``."""
    numbers = {
        "formula": _group(r"^learned: (H~ = .*)$", printed),
        "error": _group(r"^\s+SP\s+relative error at T: (\S+)", printed),
        "horizon": _group(r"up to T = (\S+) ", printed),
        "drift": _group(r"H~ drift max\|H~\(t\) - H~\(0\)\|, AVF: (\S+)", printed),
        "search_s": _group(r"^fit time: (\S+) s", printed),
    }
    chosen = re.search(r"^chosen: (?:Q=(\d+)|(finite differences)), n=(\d+) -> (\d+) terms?",
                       printed, flags=re.M)
    if chosen:
        numbers.update(Q=chosen.group(1) or "fd", n=chosen.group(3), terms=chosen.group(4))
    return numbers


def measure(workdir):
    """Run the three quoted runs in ``workdir``: ``{run: {quantity: text}}`` and their CPU seconds."""
    printed, cpu = run_first_example(workdir)
    measured, seconds = {"first-example": read_first_example(printed)}, {"first-example": cpu}
    for name, arguments in COMMANDS.items():
        folder = Path(workdir) / name
        folder.mkdir(exist_ok=True)
        printed, seconds[name] = run_command(arguments, folder)
        measured[name] = read_command(printed)
    return measured, seconds


def agrees(quoted, value):
    """Whether a number written as ``quoted`` is ``value`` to its last written digit.

    One unit of that digit either way: the README rounds, and a value near a
    rounding boundary may round either way on another platform.
    """
    unit = Decimal(10) ** Decimal(quoted).as_tuple().exponent
    return abs(Decimal(str(float(value))) - Decimal(quoted)) <= unit


def disagreements(claims, measured):
    """Each quoted number that the measured runs do not bear out, in words."""
    found = []
    for name, quoted in claims.items():
        got = measured[name]
        for key, text in quoted.items():
            value = got.get(key)
            if value is None:
                found.append(f"{name}: {key} {text!r} quoted, but the run printed none")
            elif key == "formula":
                found += _formula_disagreements(name, text, value)
            elif key == "drift":
                if not (float(text) < ROUND_OFF and float(value) < ROUND_OFF
                        and 1 / DRIFT_FACTOR <= float(text) / float(value) <= DRIFT_FACTOR):
                    found.append(f"{name}: drift {text} quoted, {value} measured")
            elif key == "error":
                if not agrees(text, value):
                    found.append(f"{name}: {key} {text} quoted, {value} measured")
            elif text != value:
                found.append(f"{name}: {key} {text} quoted, {value} measured")
    return found


def _formula_disagreements(name, quoted, printed):
    want, got = formula_terms(quoted), formula_terms(printed)
    if set(want) != set(got):
        return [f"{name}: terms {sorted(want)} quoted, {sorted(got)} printed ({printed})"]
    return [f"{name}: coefficient of {term} {want[term]} quoted, {got[term]} printed"
            for term in want if not agrees(want[term], got[term])]


def suggested_text(measured, seconds):
    """What README.md should quote, in its own words and precision."""
    first, default, grid = (measured[name] for name in NAMES)
    formula = default["formula"].split(";")[0].removesuffix(" + const")
    return "\n".join([
        "first example (README's first Python block; also docs/index.rst):",
        f"  comment: # {first['formula']}",
        f"  text:    it printed `max relative error {first['error']}, energy drift "
        f"{first['drift']}` ({seconds['first-example']:.0f} s of CPU)",
        "default run (sk-hamiltonian --no-resample):",
        f"  text:    (`{formula}`), reaches a relative error of {float(default['error']):.2g} "
        f"at T = {default['horizon']} ... keeps H~ to {float(default['drift']):.0e} with AVF; "
        f"its search took {default['search_s']} s",
        "paper grid (sk-hamiltonian --paper-grid --no-resample):",
        f"  text:    Q = {grid['Q']}, n = {grid['n']}, {grid['terms']} terms, error "
        f"{float(grid['error']):.2g} at T = {grid['horizon']}",
    ])


def main():
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as workdir:
        measured, seconds = measure(workdir)
    print(suggested_text(measured, seconds))
    print(f"\n(measured in {time.perf_counter() - start:.0f} s)")
    try:
        found = disagreements(readme_claims(README.read_text()), measured)
    except ValueError as error:
        found = [str(error)]
    print("README.md agrees with these runs." if not found else
          "README.md disagrees:\n  " + "\n  ".join(found))
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
