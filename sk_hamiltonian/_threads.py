"""Threads: the BLAS's chosen by problem size, and the package's own pool.

A multi-threaded BLAS pays for its threads on large products only. On small
ones the start-up costs more than it saves, and on a busy machine a second
thread waits for a core that another process holds while the whole product
waits for it. Measured with ``benchmarks/bench_threads.py`` (``A^T A`` by
``dsyrk``, 20 000 rows, 40 000 for the last line; best of 3, wall clock) on
a shared 2-core VM, two runs at load average 12 to 16 (run 1 with the same
code before it became that script):

========  =============  ==================  ==================
columns   multiply-adds  2 threads / 1, run 1  2 threads / 1, run 2
========  =============  ==================  ==================
100       1e8            77                  65
400       1.6e9          7.2                 4.3
800       6.4e9          1.7                 1.2
1 000     2e10           1.3                 0.67
========  =============  ==================  ==================

Below 1e10 multiply-adds the second thread lost in both runs, by far on
small products; above, it won once. The same script on the same VM with a
core to spare tells the other half (2026-11-25, load average 1.2, then with
one CPU-bound competitor started 20 s before, load 1.5-1.7):

========  =============  ===================  ====================
columns   multiply-adds  2 threads / 1, idle  2 threads / 1, busy
========  =============  ===================  ====================
30        9e6            1.08                 0.98
100       1e8            0.59                 2.09
200       4e8            0.45                 1.97
400       1.6e9          0.55                 1.60
800       6.4e9          0.79                 1.37
1 000     2e10           0.53                 1.14
========  =============  ===================  ====================

A second thread pays from about 1e8 multiply-adds when a core is idle, and
costs up to twice the time when it is not. :func:`limit_blas` therefore runs
work below :data:`PARALLEL_FLOPS` on one BLAS thread, work up to
:data:`SERIAL_FLOPS` on one thread unless a core is idle *now*
(:func:`idle_cores`), and leaves larger work to the BLAS as the user
configured it (all cores by default). A BLAS may sum in another order on
another number of threads, so a fit on an idle machine and the same fit on a
busy one agree to round-off, not bit for bit. The BLAS's threads are set
with threadpoolctl, which comes with scikit-learn.

The package's own pool (:func:`thread_pool`) runs independent pieces of
work that release the GIL: passes of the design operator over chunks of
samples (:func:`map_on_idle_cores`) and the compiled kernels over slices of
states (:func:`in_threads`).
"""

import os
import threading
from contextlib import nullcontext

import numpy as np

# Multiply-adds below which a BLAS call or a whole fit runs on one thread
# unless a core is idle (the tables above). A Gram update of n_rows x n_columns
# costs n_rows * n_columns**2 / 2: 1e10 is, e.g., 32 000 rows (8 000 states
# of 4 variables) of 800 columns.
SERIAL_FLOPS = 1e10
# From here to SERIAL_FLOPS, every core when one is idle (the second table).
PARALLEL_FLOPS = 1e8

_controller = None


def _threadpools():
    """One ThreadpoolController per process (scanning the loaded libraries is slow)."""
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    return _controller


def _own_running_tasks():
    """Threads of this process that are runnable now (Linux), counting the caller."""
    running = 0
    for task in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{task}/stat") as handle:
                # "tid (comm) state ...": the name may hold spaces and parentheses.
                state = handle.read().rpartition(")")[2].split()[0]
        except (OSError, IndexError):
            continue
        running += state == "R"
    return max(running, 1)


def idle_cores():
    """Cores that no other process is running on now, besides the caller's own.

    Linux: the runnable tasks of ``/proc/loadavg`` (an instant count, so a
    competitor that started seconds ago counts) minus this process's own
    runnable threads (a BLAS's workers spin for a while after each call).
    Elsewhere the one-minute load average stands in, and where neither is
    available the answer is 0, so that small work stays on one thread.

    Returns
    -------
    idle : float
    """
    cores = os.cpu_count() or 1
    try:
        with open("/proc/loadavg") as handle:
            runnable = int(handle.read().split()[3].split("/")[0])
        others = runnable - _own_running_tasks()
    except (OSError, ValueError, IndexError):
        try:
            others = os.getloadavg()[0] - 1
        except (AttributeError, OSError):
            return 0.0
    return float(cores - 1 - others)


def blas_threads(flops):
    """BLAS threads for work of ``flops`` multiply-adds: 1, or None (as configured).

    One thread below :data:`PARALLEL_FLOPS`, and below :data:`SERIAL_FLOPS`
    unless :func:`idle_cores` finds a core idle; None (the BLAS's own
    setting) otherwise.
    """
    if flops < PARALLEL_FLOPS:
        return 1
    if flops < SERIAL_FLOPS and idle_cores() < 1:
        return 1
    return None


def limit_blas(flops):
    """Context manager running its block on :func:`blas_threads` ``(flops)`` BLAS threads.

    Parameters
    ----------
    flops : float
        Multiply-adds of the work in the block, e.g. ``n_rows * n_columns**2
        / 2`` for a Gram matrix.

    Returns
    -------
    context : context manager
        Limits the BLAS to one thread for small work; does nothing for large
        work (or where threadpoolctl cannot be imported).
    """
    if blas_threads(flops) is None:
        return nullcontext()
    try:
        return _threadpools().limit(limits=1, user_api="blas")
    except ImportError:  # threadpoolctl comes with scikit-learn; be safe anyway
        return nullcontext()


def gram_flops(n_rows, n_columns):
    """Multiply-adds of the Gram matrix (or a dense least-squares solve) of a design."""
    return 0.5 * float(n_rows) * float(n_columns) ** 2


_POOL = None
_POOL_PREFIX = "sk_hamiltonian"


def thread_pool():
    """The package's thread pool (one per process, a worker per core), created on first use."""
    global _POOL
    if _POOL is None:
        from concurrent.futures import ThreadPoolExecutor

        _POOL = ThreadPoolExecutor(os.cpu_count() or 1, thread_name_prefix=_POOL_PREFIX)
    return _POOL


def map_on_idle_cores(function, items):
    """``[function(item) for item in items]``, spread over the cores idle now.

    For independent pieces of NumPy work that release the GIL (a pass of an
    operator over chunks of samples): one thread unless :func:`idle_cores`
    finds a core idle, and then the BLAS on one thread inside each, so that
    the threads do not compete with the BLAS's own. Consecutive items go to
    the same thread and the results come back in order, so that a sum over
    them adds the same terms in the same order whatever the number of
    threads. Called from a worker of the pool, it runs in that worker.
    """
    items = list(items)
    n_threads = 1
    # A worker of the pool waiting on the pool could wait forever.
    if len(items) >= 2 and not threading.current_thread().name.startswith(_POOL_PREFIX):
        n_threads = int(min(len(items), os.cpu_count() or 1, 1 + max(0.0, idle_cores())))
    if n_threads <= 1:
        return [function(item) for item in items]
    bounds = [round(k * len(items) / n_threads) for k in range(n_threads + 1)]

    def run(span):
        return [function(item) for item in items[span[0] : span[1]]]

    with limit_blas(0):
        results = list(thread_pool().map(run, zip(bounds[:-1], bounds[1:])))
    return [result for part in results for result in part]


def in_threads(part, n, minimum):
    """``part(rows)`` over ``n`` rows: in one slice, or one slice per core from ``minimum`` rows.

    The compiled kernels release the GIL, so threads run them in parallel
    (no numba threading layer: nothing to go wrong in forked workers). At
    most ``numba.get_num_threads()`` threads.
    """
    if n < 2 * minimum:  # one slice, whatever the thread count
        part(slice(0, n))
        return
    import numba

    # numba's thread count (NUMBA_NUM_THREADS, numba.set_num_threads), all
    # cores by default, is the knob users of numba know.
    n_threads = min(numba.get_num_threads(), n // max(1, minimum))
    if n_threads <= 1:
        part(slice(0, n))
        return
    bounds = np.linspace(0, n, n_threads + 1).astype(int)
    futures = [thread_pool().submit(part, slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]
    for future in futures:
        future.result()
