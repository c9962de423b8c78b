"""Whether a model file's ``powers_`` is the index set its parameters define.

A fitted model's ``powers_`` is ``index_set(n_states, degree, ...)`` of its
parameters. Generating that set again to compare would cost what the
parameters claim (a ``degree`` of 10**8 in the manifest would ask for
gigabytes), so the rows are checked instead, in time and memory proportional
to ``powers_`` itself:

1. every row lies in the set the parameters define (the *space*: total
   degree, degree in the momenta, separability, interactions, couplings,
   signs of non-periodic variables, the constant term);
2. no row repeats;
3. the rows are closed upwards within the space: raising the magnitude of
   one entry of a row (or of the zero row) by one either leaves the space or
   gives another row.

The space is a lower set (lowering any magnitude keeps every constraint), so
every element of it is reached from the zero row by such steps, and 1-3 hold
exactly when the rows are the whole space. A mixed variable's entry is a code
(:mod:`sk_hamiltonian._space.mixed`): its Legendre degrees rise by one from
zero, its Fourier codes by two from ``-1`` (cosines) and ``-2`` (sines), and
a code's degree is its frequency.
"""

import numpy as np

from ._space.mixed import factor_degrees

# Rows checked at a time, to bound the memory of the coupling test.
BLOCK_ROWS = 8192


def index_set_problem(powers, degree, periodic, *, momentum_degree=None, separable=False,
                      max_interaction=None, couplings=None, include_constant=False,
                      mixed=None):
    """What keeps ``powers`` from being the index set of these parameters, or None.

    Parameters
    ----------
    powers : ndarray of shape (n_terms, n_states) of int64
        The multi-indices to check.
    degree, periodic, momentum_degree, separable, max_interaction, couplings, include_constant, mixed
        As for :func:`sk_hamiltonian._space.index_set.index_set` (``couplings``
        as tuples of variable indices, ``periodic`` and ``mixed`` boolean
        arrays; None: no mixed variable).

    Returns
    -------
    problem : str or None
        A description of the first discrepancy found.
    """
    n_terms, n_states = powers.shape
    # Python integers: a parameter given as np.uint8 would wrap in -degree.
    degree = int(degree)
    momentum_degree = None if momentum_degree is None else int(momentum_degree)
    max_interaction = None if max_interaction is None else int(max_interaction)
    if degree > n_terms:
        # Every such space holds each degree 1..degree of some variable.
        return (f"degree={degree} needs at least {degree} basis functions, but powers_ has "
                f"{n_terms}")
    mixed = np.zeros(n_states, dtype=bool) if mixed is None else np.asarray(mixed, dtype=bool)
    space = _Space(n_states, degree, periodic, momentum_degree, separable, max_interaction,
                   couplings, include_constant, mixed)
    outside = space.first_outside(powers)
    if outside is not None:
        return f"powers_ holds {powers[outside].tolist()}, which these parameters exclude"
    keys = np.sort(_keys(powers))
    if n_terms > 1 and np.any(keys[1:] == keys[:-1]):
        return "powers_ holds a basis function twice"
    zero = np.zeros((1, n_states), dtype=powers.dtype)
    has_zero = _contains(keys, zero)[0]
    if include_constant and not has_zero:
        return "powers_ lacks the constant term"
    rows = powers if has_zero else np.concatenate([zero, powers])
    for i in range(n_states):
        if mixed[i]:
            # Legendre degrees up by one; from 0 to cos and sin; codes down by two.
            steps = ((rows[:, i] >= 0, 1), (rows[:, i] == 0, -1), (rows[:, i] == 0, -2),
                     (rows[:, i] < 0, -2))
        else:
            # Raise |alpha_i| by one, in the direction of its sign (from 0: both).
            steps = [(rows[:, i] * sign >= 0, sign) for sign in ((1, -1) if periodic[i] else (1,))]
        for which, step in steps:
            raised = rows[which].copy()
            raised[:, i] += step
            raised = raised[space.contains(raised)]
            found = _contains(keys, raised)
            if not found.all():
                return (f"powers_ lacks {raised[np.argmin(found)].tolist()}, which these "
                        f"parameters include")
    return None


class _Space:
    """Membership in the index set of the parameters, row by row."""

    def __init__(self, n_states, degree, periodic, momentum_degree, separable,
                 max_interaction, couplings, include_constant, mixed):
        self.degree, self.include_constant = degree, include_constant
        self.momentum_degree, self.separable = momentum_degree, separable
        self.max_interaction = max_interaction
        self.mixed = mixed
        self.fixed_sign = ~np.asarray(periodic, dtype=bool) & ~mixed
        self.half = n_states // 2
        self.outside_groups = None
        if couplings is not None:
            groups = np.zeros((len(couplings), n_states), dtype=np.int32)
            for k, group in enumerate(couplings):
                groups[k, list(group)] = 1
            self.outside_groups = (1 - groups).T  # (n_states, n_groups)

    def contains(self, rows):
        """Boolean mask of the rows in the space."""
        return np.concatenate(
            [self._contains(rows[k : k + BLOCK_ROWS]) for k in range(0, len(rows), BLOCK_ROWS)]
        ) if len(rows) else np.zeros(0, dtype=bool)

    def first_outside(self, rows):
        """Index of the first row outside the space, or None."""
        inside = self.contains(rows)
        return None if inside.all() else int(np.argmin(inside))

    def _contains(self, rows):
        # Entries beyond the degree first: np.abs of the most negative int64 is negative.
        lowest = np.where(self.mixed, -2 * self.degree, -self.degree)
        bounded = np.all((rows <= self.degree) & (rows >= lowest), axis=1)
        rows = np.where(bounded[:, None], rows, 0)
        magnitude = factor_degrees(rows, self.mixed)
        total = magnitude.sum(axis=1)
        support = magnitude > 0
        size = support.sum(axis=1)
        ok = bounded & (total <= self.degree) & ~np.any((rows < 0) & self.fixed_sign, axis=1)
        if not self.include_constant:
            ok &= total > 0
        if self.max_interaction is not None:
            ok &= size <= self.max_interaction
        if self.momentum_degree is not None:
            ok &= magnitude[:, : self.half].sum(axis=1) <= self.momentum_degree
        if self.separable:
            ok &= ~(support[:, : self.half].any(axis=1) & support[:, self.half :].any(axis=1))
        if self.outside_groups is not None:
            # Functions of two or more variables: all of them in one group.
            in_a_group = np.any(support.astype(np.int32) @ self.outside_groups == 0, axis=1)
            ok &= (size < 2) | in_a_group
        return ok


def _keys(rows):
    """One opaque, comparable key per row (for sorting and lookup)."""
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    return rows.view(np.dtype((np.void, 8 * rows.shape[1]))).ravel()


def _contains(sorted_keys, rows):
    """Whether each row's key is in ``sorted_keys``."""
    keys = _keys(rows)
    if not len(sorted_keys):
        return np.zeros(len(keys), dtype=bool)
    where = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return sorted_keys[where] == keys
