"""Tensor products over an index set: values and gradients of every function (the hot path).

Every function here works on *factor tables* (see :mod:`.tables`): for each
state variable, the 1-D basis and its derivatives at every sample, already
multiplied by the chain-rule factor, as arrays of shape ``(n_states + 1,
width, n_samples)``. A basis function is the product of one column per
variable. Most basis functions depend on few variables, so a function is
stored as *slots*: ``(variable, column)`` pairs for the variables it depends
on, padded to a common width with a dummy variable whose table is ``1`` with
zero derivatives.

The products are formed along the prefix tree of the slots (:mod:`.trie`):
one multiplication per tree node and, at the leaves, one per function and
derivative, written straight into the output. Arrays are *terms-major*
(``(n_terms, ..., n_samples)``), so every gather copies whole contiguous rows;
callers that want samples first get a transposed view. No
``(samples, terms, slots)`` temporary is formed.

Contractions with a coefficient vector (a model's value, gradient and Hessian)
live in :mod:`.contraction` for spaces where a function may depend on every
variable; :func:`gradient_dot` and :func:`hessian_dot` here serve the sparse
spaces (few variables per function), where scattering slot derivatives is
cheaper.
"""

import numpy as np
from scipy import sparse

from .trie import Level, prefix_ids
from .workspace import scratch

# Entries of one (n_terms, samples) temporary of the products: 64 Ki entries
# (512 KiB) keep a chunk's working set in a core's cache.
CHUNK_ENTRIES = 65536


class SlotLayout:
    """Slots of every basis function, from its table columns.

    Parameters
    ----------
    columns : ndarray of shape (n_terms, n_states)
        Table column of each variable in each basis function (0: constant).
    width : int, default=None
        Columns per table; None: one more than the largest column.

    Attributes
    ----------
    variables : ndarray of shape (n_terms, n_slots)
        Variable of each slot; ``n_states`` (the dummy variable) for padding.
    columns : ndarray of shape (n_terms, n_slots)
        Table column of each slot (0 for padding).
    n_states : int
        Number of (real) variables.
    dense : bool
        Whether every function has one slot per variable, in order.
    """

    def __init__(self, columns, width=None):
        n_terms, n_states = columns.shape
        self.n_states = n_states
        self.width = int(columns.max(initial=0)) + 1 if width is None else int(width)
        active = columns != 0
        n_slots = max(1, int(active.sum(axis=1).max(initial=0)))
        #: One slot per variable, in order (constants included): no scatter needed.
        self.dense = n_slots == n_states
        if self.dense:
            self.variables = np.tile(np.arange(n_states), (n_terms, 1))
            self.columns = columns.copy()
        else:
            # Active variables first in each row (stable, so in variable order).
            order = np.argsort(~active, axis=1, kind="stable")[:, :n_slots]
            variables = np.take_along_axis(
                np.broadcast_to(np.arange(n_states), columns.shape), order, 1
            )
            padding = ~np.take_along_axis(active, order, 1)
            self.variables = np.where(padding, n_states, variables)
            self.columns = np.where(padding, 0, np.take_along_axis(columns, order, 1))
        # Keys into the flattened tables (variable * width + column), and the
        # prefix tree of the slots: levels[t] for t = 1 .. n_slots - 1.
        self.keys = self.variables * self.width + self.columns
        ids = prefix_ids(self.keys) if n_terms else [np.zeros(0, np.intp)] * (n_slots + 1)
        self.levels = [None] + [
            Level(ids[t - 1], ids[t], self.keys[:, t - 1]) for t in range(1, n_slots)
        ]
        #: Each function's node at level n_slots - 1 (its parent in the tree).
        self.leaf_parent = ids[n_slots - 1]
        self._incidence = {}

    @property
    def n_slots(self):
        """Slots per basis function."""
        return self.variables.shape[1]

    def incidence(self, key, targets, n_targets):
        """Sparse 0/1 matrix sending each basis function to its target (cached by key)."""
        if key not in self._incidence:
            n = targets.shape[0]
            self._incidence[key] = sparse.csr_array(
                (np.ones(n), (targets, np.arange(n))), shape=(n_targets, n)
            )
        return self._incidence[key]

    def __getstate__(self):
        # The cached matrices are rebuilt on demand; keep pickles small.
        return {**self.__dict__, "_incidence": {}}


def _flat(table):
    """A table ``(n_states + 1, width, n_samples)`` as rows indexed by slot key."""
    return table.reshape(-1, table.shape[-1])


def _prefix_products(tables, layout, order):
    """Products of the slot factors along the tree, down to the leaves' parents.

    Returns the value and, with ``order = 1``, the derivative along each slot
    so far, at the nodes of level ``n_slots - 1``: a list ``[value, d_0, ...]``
    of arrays of shape (n_nodes, n_samples).
    """
    T0 = _flat(tables[0])
    T1 = _flat(tables[1]) if order else None
    n_samples = T0.shape[1]
    carried = [np.ones((1, n_samples))]
    for level in layout.levels[1:]:
        factor = T0[level.key]
        value = carried[0][level.parent]
        out = [value * factor]
        for derivative in carried[1:]:
            out.append(derivative[level.parent] * factor)
        if order:
            out.append(value * T1[level.key])
        carried = out
    return carried


def _chunks(n_terms, n_samples):
    """Sample ranges whose (n_terms, chunk) temporaries stay cache-sized."""
    size = max(8, CHUNK_ENTRIES // max(1, n_terms))
    return [slice(start, min(start + size, n_samples)) for start in range(0, n_samples, size)]


def values(tables, layout, out=None):
    """Values of every basis function: ndarray of shape (n_terms, n_samples)."""
    n_terms, n_samples = layout.keys.shape[0], tables.shape[-1]
    if out is None:
        out = np.empty((n_terms, n_samples))
    last = layout.keys[:, -1]
    for part in _chunks(n_terms, n_samples):
        chunk = tables[..., part]
        (parents,) = _prefix_products(chunk, layout, 0)
        factor = scratch("tensor.factor", (n_terms, part.stop - part.start))
        np.take(_flat(chunk[0]), last, axis=0, out=factor, mode="clip")
        np.multiply(parents[layout.leaf_parent], factor, out=out[:, part])
    return out


def gradients(tables, layout, out=None):
    """Gradients of every basis function.

    Parameters
    ----------
    tables : ndarray
        Factor tables with first derivatives, (n_orders, n_states + 1,
        width, n_samples).
    layout : SlotLayout
        The slots.
    out : ndarray of shape (n_terms, n_states, n_samples), default=None
        Where to write (e.g. the first rows of a design block); it is
        overwritten entirely.

    Returns
    -------
    G : ndarray of shape (n_terms, n_states, n_samples)
        ``G[j, i, s] = d phi_j / d x_i`` at sample ``s``.
    """
    n_terms, m = layout.keys.shape[0], layout.n_states
    n_samples = tables.shape[-1]
    if out is None:
        out = np.empty((n_terms, m, n_samples))
    if not layout.dense:
        out[...] = 0.0
    last = layout.keys[:, -1]
    terms = np.arange(n_terms)
    for part in _chunks(n_terms, n_samples):
        chunk = tables[..., part]
        width = part.stop - part.start
        carried = _prefix_products(chunk, layout, 1)
        factor = scratch("tensor.factor", (n_terms, width))
        parent = scratch("tensor.parent", (n_terms, width))
        np.take(_flat(chunk[0]), last, axis=0, out=factor, mode="clip")
        # Slot t's derivative: the carried derivative along t times the last
        # factor, or (last slot) the carried value times the last derivative.
        for t in range(layout.n_slots):
            if t < layout.n_slots - 1:
                np.take(carried[1 + t], layout.leaf_parent, axis=0, out=parent, mode="clip")
                other = factor
            else:
                np.take(carried[0], layout.leaf_parent, axis=0, out=parent, mode="clip")
                other = scratch("tensor.last", (n_terms, width))
                np.take(_flat(chunk[1]), last, axis=0, out=other, mode="clip")
            if layout.dense:
                np.multiply(parent, other, out=out[:, t, part])
                continue
            # Within one function every variable fills at most one slot, so
            # plain assignment never overwrites a value; padding slots (the
            # dummy variable) are zero and skipped.
            real = layout.variables[:, t] < m
            parent *= other
            out[terms[real], layout.variables[real, t], part] = parent[real]
    return out


def gradient_rows(tables, layout, rows, outs):
    """Selected functions' derivatives along each variable, for a dense layout.

    Parameters
    ----------
    tables : ndarray
        Factor tables with first derivatives.
    layout : SlotLayout
        A dense layout (slot ``i`` is variable ``i``).
    rows : list of ndarray of int
        Per variable ``i``, the functions whose ``d / d x_i`` to compute
        (e.g. those that depend on ``x_i``).
    outs : list of ndarray of shape (len(rows[i]), n_samples)
        Where to write ``d phi_rows[i][k] / d x_i``.
    """
    n_samples = tables.shape[-1]
    m = layout.n_states
    last = layout.keys[:, -1]
    parents = [layout.leaf_parent[r] for r in rows]
    keys = [last[r] for r in rows]
    for part in _chunks(max(r.size for r in rows), n_samples):
        chunk = tables[..., part]
        carried = _prefix_products(chunk, layout, 1)
        values, slopes = _flat(chunk[0]), _flat(chunk[1])
        for i in range(m):
            if i < m - 1:
                source, factor = carried[1 + i], np.take(values, keys[i], axis=0)
            else:
                source, factor = carried[0], np.take(slopes, keys[i], axis=0)
            np.multiply(np.take(source, parents[i], axis=0), factor, out=outs[i][:, part])


def _slot_factors(table, layout):
    """Factors ``table[variables, columns]`` of shape (n_terms, n_slots, n_samples)."""
    return table[layout.variables, layout.columns]


def _products_but_one(F):
    """``prod_{l != t} F[:, l]`` for every slot ``t``, without dividing by ``F``."""
    left = np.ones_like(F)
    right = np.ones_like(F)
    np.cumprod(F[:, :-1], axis=1, out=left[:, 1:])
    right[:, :-1] = np.cumprod(F[:, :0:-1], axis=1)[:, ::-1]
    return left * right


def gradient_dot(tables, layout, coef):
    """Gradient of ``sum_j coef[j] phi_j`` for a sparse layout: ndarray (n_states, n_samples)."""
    F0 = _slot_factors(tables[0], layout)
    D = _products_but_one(F0) * _slot_factors(tables[1], layout)
    weighted = D * coef[:, None, None]
    m = layout.n_states + 1
    out = np.zeros((m, weighted.shape[-1]))
    for t in range(layout.n_slots):
        # Sum the slot contributions of every function into its variable.
        out += layout.incidence(("grad", t), layout.variables[:, t], m) @ weighted[:, t]
    return out[: layout.n_states]


def hessian_dot(tables, layout, coef):
    """Hessian of ``sum_j coef[j] phi_j`` for a sparse layout: (n_states, n_states, n_samples)."""
    F0, F1, F2 = (_slot_factors(table, layout) for table in tables[:3])
    m = layout.n_states + 1
    hess = np.zeros((m * m, F0.shape[-1]))
    V = layout.variables
    for a in range(layout.n_slots):
        for b in range(a, layout.n_slots):
            parts = F0.copy()
            if a == b:
                parts[:, a] = F2[:, a]
            else:
                parts[:, a] = F1[:, a]
                parts[:, b] = F1[:, b]
            weighted = parts.prod(axis=1) * coef[:, None]
            hess += layout.incidence(("hess", a, b), V[:, a] * m + V[:, b], m * m) @ weighted
            if a != b:
                hess += layout.incidence(("hess", b, a), V[:, b] * m + V[:, a], m * m) @ weighted
    n = layout.n_states
    return hess.reshape(m, m, -1)[:n, :n]
