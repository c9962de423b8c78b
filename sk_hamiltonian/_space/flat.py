"""Flat contraction for small model spaces: every derivative as one product per function.

The prefix-tree contraction of :mod:`.contraction` does little arithmetic per
state, but a fixed amount of bookkeeping per level of the tree (numpy calls,
or loops of the compiled kernel), which is all a space of a dozen functions
(a sparse model's kept terms) costs. Here a derivative pattern ``q`` of
``f = sum_j c_j prod_i T_i[alpha_ji]`` is written out as a list of
*functions*: for each basis function that depends on every variable of
``q``, the product of one table entry per variable it depends on, of the
derivative order that ``q`` asks of that variable. The result is

    d^q f = sum_{functions g of q} c_{j(g)} prod_t table[key_gt],

one gather and one product per slot, then a small matrix product, whatever
the number of variables. :meth:`FlatPlan.cost` against
:attr:`.ContractionPlan.cost` decides which contraction a space uses.

The keys index the flattened factor tables; key ``0`` (the constant column of
the first variable, ``1`` in every family) pads functions with fewer
variables. Two layouts are kept: the numpy tables of :mod:`.tables`,
``(order, variable, column)``, and the compiled kernels' work table,
``(variable, order, column)`` with 3 orders.
"""

from itertools import combinations_with_replacement

import numpy as np

# Flat evaluation while its multiply-adds per state (FlatPlan.cost) stay below
# the tree's (ContractionPlan.cost per derivative order) plus the tree's fixed
# bookkeeping, in multiply-adds. Measured on a 2-core VM (load 3.8), one state
# to 16 states, the gradient of 4-D spaces: numpy flat 43-50 us against tree
# 85-129 us for 11 terms, 104 against 203 us at degree 6 (209 terms, 16
# states), about even at degree 8; compiled, 594 against 1 271 ns for 11
# terms, 1 806 against 2 309 ns at degree 4, but 4 691 against 1 965 ns at
# degree 6. numpy pays its fixed cost per call, so it counts only for a few
# states; with many, the flat gathers cost more than the tree's products.
TREE_OVERHEAD = {"numpy": 2000, "numba": 300}
FEW_SAMPLES = 64


def choose_flat(flat_cost, tree_cost, kernels, n_samples=1):
    """Whether the flat contraction costs less (see :data:`TREE_OVERHEAD`).

    Parameters
    ----------
    flat_cost, tree_cost : int
        Multiply-adds per state of the flat and the tree contraction.
    kernels : {"numpy", "numba"}
        Which path evaluates.
    n_samples : int, default=1
        States per call (numpy only).

    Returns
    -------
    flat : bool
    """
    overhead = TREE_OVERHEAD[kernels]
    if kernels == "numpy" and n_samples > FEW_SAMPLES:
        overhead = 0
    return flat_cost <= tree_cost + overhead


class FlatPlan:
    """The functions of every derivative pattern of one order, for a space's multi-indices.

    Parameters
    ----------
    columns : ndarray of shape (n_terms, n_states)
        Table column of every variable in every basis function (0: constant).
    width : int
        Columns per table.
    order : {0, 1, 2}
        Derivative order of the patterns: the value, the gradient or the
        Hessian (``i <= j``).
    """

    def __init__(self, columns, width, order):
        n_terms, m = columns.shape
        self.order, self.n_states, self.width = order, m, width
        self.patterns = list(combinations_with_replacement(range(m), order))
        active = columns != 0
        terms, orders, pattern_of = [], [], []
        for q, pattern in enumerate(self.patterns):
            r = np.bincount(np.asarray(pattern, dtype=np.intp), minlength=m)
            # A function constant in a variable of the pattern has no such derivative.
            rows = np.flatnonzero(active[:, r > 0].all(axis=1))
            terms.append(rows)
            orders.append(np.broadcast_to(r, (rows.size, m)))
            pattern_of.append(np.full(rows.size, q, dtype=np.intp))
        #: The basis function and the pattern of every function.
        self.terms = np.concatenate(terms)
        self.pattern = np.concatenate(pattern_of)
        orders = np.concatenate(orders)
        cols = columns[self.terms]
        used = cols != 0
        n_slots = max(1, int(used.sum(axis=1).max(initial=0)))
        # Each function's variables first (stable: in variable order).
        variable = np.argsort(~used, axis=1, kind="stable")[:, :n_slots]
        real = np.take_along_axis(used, variable, 1)
        col = np.take_along_axis(cols, variable, 1)
        r = np.take_along_axis(orders, variable, 1)
        #: Keys into the numpy tables (n_orders, n_states + 1, width) flattened.
        self.keys = np.where(real, (r * (m + 1) + variable) * width + col, 0).astype(np.intp)
        #: Keys into the compiled work table (n_states, 3, width) flattened.
        self.jit_keys = np.where(real, (variable * 3 + r) * width + col, 0).astype(np.int64)
        self.n_functions = self.terms.size

    @property
    def n_slots(self):
        """Table entries multiplied per function."""
        return self.keys.shape[1]

    @property
    def cost(self):
        """Multiply-adds per state and target: the products and the sum."""
        return self.n_functions * (self.n_slots + 1)

    def bind(self, coef):
        """The matrix sending function values to the patterns: (n_patterns * K, n_functions).

        Row ``q * K + k`` holds target ``k``'s coefficient of each function of
        pattern ``q``, zero for the other patterns' functions.

        Parameters
        ----------
        coef : ndarray of shape (n_terms,) or (n_terms, K)
            Coefficients of the basis functions.
        """
        coef = np.asarray(coef, dtype=float)
        coef = coef.reshape(coef.shape[0], -1)
        K = coef.shape[1]
        W = np.zeros((len(self.patterns), K, self.n_functions))
        W[self.pattern, :, np.arange(self.n_functions)] = coef[self.terms]
        return W.reshape(-1, self.n_functions)

    def contract(self, tables, W):
        """Every pattern of this order: ndarray of shape (n_patterns, K, n_samples).

        Parameters
        ----------
        tables : ndarray of shape (n_orders, n_states + 1, width, n_samples)
            Factor tables with at least ``order + 1`` derivative orders.
        W : ndarray
            From :meth:`bind`.
        """
        n_samples = tables.shape[-1]
        flat = tables.reshape(-1, n_samples)
        values = flat[self.keys[:, 0]]
        for t in range(1, self.n_slots):
            values *= flat[self.keys[:, t]]
        return (W @ values).reshape(len(self.patterns), -1, n_samples)
