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


@pytest.fixture(scope="session")
def small_angle_record():
    """One pendulum record at small angles: 3 001 samples, dt = 0.02, 2 % relative noise.

    Along one orbit ``p**2`` is a function of ``q``: the search's tied
    finalists keep ``p^2, q^2`` and a six-term series with ``p^2 q^2`` and
    ``p^2 q^4``, which stage 3 prunes (tests/test_named_terms.py,
    tests/test_cli.py).
    """
    import numpy as np

    from sk_hamiltonian.datasets import single_pendulum

    system = single_pendulum()
    box = np.asarray(system.domain, dtype=float)
    rng = np.random.default_rng(12)
    x0 = []
    while not x0:
        x = rng.uniform(box[:, 0], box[:, 1], size=(256, 2))
        x0.extend(x[system.hamiltonian(x) < 5.0])
    X = system.solve(np.array(x0[:1]), 0.02 * np.arange(3001), max_step=0.002)
    return X * (1 + 0.02 * rng.standard_normal(X.shape))
