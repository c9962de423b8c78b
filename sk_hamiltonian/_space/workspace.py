"""Reusable scratch arrays for the hot loops.

The kernels repeat the same few large temporaries (tables, products, design
blocks) for every chunk of samples and every step of a simulation. Allocating
them afresh costs a page fault per 4 KiB whenever the allocator has returned
the memory to the system in between, which can take longer than the
arithmetic (measured on a 2-core VM: 1 400 faults and 5 ms of system time per
contraction of 128 states, against 2 ms of computing). A workspace keeps one
buffer per name and thread and hands out views of it.

Rules for callers: a view is valid until the next request of the same name in
the same thread, and never leaves the function that requested it (results
returned to users are fresh arrays).
"""

import threading

import numpy as np

_local = threading.local()


def scratch(name, shape):
    """A float64 array of ``shape`` backed by this thread's buffer ``name`` (contents undefined).

    Parameters
    ----------
    name : str
        Which buffer; distinct call sites that are alive at the same time
        must use distinct names.
    shape : tuple of int
        Shape of the view.

    Returns
    -------
    view : ndarray
        C-contiguous.
    """
    buffers = getattr(_local, "buffers", None)
    if buffers is None:
        buffers = _local.buffers = {}
    size = 1
    for n in shape:
        size *= int(n)
    buffer = buffers.get(name)
    if buffer is None or buffer.size < size:
        # Grow geometrically so a slowly growing request does not reallocate often.
        buffer = np.empty(max(size, 0 if buffer is None else int(buffer.size * 1.5)))
        buffers[name] = buffer
    return buffer[:size].reshape(shape)


def release():
    """Drop this thread's buffers (e.g. after a large fit)."""
    _local.buffers = {}
