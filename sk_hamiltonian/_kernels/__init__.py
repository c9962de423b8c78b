"""Compiled kernels (numba): arrays in, arrays out.

numba is optional (``pip install sk_hamiltonian[fast]``). Nothing here
imports it until a kernel is first asked for, and nothing here imports the
rest of the package: the choice between these kernels and the numpy path is
made above them (:func:`sk_hamiltonian._config.use_numba`), by the model
space and the integrators, which also turn a model space into the arrays the
kernels take (:mod:`sk_hamiltonian._space.compiled`,
:mod:`sk_hamiltonian._space.kernel_tree`,
:mod:`sk_hamiltonian._integrate.compiled`).

- :mod:`._jit`: value, gradient and Hessian of ``sum_j coef[j] phi_j`` (and
  a Hamiltonian's vector field) state by state, along the prefix tree of the
  index set or by flat products;
- :mod:`._lanes_jit`: the value and gradient of one scalar for batches of
  :data:`LANE_ROWS` states or more, through the tree together;
- :mod:`._checked_jit`: the field at a few states with ``predict``'s checks,
  in one compiled call, its arrays packed by :mod:`.packing`;
- :mod:`._simulate_jit`: whole fixed-step integrations as compiled loops.
"""

import threading

# Rows of a batch per thread from which the evaluation runs on every core
# (below, handing the work to threads costs more than it saves).
PARALLEL_ROWS = 256
# States from which a batch goes through the tree in lanes (_lanes_jit), and
# the most states per pass. Measured on the degree-15 model of
# benchmarks/bench_scale.py (3 875 terms, the field of 1 024 states, one
# thread, best of 25 timings of _lanes_jit.fields and _jit.fields, a scratch
# script, 2026-11-25): per state 5.2 us state by state; in lanes 3.5 us at
# 16 states per pass, 2.2 at 32, 1.75 at 64, 1.5 at 128 and 1.4 at 256
# (1.6-1.7 at 192, 320 and 512).
LANE_ROWS = 16
MAX_LANES = 256

_local = threading.local()
_JIT = None


def jit():
    """The module of compiled kernels :mod:`._jit` (imported, and numba with it, on first use)."""
    global _JIT
    if _JIT is None:
        from . import _jit

        _JIT = _jit
    return _JIT


def lanes(n):
    """States per pass for ``n`` states: at most MAX_LANES, in passes of about equal size.

    A multiple of 8 (the last pass repeats a state where that is more than
    ``n`` needs): rows of any other length end in a scalar remainder and
    straddle cache lines (measured: 125 lanes ran 1.3 times slower than
    120 or 128).
    """
    n_passes = -(-n // MAX_LANES)
    return min(MAX_LANES, 8 * -(-n // (8 * n_passes)))


def work(tree, K, m):
    """This thread's work arrays of :func:`._jit.evaluate` for ``tree`` and ``K`` targets (kept between calls)."""
    cache = getattr(_local, "work", None)
    if cache is None:
        cache = _local.work = {}
    key = (id(tree), K)
    entry = cache.get(key)
    if entry is None or entry[0] is not tree:
        if len(cache) >= 16:
            cache.clear()
        entry = cache[key] = (tree, jit().work(tree, K, m))
    return entry[1]
