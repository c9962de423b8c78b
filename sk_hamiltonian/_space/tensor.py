"""Tensor products over an index set: values, gradients and Hessians (the hot path).

Every function here works on *factor tables*: for each state variable, the 1-D
basis (Legendre or Fourier) and its derivatives at every sample, already
multiplied by the chain-rule factor of the variable's coordinate map. A basis
function is the product of one column per variable. Most basis functions
depend on few variables, so a function is stored as *slots*: ``(variable,
column)`` pairs for the variables it depends on, padded to a common width with
a dummy variable whose table is ``1`` with zero derivatives. The cost of every
operation is then proportional to the slots, not to ``n_terms * n_states``.

The interface is narrow on purpose (tables in, arrays out), so that a faster
kernel can replace one of these functions without touching the estimators.
"""

import numpy as np
from scipy import sparse


class SlotLayout:
    """Slots of every basis function, from its table columns.

    Parameters
    ----------
    columns : ndarray of shape (n_terms, n_states)
        Table column of each variable in each basis function (0: constant).

    Attributes
    ----------
    variables : ndarray of shape (n_terms, n_slots)
        Variable of each slot; ``n_states`` (the dummy variable) for padding.
    columns : ndarray of shape (n_terms, n_slots)
        Table column of each slot (0 for padding).
    n_states : int
        Number of (real) variables.
    """

    def __init__(self, columns):
        n_terms, n_states = columns.shape
        self.n_states = n_states
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
                (np.ones(n), (np.arange(n), targets)), shape=(n, n_targets)
            )
        return self._incidence[key]

    def __getstate__(self):
        # The cached matrices are rebuilt on demand; keep pickles small.
        return {**self.__dict__, "_incidence": {}}


def gather(table, layout):
    """Factors ``table[:, variables, columns]`` of shape (n_samples, n_terms, n_slots)."""
    return table[:, layout.variables, layout.columns]


def products_but_one(F):
    """``prod_{l != t} F[..., l]`` for every ``t``, without dividing by ``F``."""
    left = np.ones_like(F)
    right = np.ones_like(F)
    np.cumprod(F[..., :-1], axis=-1, out=left[..., 1:])
    right[..., :-1] = np.cumprod(F[..., :0:-1], axis=-1)[..., ::-1]
    return left * right


def values(tables, layout):
    """Values of every basis function: ndarray of shape (n_samples, n_terms)."""
    return gather(tables[0], layout).prod(axis=-1)


def slot_gradients(tables, layout):
    """Derivative of each function along the variable of each slot.

    Returns
    -------
    D : ndarray of shape (n_samples, n_terms, n_slots)
        ``D[s, j, t] = d phi_j / d x_{variables[j, t]}`` at sample ``s`` (zero
        on padding slots).
    """
    return products_but_one(gather(tables[0], layout)) * gather(tables[1], layout)


def gradients(tables, layout):
    """Gradients of every basis function.

    Returns
    -------
    G : ndarray of shape (n_samples, n_states, n_terms)
        ``G[s, i, j] = d phi_j / d x_i`` at sample ``s``.
    """
    D = slot_gradients(tables, layout)
    if layout.dense:
        return np.moveaxis(D, -1, 1)
    n_samples, n_terms, n_slots = D.shape
    G = np.zeros((n_samples, layout.n_states + 1, n_terms))
    terms = np.arange(n_terms)
    # Within one function every variable fills at most one slot, and padding
    # goes to the dummy row, so plain assignment never overwrites a value.
    for t in range(n_slots):
        G[:, layout.variables[:, t], terms] = D[:, :, t]
    return G[:, : layout.n_states]


def gradient_dot(tables, layout, coef):
    """Gradient of ``sum_j coef[j] phi_j``: ndarray of shape (n_samples, n_states)."""
    D = slot_gradients(tables, layout)
    if layout.dense:
        return np.einsum("sjm,j->sm", D, coef)
    weighted = D * coef[None, :, None]
    m = layout.n_states + 1
    out = np.zeros((weighted.shape[0], m))
    for t in range(layout.n_slots):
        # Sum the slot contributions of every function into its variable.
        out += weighted[:, :, t] @ layout.incidence(("grad", t), layout.variables[:, t], m)
    return out[:, : layout.n_states]


def hessian_dot(tables, layout, coef):
    """Hessian of ``sum_j coef[j] phi_j``: ndarray of shape (n_samples, n_states, n_states)."""
    F0, F1, F2 = (gather(table, layout) for table in tables[:3])
    m = layout.n_states + 1
    hess = np.zeros((F0.shape[0], m * m))
    V = layout.variables
    for a in range(layout.n_slots):
        for b in range(a, layout.n_slots):
            parts = F0.copy()
            if a == b:
                parts[..., a] = F2[..., a]
            else:
                parts[..., a] = F1[..., a]
                parts[..., b] = F1[..., b]
            weighted = parts.prod(axis=-1) * coef
            hess += weighted @ layout.incidence(("hess", a, b), V[:, a] * m + V[:, b], m * m)
            if a != b:
                hess += weighted @ layout.incidence(("hess", b, a), V[:, b] * m + V[:, a], m * m)
    return hess.reshape(-1, m, m)[:, : layout.n_states, : layout.n_states]
