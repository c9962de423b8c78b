"""pytest set-up shared by the test suite and the doctests of the package."""

import os
from importlib.util import find_spec

import pytest

# The compiled kernels import numba at the top (the optional "fast" extra);
# without it their modules cannot be collected for doctests, and they have
# none. tests/test_kernels.py skips its compiled cases with the reason.
collect_ignore = []
if find_spec("numba") is None:
    collect_ignore += [f"sk_hamiltonian/_kernels/{name}.py"
                       for name in ("_jit", "_simulate_jit", "_lanes_jit", "_checked_jit")]

# Tests marked slow (whole examples and benchmark runs as subprocesses, long
# searches) are skipped by default, so that the README's `python -m pytest`
# stays a few minutes on two cores; each has a fast counterpart where it
# guards behaviour. CI runs everything with --runslow.
RUNSLOW_VARIABLE = "SK_HAMILTONIAN_RUNSLOW"
SLOW_REASON = f"slow: run with --runslow or {RUNSLOW_VARIABLE}=1"


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False,
                     help=f"also run the tests marked slow (as CI does; or set {RUNSLOW_VARIABLE}=1)")


def run_slow(config):
    """Whether the slow tests run: --runslow, or the environment variable set to a true value."""
    value = os.environ.get(RUNSLOW_VARIABLE, "").strip().lower()
    return config.getoption("--runslow") or value not in ("", "0", "false", "no")


def pytest_collection_modifyitems(config, items):
    if run_slow(config):
        return
    skip = pytest.mark.skip(reason=SLOW_REASON)
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
