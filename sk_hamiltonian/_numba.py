"""Whether numba can be imported: what the configuration asks before choosing the compiled path.

A leaf, so that :mod:`._config` answers without importing the kernels (or
numba) when the package is imported: numba itself is imported once, on the
first question.
"""

_NUMBA = None


def numba_available():
    """Whether numba can be imported (checked once per process)."""
    global _NUMBA
    if _NUMBA is None:
        try:
            import numba  # noqa: F401
        except Exception:  # ImportError, or a numba broken against this numpy
            _NUMBA = False
        else:
            _NUMBA = True
    return _NUMBA
