"""BLAS threads chosen by problem size and machine load (threadpoolctl, from scikit-learn).

A multi-threaded BLAS pays for its threads on large products on free cores
only. On small products the start-up costs more than it saves, and on a busy
machine a second thread waits for a core that another process holds: every
fit then waits for its slowest thread. Measured on a shared 2-core VM at load
average 12 (``A^T A`` by ``dsyrk``, 20 000 rows; best of 3, wall clock):

========  ===========  =========  ==========
columns   multiply-add 1 thread   2 threads
========  ===========  =========  ==========
100       1e8          21 ms      1 601 ms
400       1.6e9        214 ms     1 546 ms
800       6.4e9        967 ms     1 611 ms
1 000     2e10         2 564 ms   3 334 ms
========  ===========  =========  ==========

(40 000 rows for the last line.) :func:`limit_blas` therefore runs a piece of
work on one BLAS thread when it is small (below :data:`SERIAL_FLOPS`) or when
the cores are taken (a one-minute load average above the number of cores
minus one half, this process's own thread counting one), and leaves the BLAS
as the user configured it otherwise (all cores by default).
"""

import os
from contextlib import nullcontext

# Multiply-adds below which a BLAS call or a whole fit runs on one thread.
# A Gram update of n_rows x n_columns costs n_rows * n_columns**2 / 2; 2e9
# is, e.g., 100 000 rows of 200 columns, about 0.2 s on one core.
SERIAL_FLOPS = 2e9

_controller = None


def _threadpools():
    """One ThreadpoolController per process (scanning the loaded libraries is slow)."""
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    return _controller


def cores_busy():
    """Whether other processes keep the cores busy (one-minute load average; False if unknown)."""
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):  # not on every platform
        return False
    return load > (os.cpu_count() or 1) - 0.5


def blas_threads(flops):
    """BLAS threads for work of ``flops`` multiply-adds: 1 if small or the cores are busy, else None."""
    return 1 if flops < SERIAL_FLOPS or cores_busy() else None


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
