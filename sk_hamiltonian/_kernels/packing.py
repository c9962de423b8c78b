"""Many arrays as one integer and one float array, for cheap calls of a compiled kernel.

numba's dispatch unboxes every array it is given, the arrays inside tuples
included: the tree and flat plans of the one-state kernels are some 25
arrays, and handing them over cost 2 to 3 us of a 10 us call (measured with
a scratch script: a compiled function that only reads its arguments took
2.9 us called with those tuples against 0.9 us with seven arrays). Packed,
they are two arrays, and the kernel takes its views of them back
(:func:`._checked_jit.unpack`) for the cost of a few index reads.

The layout is a header of ``SLOTS`` integers per item at the start of the
integer array: the item's offset (into the integer array for integer and
boolean items, into the float array for float items) and its three
dimensions, padded with ones; a plain integer item is stored in the offset
slot. Plain numpy: no numba is needed to build it.
"""

import numpy as np

SLOTS = 4  # header integers per item: offset, then three dimensions


def pack(items):
    """Pack ``items`` (arrays of up to three dimensions, or integers) into two arrays.

    Parameters
    ----------
    items : sequence of ndarray or int
        Integer and boolean arrays go to the integer array (booleans as 0
        and 1), float arrays to the float array, integers to the header.

    Returns
    -------
    ints : ndarray of int64
        The header (``SLOTS`` entries per item), then the integer items.
    floats : ndarray of float64
        The float items.
    """
    header = np.zeros(SLOTS * len(items), dtype=np.int64)
    ints, floats = [header], [np.zeros(0)]
    sizes = {"i": header.size, "f": 0}
    for k, item in enumerate(items):
        head = header[SLOTS * k : SLOTS * (k + 1)]
        if isinstance(item, (int, np.integer)):
            head[0] = item
            continue
        item = np.asarray(item)
        if item.ndim >= SLOTS:
            raise ValueError(f"item {k} has {item.ndim} dimensions; at most {SLOTS - 1} pack.")
        where, parts, dtype = ("f", floats, np.float64) if item.dtype.kind == "f" else ("i", ints, np.int64)
        head[0] = sizes[where]
        head[1:] = item.shape + (1,) * (SLOTS - 1 - item.ndim)
        parts.append(item.astype(dtype).ravel())
        sizes[where] += item.size
    return np.concatenate(ints), np.concatenate(floats)
