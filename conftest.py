"""pytest set-up shared by the test suite and the doctests of the package."""

from importlib.util import find_spec

# The compiled kernels import numba at the top (the optional "fast" extra);
# without it their modules cannot be collected for doctests, and they have
# none. tests/test_kernels.py skips its compiled cases with the reason.
collect_ignore = []
if find_spec("numba") is None:
    collect_ignore += [f"sk_hamiltonian/_kernels/{name}.py"
                       for name in ("_jit", "_simulate_jit", "_lanes_jit", "_checked_jit")]
