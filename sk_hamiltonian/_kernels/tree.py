"""The arrays a compiled kernel needs from a model space (plain numpy, no numba).

A model space's index set becomes a prefix tree (:mod:`sk_hamiltonian._space.trie`):
the functions grouped by their first ``m - 1`` columns (the leaves, in
compressed-row form: each prefix's functions and the column of their last
variable), then one level per variable with each node's parent and column.
The 1-D families become four arrays: family (0 Legendre, 1 Fourier), highest
degree or frequency, and the affine map ``window = slope * x + offset`` of
:class:`~sk_hamiltonian._space.tables.FactorTables`, so both paths read the
same numbers.
"""

import numpy as np

from .._space.tables import _legendre
from .._space.trie import Level, prefix_ids

INDEX = np.int64


def tree_arrays(space):
    """The tuple of arrays describing ``space`` to :mod:`._jit`, and the leaf order of its terms.

    Returns
    -------
    tree : tuple
        ``(family, degree, slope, offset, leaf_start, leaf_column,
        level_start, level_parent, level_key, node_counts, width, level_pos)``.
    order : ndarray of shape (n_terms,)
        The terms in leaf order: bound coefficients are ``coef[order]``.
    """
    m = space.n_states
    family = np.zeros(m, dtype=INDEX)
    degree = np.zeros(m, dtype=INDEX)
    slope = np.zeros(m)
    offset = np.zeros(m)
    for kernel, n, _, rows, a, b in space.factor_tables.families:
        rows = np.arange(m) if rows is None else rows
        family[rows] = 0 if kernel is _legendre else 1
        degree[rows] = n
        slope[rows] = a[:, 0]
        offset[rows] = b[:, 0]
    columns = space.columns
    if columns.shape[0] == 0:
        columns = np.zeros((0, m), dtype=np.intp)
    ids = prefix_ids(columns) if columns.shape[0] else [np.zeros(0, np.intp)] * (m + 1)
    leaf_parent = ids[m - 1]
    n_prefixes = int(leaf_parent.max(initial=0)) + 1
    order = np.argsort(leaf_parent, kind="stable")
    leaf_start = np.searchsorted(leaf_parent[order], np.arange(n_prefixes + 1)).astype(INDEX)
    leaf_column = np.ascontiguousarray(columns[order, m - 1], dtype=INDEX)
    starts, parents, keys, counts = [0], [], [], [n_prefixes]
    for k in range(m - 1, 0, -1):
        if columns.shape[0]:
            level = Level(ids[k - 1], ids[k], columns[:, k - 1])
            parent, key = level.parent, level.key
        else:
            parent = key = np.zeros(1, dtype=np.intp)
        parents.append(parent)
        keys.append(key)
        starts.append(starts[-1] + parent.size)
        counts.append(int(parent.max(initial=0)) + 1)
    cat = np.concatenate if parents else (lambda _: np.zeros(0, dtype=INDEX))
    tree = (
        family, degree, slope, offset, leaf_start, leaf_column,
        np.array(starts, dtype=INDEX), cat(parents).astype(INDEX), cat(keys).astype(INDEX),
        np.array(counts, dtype=INDEX), int(space.width),
        # Each node's slot in its level's padded (column, parent) array.
        (cat(keys) * np.repeat(counts[1:], [p.size for p in parents]) + cat(parents)).astype(INDEX)
        if parents else np.zeros(0, dtype=INDEX),
    )
    return tree, order
