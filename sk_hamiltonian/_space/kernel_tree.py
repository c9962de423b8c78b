"""The arrays a compiled kernel needs from a model space (plain numpy, no numba).

A model space's index set becomes a prefix tree (:mod:`.trie`):
the functions grouped by their first ``m - 1`` columns (the leaves, in
compressed-row form: each prefix's functions and the column of their last
variable), then one level per variable with each node's parent and column.
The 1-D families become four arrays: family (0 Legendre, 1 Fourier, 2 mixed),
highest degree or frequency, and the affine map ``window = slope * x + offset`` of
:class:`~sk_hamiltonian._space.tables.FactorTables`, so both paths read the
same numbers; two more give a mixed variable's highest Fourier frequency and
its angle per unit of ``x``.

The nodes of each level are numbered by their largest child key, largest
first, and ``column_counts`` says how many of them have a child of each
column: a contraction over column ``c`` then runs over the first
``column_counts[., c]`` nodes only. For a downward-closed index set (total
degree, hyperbolic cross) those are exactly the nodes with that child, so
no product by a zero coefficient is left (the dense (column, node) arrays
of a degree-15 space in four variables are 3.4 times its 3 876 terms).
"""

import numpy as np

from .tables import _legendre, _mixed
from .trie import Level, prefix_ids

INDEX = np.int64


def tree_arrays(space):
    """The tuple of arrays describing ``space`` to :mod:`sk_hamiltonian._kernels._jit`, and the leaf order of its terms.

    Returns
    -------
    tree : tuple
        ``(family, degree, slope, offset, leaf_start, leaf_column,
        level_start, level_parent, level_key, node_counts, width, level_pos,
        column_counts, trig_degree, trig_rate)``; ``column_counts[0, c]`` prefixes have a leaf in
        column ``c``, and ``column_counts[1 + L, c]`` parents of level ``L``
        a child of key ``c``, always the first ones.
    order : ndarray of shape (n_terms,)
        The terms in leaf order: bound coefficients are ``coef[order]``.
    """
    m = space.n_states
    family = np.zeros(m, dtype=INDEX)
    degree = np.zeros(m, dtype=INDEX)
    slope = np.zeros(m)
    offset = np.zeros(m)
    trig_degree = np.zeros(m, dtype=INDEX)
    trig_rate = np.zeros(m)
    for kernel, n, _, rows, a, b in space.factor_tables.families:
        rows = np.arange(m) if rows is None else rows
        family[rows] = 0 if kernel is _legendre else 2 if kernel is _mixed else 1
        if kernel is _mixed:
            (n, trig_degree[rows]), trig_rate[rows] = n, space.factor_tables.mixed_rate
        degree[rows] = n
        slope[rows] = a[:, 0]
        offset[rows] = b[:, 0]
    columns = space.columns
    if columns.shape[0] == 0:
        columns = np.zeros((0, m), dtype=np.intp)
    ids = prefix_ids(columns) if columns.shape[0] else [np.zeros(0, np.intp)] * (m + 1)
    width = int(space.width)
    column_counts = np.zeros((m, width), dtype=INDEX)
    for k in range(m - 1, -1, -1):
        # Nodes of prefix length k, by the largest key of their children.
        ids[k], largest = _by_largest_child(ids[k], columns[:, k])
        column_counts[m - 1 - k] = (largest[:, None] >= np.arange(width)).sum(axis=0)
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
        np.array(counts, dtype=INDEX), width,
        # Each node's slot in its level's padded (column, parent) array.
        (cat(keys) * np.repeat(counts[1:], [p.size for p in parents]) + cat(parents)).astype(INDEX)
        if parents else np.zeros(0, dtype=INDEX),
        column_counts, trig_degree, trig_rate,
    )
    return tree, order


def _by_largest_child(ids, child_keys):
    """Renumber nodes by the largest key of their children, largest first.

    Returns the rows' new node ids and each new node's largest child key.
    """
    n_nodes = int(ids.max(initial=-1)) + 1
    largest = np.full(n_nodes, -1, dtype=INDEX)
    np.maximum.at(largest, ids, child_keys)
    ranking = np.argsort(-largest, kind="stable")
    new = np.empty(n_nodes, dtype=np.intp)
    new[ranking] = np.arange(n_nodes)
    return new[ids], largest[ranking]


def children_by_parent(tree):
    """Each level's nodes grouped by parent, for the kernels of :mod:`sk_hamiltonian._kernels._lanes_jit`.

    Returns
    -------
    children : tuple
        ``(child_order, child_start, child_offset)``: level ``L``'s nodes in
        the order of their parents are
        ``child_order[level_start[L]:level_start[L + 1]]``, and parent ``P``'s
        are entries ``child_start[child_offset[L] + P]`` up to the next.
    """
    level_start, level_parent, node_counts = tree[6], tree[7], tree[9]
    orders, starts, offsets = [], [], [0]
    for L in range(node_counts.size - 1):
        parent = level_parent[level_start[L]:level_start[L + 1]]
        order = np.argsort(parent, kind="stable")
        orders.append(order)
        starts.append(np.searchsorted(parent[order], np.arange(node_counts[L + 1] + 1)))
        offsets.append(offsets[-1] + starts[-1].size)
    cat = np.concatenate if orders else (lambda _: np.zeros(0, dtype=INDEX))
    return cat(orders).astype(INDEX), cat(starts).astype(INDEX), np.array(offsets, dtype=INDEX)
