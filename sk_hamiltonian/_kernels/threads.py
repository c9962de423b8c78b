"""BLAS threads chosen by problem size (threadpoolctl, which comes with scikit-learn).

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
small products; above, it won once. :func:`limit_blas` therefore runs work
below :data:`SERIAL_FLOPS` on one BLAS thread and leaves the BLAS as the
user configured it (all cores by default) for larger work.
"""

from contextlib import nullcontext

# Multiply-adds below which a BLAS call or a whole fit runs on one thread
# (the table above). A Gram update of n_rows x n_columns costs n_rows *
# n_columns**2 / 2: 1e10 is, e.g., 32 000 rows (8 000 states of 4
# variables) of 800 columns.
SERIAL_FLOPS = 1e10

_controller = None


def _threadpools():
    """One ThreadpoolController per process (scanning the loaded libraries is slow)."""
    global _controller
    if _controller is None:
        from threadpoolctl import ThreadpoolController

        _controller = ThreadpoolController()
    return _controller


def blas_threads(flops):
    """BLAS threads for work of ``flops`` multiply-adds: 1 below :data:`SERIAL_FLOPS`, else None (as configured)."""
    return 1 if flops < SERIAL_FLOPS else None


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
