"""Global configuration of sk_hamiltonian: which kernels evaluate and simulate models, and how much memory a fit may plan for.

Mirrors :func:`sklearn.set_config`: a process-wide default, a per-thread
current value, and a context manager that restores the previous value.
"""

import math
import os
import threading
from contextlib import contextmanager
from numbers import Real

from ._numba import numba_available

_KERNELS = ("auto", "numpy", "numba")
# The environment variable SK_HAMILTONIAN_KERNELS sets the process-wide
# default (e.g. to run a test suite on one path); unknown values are ignored
# here and rejected by set_config.
_global_config = {
    "kernels": os.environ.get("SK_HAMILTONIAN_KERNELS", "auto")
    if os.environ.get("SK_HAMILTONIAN_KERNELS") in _KERNELS else "auto",
    "memory_limit": "auto",
}
_local = threading.local()


def _thread_config():
    """This thread's configuration (a copy of the global one on first use)."""
    if not hasattr(_local, "config"):
        _local.config = dict(_global_config)
    return _local.config


def get_config():
    """Current values of the configuration set by :func:`set_config`.

    Returns
    -------
    config : dict
        Keys are the parameter names of :func:`set_config`.

    See Also
    --------
    set_config : Set the configuration.
    config_context : Set the configuration within a ``with`` block.

    Examples
    --------
    >>> import sk_hamiltonian
    >>> sorted(sk_hamiltonian.get_config())
    ['kernels', 'memory_limit']
    """
    return dict(_thread_config())


def set_config(kernels=None, memory_limit=None):
    """Set the configuration of sk_hamiltonian.

    Parameters
    ----------
    kernels : {"auto", "numpy", "numba"}, default=None
        Which kernels evaluate a fitted model's ``H~``, its gradient and
        Hessian (and a vector field's values), and run fixed-step
        simulations. ``"numpy"``: the vectorized numpy kernels.
        ``"numba"``: compiled kernels (``pip install sk_hamiltonian[fast]``);
        the first call of each kernel compiles it and caches the machine code
        on disk, so later processes skip the compilation. ``"auto"`` (the
        initial value, unless the environment variable
        ``SK_HAMILTONIAN_KERNELS`` names another): numba where it can be
        imported, else numpy. Both give the same answers up to round-off.
        None leaves the value unchanged.
    memory_limit : "auto" or float, default=None
        Bytes a fit (``fit``, ``partial_fit``) and a simulation may plan to
        allocate. Before building anything large they estimate what they need
        from the number of unknowns, rows and output times, and refuse with a
        ``ValueError`` naming the sizes and the remedies beyond this limit,
        rather than run for minutes into a ``MemoryError``. ``"auto"`` (the
        initial value): three quarters of the machine's physical memory (or
        of a container's memory limit, or of what this process's own
        address-space limit, ``ulimit -v``, leaves free, if lower), or 8 GiB
        where none can be read. ``numpy.inf`` turns the check off. None leaves the value
        unchanged.

    Raises
    ------
    ValueError
        If ``kernels`` is not one of the choices, or ``memory_limit`` neither
        ``"auto"`` nor a positive number.
    ImportError
        If ``kernels="numba"`` and numba cannot be imported.

    See Also
    --------
    get_config : The current configuration.
    config_context : Set the configuration within a ``with`` block.

    Examples
    --------
    >>> import sk_hamiltonian
    >>> previous = sk_hamiltonian.get_config()["kernels"]
    >>> sk_hamiltonian.set_config(kernels="numpy")
    >>> sk_hamiltonian.get_config()["kernels"]
    'numpy'
    >>> sk_hamiltonian.set_config(kernels=previous)
    """
    if memory_limit is not None and not (
        (isinstance(memory_limit, str) and memory_limit == "auto") or (
            isinstance(memory_limit, Real) and not isinstance(memory_limit, bool)
            and not math.isnan(memory_limit) and memory_limit > 0
        )
    ):
        raise ValueError(
            f"memory_limit must be 'auto' or a positive number of bytes (numpy.inf: no "
            f"limit); got {memory_limit!r}."
        )
    if kernels is not None:
        if kernels not in _KERNELS:
            raise ValueError(f"kernels must be one of {list(_KERNELS)}; got {kernels!r}.")
        if kernels == "numba" and not numba_available():
            raise ImportError(
                "kernels='numba' needs numba, which cannot be imported; install it with "
                "`pip install sk_hamiltonian[fast]`, or use kernels='auto' (numba when "
                "available, else numpy)."
            )
    # Both checked before either is set: a refused call changes nothing.
    for name, value in (("kernels", kernels), ("memory_limit", memory_limit)):
        if value is not None:
            _global_config[name] = value
            _thread_config()[name] = value


@contextmanager
def config_context(*, kernels=None, memory_limit=None):
    """Set the configuration within a ``with`` block, and restore it on leaving.

    Parameters
    ----------
    kernels : {"auto", "numpy", "numba"}, default=None
        As in :func:`set_config`; None leaves the value unchanged.
    memory_limit : "auto" or float, default=None
        As in :func:`set_config`; None leaves the value unchanged.

    Yields
    ------
    None

    Raises
    ------
    ValueError
        If ``kernels`` or ``memory_limit`` is not one of the choices.
    ImportError
        If ``kernels="numba"`` and numba cannot be imported.

    See Also
    --------
    set_config : Set the configuration.
    get_config : The current configuration.

    Notes
    -----
    Like ``sklearn.config_context``, the block changes the process-wide
    default as well as this thread's value, and restores both.

    Examples
    --------
    >>> import sk_hamiltonian
    >>> with sk_hamiltonian.config_context(kernels="numpy"):
    ...     sk_hamiltonian.get_config()["kernels"]
    'numpy'
    """
    previous = get_config()
    set_config(kernels=kernels, memory_limit=memory_limit)
    try:
        yield
    finally:
        set_config(**previous)


def memory_limit_setting():
    """The current ``memory_limit``: ``"auto"`` or a number of bytes."""
    return _thread_config()["memory_limit"]


def use_numba():
    """Whether the compiled kernels are to be used now."""
    kernels = _thread_config()["kernels"]
    if kernels == "numpy":
        return False
    # "numba" was checked by set_config; "auto" falls back quietly.
    return numba_available()
