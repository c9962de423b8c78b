"""``predict`` of a few states in one compiled call, its checks included; imported only when numba is.

For one state the contraction itself takes a few microseconds, and what a
call of :func:`._jit.fields` costs around it (unboxing some 30 arrays,
comparing the coefficients with those bound, checking the states for
finiteness and against the domain in Python) took as long again. Here the
bound arrays come packed (:mod:`.packing`), and the kernel itself compares
the coefficients it is given with the ones it was bound to, checks the
states and counts those outside the domain, then calls the general path's
compiled :func:`._jit.fields`, so the answers are the same to the bit and
the contraction is compiled once for both.
"""

import math

import numpy as np
from numba import njit

from ._jit import fields
from .packing import SLOTS

# Status codes of checked_fields besides a count of states outside.
STALE = -1  # the coefficients differ from the ones bound: nothing computed
NOT_FINITE = -2  # a state has a NaN or an infinity: nothing computed


@njit(cache=True, nogil=True, inline="always")
def _ints(ints, k):
    o = ints[SLOTS * k]
    return ints[o : o + ints[SLOTS * k + 1]]


@njit(cache=True, nogil=True, inline="always")
def _ints2(ints, k):
    o, a, b = ints[SLOTS * k], ints[SLOTS * k + 1], ints[SLOTS * k + 2]
    return ints[o : o + a * b].reshape((a, b))


@njit(cache=True, nogil=True, inline="always")
def _floats(ints, floats, k):
    o = ints[SLOTS * k]
    return floats[o : o + ints[SLOTS * k + 1]]


@njit(cache=True, nogil=True, inline="always")
def _floats2(ints, floats, k):
    o, a, b = ints[SLOTS * k], ints[SLOTS * k + 1], ints[SLOTS * k + 2]
    return floats[o : o + a * b].reshape((a, b))


@njit(cache=True, nogil=True, inline="always")
def _floats3(ints, floats, k):
    o, a, b, c = ints[SLOTS * k], ints[SLOTS * k + 1], ints[SLOTS * k + 2], ints[SLOTS * k + 3]
    return floats[o : o + a * b * c].reshape((a, b, c))


@njit(cache=True, nogil=True, inline="always")
def unpack(ints, floats):
    """The views of the items :func:`sk_hamiltonian._space.compiled.checked_field` packs, in its order.

    Returns ``(tree, C, flat, snapshot)``: the tree and flat tuples of
    :func:`sk_hamiltonian._space.compiled.bound_kernels`, the bound coefficients
    and the coefficients they were bound from. The items are, in order, the
    15 of the tree (0 to 14, the width a plain integer), the bound
    coefficients (15), the 10 of the flat tuple (16 to 25, its flags as
    integers) and the coefficients (26).
    """
    tree = (_ints(ints, 0), _ints(ints, 1), _floats(ints, floats, 2), _floats(ints, floats, 3),
            _ints(ints, 4), _ints(ints, 5), _ints(ints, 6), _ints(ints, 7), _ints(ints, 8),
            _ints(ints, 9), ints[SLOTS * 10], _ints(ints, 11), _ints2(ints, 12),
            _ints(ints, 13), _floats(ints, floats, 14))
    C = _floats3(ints, floats, 15)
    flat = (_ints(ints, 16) != 0, _ints2(ints, 17), _ints(ints, 18), _floats2(ints, floats, 19),
            _ints2(ints, 20), _ints(ints, 21), _floats2(ints, floats, 22),
            _ints2(ints, 23), _ints(ints, 24), _floats2(ints, floats, 25))
    snapshot = _floats(ints, floats, 26)
    return tree, C, flat, snapshot


@njit(cache=True, nogil=True)
def checked_fields(kind, X, coef, domain, periodic, slack, gamma, ints, floats, T, cur, nxt, pad, out):
    """The field ``(J^{-1} - Gamma) grad H`` at the rows of ``X`` into ``out``, after predict's checks.

    Parameters
    ----------
    kind : int
        0, as :func:`._jit.fields` takes it (an argument, not a constant in
        the call below: a literal would compile that kernel once more).
    X : ndarray of shape (n, m)
        States.
    coef : ndarray of shape (n_terms,)
        The model's coefficients now; compared bit for bit with those bound.
    domain : ndarray of shape (m, 2)
        The box of the domain check, widened by ``slack`` times each width
        (as :func:`sk_hamiltonian._space.space.outside_domain`).
    periodic : ndarray of shape (m,) of bool
        Variables never outside.
    slack : float
    gamma : ndarray of shape (m // 2,)
        Damping.
    ints, floats : ndarray
        The packed tree and coefficients.
    T, cur, nxt, pad : ndarray
        The work arrays of :func:`._jit.work` (one coefficient column).
    out : ndarray of shape (n, m)

    Returns
    -------
    status : int
        ``STALE`` or ``NOT_FINITE`` (nothing computed), else the number of
        rows outside the domain.
    """
    tree, C, flat, snapshot = unpack(ints, floats)
    if coef.shape[0] != snapshot.shape[0]:
        return STALE
    # Bit for bit, as the bindings are cached by the coefficients' bytes (a
    # NaN equals itself, -0.0 differs from 0.0). No early exit: the loop then
    # vectorizes (1.5 against 2.7 us for 3 875 coefficients, a scratch timing
    # of both under load).
    bits = coef.view(np.int64)
    bound_bits = snapshot.view(np.int64)
    differ = 0
    for j in range(bits.shape[0]):
        differ |= bits[j] ^ bound_bits[j]
    if differ != 0:
        return STALE
    n, m = X.shape
    for s in range(n):
        for i in range(m):
            if not math.isfinite(X[s, i]):
                return NOT_FINITE
    outside = 0
    for s in range(n):
        for i in range(m):
            if periodic[i]:
                continue
            margin = slack * (domain[i, 1] - domain[i, 0])
            if X[s, i] < domain[i, 0] - margin or X[s, i] > domain[i, 1] + margin:
                outside += 1
                break
    # A call, not an inlined copy: the general path's compiled kernel, for
    # the same answers and without compiling the contraction once more.
    fields(kind, X, tree, C, flat, gamma, out, T, cur, nxt, pad)
    return outside
