"""Prefix trees of multi-indices: the structure the tensor kernels walk.

A basis function is a product of one factor per *slot* (a variable and the
column of its 1-D table). Functions that share their first ``k`` slots share
the product of those ``k`` factors, so a set of functions is a tree of
prefixes: level ``k`` holds one node per distinct prefix of length ``k``,
and every node has one parent at level ``k - 1``. Walking the tree from the
root multiplies one factor per node (the forward products of :mod:`.tensor`);
walking it from the leaves sums children into parents (the contractions of
:mod:`.contraction`). Either way the work per level is the number of nodes,
never ``n_terms * n_slots`` except at the leaves.

Nodes are numbered level by level in lexicographic order of their prefixes, so
the children of a node are consecutive: a sum over children is one
:func:`numpy.add.reduceat`.
"""

import numpy as np


def prefix_ids(keys):
    """Node of every row's prefix, level by level.

    Parameters
    ----------
    keys : ndarray of shape (n_rows, n_levels) of int
        One non-negative key per row and level (e.g. ``variable * width +
        column``).

    Returns
    -------
    ids : list of ndarray of shape (n_rows,)
        ``ids[k][j]`` numbers the prefix ``keys[j, :k]`` among the distinct
        prefixes of length ``k``, in lexicographic order; ``ids[0]`` is all
        zeros (the root).
    """
    n_rows, n_levels = keys.shape
    base = int(keys.max(initial=0)) + 1
    ids = [np.zeros(n_rows, dtype=np.intp)]
    for k in range(n_levels):
        combined = ids[-1].astype(np.int64) * base + keys[:, k]
        _, inverse = np.unique(combined, return_inverse=True)
        ids.append(inverse.ravel().astype(np.intp))
    return ids


class Level:
    """The nodes of one level: parent and key of each, and where each parent's children start.

    Parameters
    ----------
    parent_ids : ndarray of shape (n_rows,)
        Node at the previous level of every row.
    node_ids : ndarray of shape (n_rows,)
        Node at this level of every row (numbered in lexicographic order).
    keys : ndarray of shape (n_rows,)
        Key of this level of every row.

    Attributes
    ----------
    parent : ndarray of shape (n_nodes,)
        Parent of each node.
    key : ndarray of shape (n_nodes,)
        Key of each node.
    starts : ndarray of shape (n_parents,)
        Index of the first child of each parent (children are consecutive).
    """

    def __init__(self, parent_ids, node_ids, keys):
        n_nodes = int(node_ids.max(initial=-1)) + 1
        representative = np.zeros(n_nodes, dtype=np.intp)
        representative[node_ids] = np.arange(node_ids.size)
        self.parent = parent_ids[representative]
        self.key = keys[representative]
        self.starts = np.flatnonzero(np.r_[True, self.parent[1:] != self.parent[:-1]])

    @property
    def n_nodes(self):
        """Number of nodes at this level."""
        return self.parent.size
