"""Index sets: which tensor-product basis functions enter a model.

A basis function is named by a multi-index ``alpha`` with one entry per state
variable: a Legendre degree for an ordinary variable, a signed frequency for a
periodic one (``+k``: ``cos(k theta)``, ``-k``: ``sin(k theta)``, see
:mod:`.fourier`). Its degree is ``sum_i |alpha_i|``.

:func:`index_set` *generates* the multi-indices that satisfy every constraint
(total degree, degree in the momenta, separability, number of interacting
variables, which variables may interact) rather than filtering a total-degree
list, so that spaces over many variables with few interactions (a 64-variable
lattice) cost what they hold.
"""

from itertools import combinations
from math import comb

import numpy as np

from .mixed import factor_degrees, mixed_code


def _positive_compositions(size, max_total):
    """Rows of ``size`` positive integers with sum at most ``max_total``."""
    rows = [()]
    for _ in range(size):
        rows = [r + (k,) for r in rows for k in range(1, max_total - sum(r) - (size - len(r)) + 2)]
    return np.array(rows, dtype=np.intp).reshape(-1, size)


def _supports(n_states, size, separable, couplings=None):
    """Sets of ``size`` variables a basis function may depend on, as rows."""
    if not separable:
        groups = [range(n_states)]
    else:
        half = n_states // 2
        groups = [range(half), range(half, n_states)]
    if couplings is not None and size > 1:
        # Every variable of a coupled function lies in one coupling group
        # (and, if separable, in one half).
        groups = [sorted(set(c) & set(g)) for c in couplings for g in groups]
    # Overlapping groups share subsets: each set once, in a fixed order.
    rows = sorted({c for group in groups for c in combinations(group, size)})
    return np.array(rows, dtype=np.intp).reshape(-1, size)


def index_set(
    n_states,
    degree,
    *,
    periodic=None,
    momentum_degree=None,
    separable=False,
    max_interaction=None,
    couplings=None,
    include_constant=False,
    mixed=None,
):
    """Multi-indices of a tensor-product space, in graded order.

    Parameters
    ----------
    n_states : int
        Number of variables ``m``. Where ``momentum_degree`` or ``separable``
        are used, ``m = 2d`` is even and the first ``d`` variables are the
        momenta.
    degree : int
        Largest total degree ``sum_i |alpha_i|``.
    periodic : ndarray of shape (n_states,) of bool, default=None
        Which variables are periodic; each non-zero frequency of one of them
        gives two basis functions (cosine and sine).
    momentum_degree : int, default=None
        Largest total degree in the momenta; None: no limit beyond ``degree``.
    separable : bool, default=False
        No basis function depends on both a momentum and a position.
    max_interaction : int, default=None
        Most variables one basis function depends on; None: no limit.
    couplings : sequence of sequences of int, default=None
        Groups of variables that may be coupled: a basis function of two or
        more variables enters only if they all lie in one group (functions of
        one variable always may). None: any variables may be coupled.
    include_constant : bool, default=False
        Whether the zero multi-index comes first.
    mixed : ndarray of shape (n_states,) of bool, default=None
        Which variables are mixed (:mod:`.mixed`): each non-zero degree ``k`` of
        one of them gives three basis functions, the Legendre polynomial of
        degree ``k``, ``cos(k x)`` and ``sin(k x)``, with the codes of
        :mod:`.mixed`. None: no mixed variable.

    Returns
    -------
    powers : ndarray of shape (n_terms, n_states)
        One multi-index per row, ordered by degree, then by decreasing
        ``|alpha_1|``, ``|alpha_2|``, ..., Legendre factors before cosines
        before sines. On a total-degree set without periodic variables this is
        the order of the paper's basis.
    """
    periodic = np.zeros(n_states, dtype=bool) if periodic is None else np.asarray(periodic)
    largest = n_states if max_interaction is None else min(max_interaction, n_states)
    blocks = [np.zeros((1, n_states), dtype=np.intp)] if include_constant else []
    for size in range(1, min(largest, degree) + 1):
        supports = _supports(n_states, size, separable, couplings)
        parts = _positive_compositions(size, degree)
        if supports.size == 0 or parts.size == 0:
            continue
        rows = np.zeros((supports.shape[0] * parts.shape[0], n_states), dtype=np.intp)
        which = np.repeat(supports, parts.shape[0], axis=0)
        np.put_along_axis(rows, which, np.tile(parts, (supports.shape[0], 1)), axis=1)
        if momentum_degree is not None:
            rows = rows[rows[:, : n_states // 2].sum(axis=1) <= momentum_degree]
        blocks.append(rows)
    powers = np.concatenate(blocks) if blocks else np.zeros((0, n_states), dtype=np.intp)
    # Each non-zero frequency of a periodic variable stands for a cosine and a sine.
    for i in np.flatnonzero(periodic):
        sines = powers[powers[:, i] != 0].copy()
        sines[:, i] *= -1
        powers = np.concatenate([powers, sines])
    # Each non-zero degree of a mixed variable also stands for a cosine and a sine.
    mixed = np.zeros(n_states, dtype=bool) if mixed is None else np.asarray(mixed, dtype=bool)
    for i in np.flatnonzero(mixed):
        rows = powers[powers[:, i] != 0]
        cosines, sines = rows.copy(), rows.copy()
        cosines[:, i] = mixed_code(rows[:, i])
        sines[:, i] = mixed_code(-rows[:, i])
        powers = np.concatenate([powers, cosines, sines])
    magnitude = factor_degrees(powers, mixed)
    # The kind of each factor: 0 Legendre or cosine of an angle, 1 sine of an
    # angle; for mixed variables 0 Legendre, 1 cosine, 2 sine.
    kind = (powers < 0).astype(np.intp)
    kind[:, mixed] += (powers[:, mixed] < 0) & (powers[:, mixed] % 2 == 0)
    keys = tuple(kind[:, i] for i in reversed(range(n_states)))
    keys += tuple(-magnitude[:, i] for i in reversed(range(n_states)))
    order = np.lexsort(keys + (magnitude.sum(axis=1),))
    return powers[order]


def count_index_set(
    n_states,
    degree,
    *,
    periodic=None,
    momentum_degree=None,
    separable=False,
    max_interaction=None,
    couplings=None,
    include_constant=False,
    mixed=None,
):
    """Number of multi-indices :func:`index_set` returns, counted without building them.

    Closed forms, so that a space too large to build (degree ``10**6``, or
    60 in four variables) is measured in microseconds. A basis function
    depends on a *support* of ``s`` variables, ``a`` momenta and ``b``
    positions of them, with positive degrees summing to at most
    ``degree``: ``C(degree, s)`` of them, or with ``momentum_degree`` ``M``
    the Vandermonde sum ``sum_j C(M, a + j) C(degree - M, b - j)``; each
    periodic variable of the support doubles them (a cosine and a sine), each
    mixed one triples them (a polynomial, a cosine and a sine).
    With ``couplings`` the supports of two or more variables are the
    distinct subsets of the groups, counted by inclusion and exclusion over
    the groups' intersections.

    Parameters
    ----------
    n_states, degree, periodic, momentum_degree, separable, max_interaction, couplings, include_constant, mixed
        As :func:`index_set` takes them.

    Returns
    -------
    n_terms : int
        Exactly ``index_set(...).shape[0]``.
    """
    periodic = np.zeros(n_states, dtype=bool) if periodic is None else np.asarray(periodic, bool)
    mixed = np.zeros(n_states, dtype=bool) if mixed is None else np.asarray(mixed, bool)
    largest = n_states if max_interaction is None else min(max_interaction, n_states)
    largest = min(largest, degree)
    split = momentum_degree is not None or separable
    half = n_states // 2 if split else 0
    momentum_cap = degree if momentum_degree is None else min(momentum_degree, degree)

    def compositions(a, b):
        # Positive degrees on a momenta and b positions: total <= degree,
        # momenta's total <= momentum_cap.
        if a == 0 or momentum_cap >= degree:
            return comb(degree, a + b)
        return sum(comb(momentum_cap, a + j) * comb(degree - momentum_cap, b - j)
                   for j in range(b + 1))

    def weighted_subsets(variables, smallest):
        # Sum over the subsets of `variables` with smallest..largest members of
        # 2**(periodic members) times their compositions.
        variables = list(variables)
        momenta = [i for i in variables if i < half]
        positions = [i for i in variables if i >= half]
        by_size = []
        for members in (momenta, positions):
            # Subsets of k members weighted by 2 per periodic member and 3 per
            # mixed one: the coefficients of prod(1 + weight x).
            ways = [1]
            for i in members:
                w = 2 if periodic[i] else 3 if mixed[i] else 1
                ways = [a + w * b for a, b in zip(ways + [0], [0] + ways)]
            by_size.append(ways)
        total = 0
        for a, ways_a in enumerate(by_size[0]):
            for b, ways_b in enumerate(by_size[1]):
                if smallest <= a + b <= largest and not (separable and a and b):
                    total += ways_a * ways_b * compositions(a, b)
        return total

    count = 1 if include_constant else 0
    if largest < 1:
        return count
    if couplings is None:
        if not separable:
            return count + weighted_subsets(range(n_states), 1)
        return (count + weighted_subsets(range(half), 1)
                + weighted_subsets(range(half, n_states), 1))
    # Functions of one variable always enter; those of two or more, on the
    # distinct subsets of the groups (within one half, if separable).
    count += weighted_subsets(range(n_states), 1) - weighted_subsets(range(n_states), 2)
    halves = [range(half), range(half, n_states)] if separable else [range(n_states)]
    groups = {frozenset(c) & frozenset(h) for c in couplings for h in halves}
    groups = [g for g in groups if len(g) >= 2]
    # A group inside another adds no subset.
    groups = [g for g in groups if not any(g < other for other in groups)]
    return count + _union_of_subsets(groups, lambda g: weighted_subsets(sorted(g), 2))


def _union_of_subsets(groups, weight):
    """``weight`` summed over the distinct subsets of the ``groups`` (inclusion-exclusion).

    ``weight(g)`` sums over the subsets of ``g`` with at least two members;
    an intersection of fewer than two variables holds none, which prunes
    the search (a chain's pairs meet in one variable: no term beyond the
    groups themselves).
    """
    total = 0

    def visit(start, common, sign):
        nonlocal total
        for i in range(start, len(groups)):
            meet = groups[i] if common is None else common & groups[i]
            if len(meet) >= 2:
                total += sign * weight(meet)
                visit(i + 1, meet, -sign)

    visit(0, None, 1)
    return total
