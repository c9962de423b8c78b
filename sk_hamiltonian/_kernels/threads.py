"""BLAS threads chosen by problem size (threadpoolctl, a dependency of scikit-learn).

A multi-threaded BLAS pays for its threads on large products only. On small
ones the start-up and, on a busy machine, the oversubscription of cores cost
more than they save: every small fit of a search (the command line's, a
GridSearchCV's) then waits for threads spinning on cores that another
process needs. :func:`limit_blas` runs a piece of work on one BLAS thread
when its size is below :data:`SERIAL_FLOPS` and leaves the BLAS as the user
configured it otherwise (all cores by default).
"""

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
