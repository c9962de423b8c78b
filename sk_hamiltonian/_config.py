"""Global configuration of sk_hamiltonian: which kernels evaluate and simulate models.

Mirrors :func:`sklearn.set_config`: a process-wide default, a per-thread
current value, and a context manager that restores the previous value.
"""

import os
import threading
from contextlib import contextmanager

from ._numba import numba_available

_KERNELS = ("auto", "numpy", "numba")
# The environment variable SK_HAMILTONIAN_KERNELS sets the process-wide
# default (e.g. to run a test suite on one path); unknown values are ignored
# here and rejected by set_config.
_global_config = {
    "kernels": os.environ.get("SK_HAMILTONIAN_KERNELS", "auto")
    if os.environ.get("SK_HAMILTONIAN_KERNELS") in _KERNELS else "auto"
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
    ['kernels']
    """
    return dict(_thread_config())


def set_config(kernels=None):
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

    Raises
    ------
    ValueError
        If ``kernels`` is not one of the choices.
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
    if kernels is None:
        return
    if kernels not in _KERNELS:
        raise ValueError(f"kernels must be one of {list(_KERNELS)}; got {kernels!r}.")
    if kernels == "numba":
        if not numba_available():
            raise ImportError(
                "kernels='numba' needs numba, which cannot be imported; install it with "
                "`pip install sk_hamiltonian[fast]`, or use kernels='auto' (numba when "
                "available, else numpy)."
            )
    _global_config["kernels"] = kernels
    _thread_config()["kernels"] = kernels


@contextmanager
def config_context(*, kernels=None):
    """Set the configuration within a ``with`` block, and restore it on leaving.

    Parameters
    ----------
    kernels : {"auto", "numpy", "numba"}, default=None
        As in :func:`set_config`; None leaves the value unchanged.

    Yields
    ------
    None

    Raises
    ------
    ValueError
        If ``kernels`` is not one of the choices.
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
    set_config(kernels=kernels)
    try:
        yield
    finally:
        set_config(**previous)


def use_numba():
    """Whether the compiled kernels are to be used now."""
    kernels = _thread_config()["kernels"]
    if kernels == "numpy":
        return False
    # "numba" was checked by set_config; "auto" falls back quietly.
    return numba_available()
