"""How much memory a fit or a simulation would take, checked before it is taken.

A fit's memory is set by its number of unknowns ``n`` (and, for the dense
solver, its rows): every solver holds a few ``n x n`` matrices (the normal
matrix and its Cholesky factor, or a preconditioner), and ``"lstsq"`` the
whole design. Counting the unknowns costs microseconds
(:func:`~sk_hamiltonian._space.index_set.count_index_set`), so an
impossible request (``degree=10**6``, or 60 in four variables: 635 375
unknowns and 9.7 TB) is refused at once, with the sizes and the remedies,
instead of running for minutes into a bare ``MemoryError``. The limit is
``memory_limit`` of :func:`sk_hamiltonian.set_config`: by default three
quarters of the memory this process may use (the machine's physical memory,
or a container's limit, or what the process's own ``ulimit -v`` leaves).
"""

import math
import os

from ._config import memory_limit_setting

# Share of the physical memory a fit may plan to use with memory_limit="auto".
AUTO_FRACTION = 0.75
# Assumed physical memory where it cannot be read.
FALLBACK_MEMORY = 8 * 2**30
# Bytes of a float64.
FLOAT = 8
# n x n float64 matrices a solver holds at its peak: the normal matrix, its
# mirrored or equilibrated copy, and its Cholesky factor (or the
# preconditioner, its equilibrated copy and factor); "lstsq" holds the
# design of at least n rows with its copy (below), and its factors.
SQUARE_MATRICES = {"lstsq": 1, "normal": 3, "iterative": 3, "sketch": 3}
# What every fit of n unknowns holds at least, in n x n matrices: three
# (for "lstsq", two copies of a design of at least n rows and one more).
LEAST_SQUARE_MATRICES = 3
# Rows of the sketch per unknown (sk_hamiltonian._sketch), held beside them.
SKETCH_ROWS = 3
# The row blocks a streamed design is assembled in (float64, with a copy):
# see _design.BLOCK_ENTRIES.
BLOCK_BYTES = 2 * 8_000_000 * FLOAT
# Integer tables per unknown and state variable (the index set, its sort
# keys and the space's tables), in bytes.
INDEX_BYTES = 4 * FLOAT


def physical_memory():
    """Bytes of memory this process may use; None if unknown.

    The machine's physical memory, or less: a container's limit, or what is
    left of this process's own limit on its address space or data
    (``ulimit -v``, ``ulimit -d``) beyond what it has mapped already.
    """
    total = None
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, OSError, ValueError):
        total = _meminfo_total()
    for limit in (_cgroup_limit(), _process_limit()):
        if limit is not None and (total is None or limit < total):
            total = limit
    return total if total and total > 0 else None


def _process_limit():
    """What this process's address-space or data limit leaves free; None where there is none."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    limits = []
    for name in ("RLIMIT_AS", "RLIMIT_DATA"):
        try:
            soft, _ = resource.getrlimit(getattr(resource, name))
        except (AttributeError, OSError, ValueError):
            continue
        if soft != resource.RLIM_INFINITY and soft > 0:
            limits.append(soft)
    if not limits:
        return None
    return max(min(limits) - _mapped_bytes(), 0) or None


def _mapped_bytes():
    """The virtual memory this process has mapped (0 where it cannot be read)."""
    try:
        with open("/proc/self/statm") as statm:
            return int(statm.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        return 0


def _meminfo_total():
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemTotal:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_limit():
    """A container's memory limit (cgroup v2 or v1), None where there is none."""
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as file:
                text = file.read().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 2**60:  # "max" or a huge number: none
            return int(text)
    return None


def memory_limit():
    """The bytes a fit or simulation may plan for (``set_config(memory_limit=...)``)."""
    setting = memory_limit_setting()
    if setting != "auto":
        return float(setting)
    return AUTO_FRACTION * (physical_memory() or FALLBACK_MEMORY)


def describe_limit():
    """Where the limit comes from, for messages."""
    setting = memory_limit_setting()
    if setting != "auto":
        return (f"the memory limit of {bytes_text(memory_limit())} set by "
                f"sk_hamiltonian.set_config(memory_limit=...)")
    total = physical_memory()
    machine = (f"the {bytes_text(total)} this process may use" if total
               else f"an assumed {bytes_text(FALLBACK_MEMORY)}: the machine's could not be read")
    return (f"the memory limit of {bytes_text(memory_limit())} ({AUTO_FRACTION:.0%} of "
            f"{machine}; sk_hamiltonian.set_config(memory_limit=...) changes it)")


def bytes_text(n):
    """``n`` bytes in words: ``"9.7 TB"``."""
    if not math.isfinite(n):
        return "unbounded memory"
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def fit_memory(solver, n_columns, n_rows=0, n_states=1):
    """Estimated peak bytes of a fit with ``solver`` on a design of this shape.

    Parameters
    ----------
    solver : {"lstsq", "normal", "iterative", "sketch"} or None
        None: the least any solver needs (its ``n x n`` matrices).
    n_columns : int
        Unknowns.
    n_rows : int, default=0
        Rows of the design (enter only for ``"lstsq"``, which holds it whole).
    n_states : int, default=1
        State variables (for the index set's tables).

    Returns
    -------
    bytes : float
    """
    n = float(n_columns)
    square = FLOAT * n * n
    tables = INDEX_BYTES * n * n_states
    if solver is None:
        return LEAST_SQUARE_MATRICES * square + tables
    need = SQUARE_MATRICES[solver] * square + tables
    if solver == "lstsq":
        # The design and its copy as it is stacked from blocks.
        need += 2 * FLOAT * float(n_rows) * n
    else:
        need += BLOCK_BYTES
    if solver == "sketch":
        need += SKETCH_ROWS * square
    return need


class SizeLimitError(ValueError):
    """A fit or a simulation would need more memory, or more steps, than allowed (a ``ValueError``)."""


def _space_words(estimator):
    return f"{type(estimator).__name__}(degree={estimator.degree})"


def largest_degree_within(estimator, n_states, limit, count):
    """The largest degree below the estimator's whose least memory fits ``limit`` (0 if none)."""
    low, high = 0, int(estimator.degree)
    # Memory grows with the degree: bisect on it with counts, never building a space.
    while low < high:
        mid = (low + high + 1) // 2
        if fit_memory(None, count(mid), n_states=n_states) <= limit:
            low = mid
        else:
            high = mid - 1
    return low


def check_space_memory(estimator, n_columns, n_states, count):
    """Refuse a model space whose least fit memory exceeds the limit (before it is built).

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        For its name and parameters in the message.
    n_columns : int
        Unknowns of the fit.
    n_states : int
        State variables.
    count : callable
        ``count(degree)``: the unknowns at another degree, the other
        parameters unchanged (for the largest degree that fits).

    Raises
    ------
    SizeLimitError
    """
    limit = memory_limit()
    need = fit_memory(None, n_columns, n_states=n_states)
    if need <= limit:
        return
    fits = largest_degree_within(estimator, n_states, limit, count)
    lower = (f"lower `degree` (at most {fits} fits here)" if fits >= 1
             else "lower `degree`")
    raise SizeLimitError(
        f"{_space_words(estimator)} has {n_columns:,} unknowns for {n_states} state "
        f"variables: any fit holds about three {n_columns:,} x {n_columns:,} matrices, at least "
        f"{bytes_text(need)}, beyond {describe_limit()}. Reduce the unknowns: {lower}, or "
        f"restrict the space with max_interaction (e.g. 2: pairwise couplings), "
        f"momentum_degree, separable or couplings."
    )


def check_solver_memory(estimator, solver, n_columns, n_rows, n_states):
    """Refuse a fit whose chosen solver would exceed the memory limit, naming one that fits.

    Raises
    ------
    SizeLimitError
    """
    limit = memory_limit()
    need = fit_memory(solver, n_columns, n_rows, n_states)
    if need <= limit:
        return
    others = [s for s in ("iterative", "normal") if s != solver
              and fit_memory(s, n_columns, n_rows, n_states) <= limit]
    if others:
        remedy = (f"use solver='{others[0]}' (about "
                  f"{bytes_text(fit_memory(others[0], n_columns, n_rows, n_states))}), lower "
                  f"`degree`, or restrict the space (max_interaction, momentum_degree, "
                  f"separable, couplings)")
    else:
        remedy = ("lower `degree`, or restrict the space (max_interaction, momentum_degree, "
                  "separable, couplings)")
    design = (f" (the design alone is {n_rows:,} x {n_columns:,})" if solver == "lstsq" else "")
    raise SizeLimitError(
        f"{_space_words(estimator)} with solver='{solver}' on {n_rows:,} rows and "
        f"{n_columns:,} unknowns would need about {bytes_text(need)}{design}, beyond "
        f"{describe_limit()}. To fit: {remedy}."
    )
