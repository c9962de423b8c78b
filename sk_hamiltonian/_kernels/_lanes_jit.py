"""Compiled (numba) contraction of many states at once; imported only when numba is.

The kernels of :mod:`._jit` contract one state at a time and vectorize over
the nodes of the prefix tree; every product then loads and stores a partial
sum, and the short sums of the upper levels do not vectorize at all. Here a
block of ``S`` states (the *lanes*) goes through the tree together, the
states innermost: each coefficient, table entry or partial sum of a node is a
row of ``S`` numbers, and every sum over children is a loop over the lanes,
which the compiler vectorizes whatever the shape of the tree.

Three things make it fast, each measured with scratch scripts (the numbers
are on the scaling page of the docs):

- the work arrays are allocated inside the compiled call, so the compiler
  knows they alias nothing (given as arguments, most loops over the lanes
  stayed scalar);
- the lane count is a run-time value (a compile-time one was unrolled into
  scalar code);
- it is a multiple of 8 (:func:`sk_hamiltonian._kernels.lanes`).

Results are the value and the gradient (``R = 1`` or ``2`` table rows) of a
scalar ``sum_j coef[j] phi_j``: what ``predict``, ``hamiltonian`` and
``gradient`` take for batches, and RK4 (:func:`rk4`) for many initial
states. The Hessian, several targets, small batches and the other
integrators stay with :mod:`._jit` and :mod:`._simulate_jit`.

A *tree* is the tuple of :func:`sk_hamiltonian._space.kernel_tree.tree_arrays`; *children* the tuple of
:func:`sk_hamiltonian._space.kernel_tree.children_by_parent`; ``leaf_coef`` the coefficients in the
tree's leaf order.
"""

import math

import numpy as np
from numba import njit

from ._simulate_jit import _wrap


@njit(cache=True, nogil=True, inline="always")
def _tables(X, first, n, family, degree, slope, offset, trig, rate, T, w):
    """``T[i, c, r, s]``: ``slope**r`` times the r-th derivative of column c of variable i at lane s.

    Lanes past the ``n`` states from ``first`` repeat the last state (their
    results are not stored). Families as in :func:`._jit.fill_tables`.
    """
    S = T.shape[3]
    R = T.shape[2]
    m = X.shape[1]
    for i in range(m):
        s_i = slope[i]
        for s in range(S):
            w[s] = X[first + min(s, n - 1), i] * s_i + offset[i]
        n_i = degree[i]
        if family[i] != 1:
            # Legendre: the three-term recurrence and P'_{k+1} = P'_{k-1} +
            # (2k + 1) P_k (with the chain-rule factor), as in _jit.fill_tables.
            for s in range(S):
                T[i, 0, 0, s] = 1.0
            if n_i >= 1:
                for s in range(S):
                    T[i, 1, 0, s] = w[s]
            for k in range(1, n_i):
                a = (2 * k + 1) / (k + 1)
                b = k / (k + 1)
                for s in range(S):
                    T[i, k + 1, 0, s] = a * w[s] * T[i, k, 0, s] - b * T[i, k - 1, 0, s]
            if R > 1:
                for s in range(S):
                    T[i, 0, 1, s] = 0.0
                if n_i >= 1:
                    for s in range(S):
                        T[i, 1, 1, s] = s_i
                for k in range(1, n_i):
                    f = (2 * k + 1) * s_i
                    for s in range(S):
                        T[i, k + 1, 1, s] = T[i, k - 1, 1, s] + f * T[i, k, 0, s]
            if family[i] == 2:
                r_i = rate[i]
                for s in range(S):
                    w[s] = X[first + min(s, n - 1), i] * r_i
                _lane_fourier(w, r_i, trig[i], n_i, R, T, i)
        else:
            for s in range(S):
                T[i, 0, 0, s] = 1.0
                if R > 1:
                    T[i, 0, 1, s] = 0.0
            _lane_fourier(w, s_i, n_i, 0, R, T, i)


@njit(cache=True, nogil=True, inline="always")
def _lane_fourier(w, s_i, n_i, first, R, T, i):
    """Columns ``first + 2k - 1``, ``first + 2k``: cos and sin of ``k w`` at every lane."""
    S = T.shape[3]
    for k in range(1, n_i + 1):
        for s in range(S):
            angle = k * w[s]
            c = math.cos(angle)
            sn = math.sin(angle)
            T[i, first + 2 * k - 1, 0, s] = c
            T[i, first + 2 * k, 0, s] = sn
            if R > 1:
                T[i, first + 2 * k - 1, 1, s] = -(k * sn) * s_i
                T[i, first + 2 * k, 1, s] = (k * c) * s_i


@njit(cache=True, nogil=True, inline="always")
def _contract(T, tree, children, leaf_coef, leaf, cur, nxt):
    """The root's value (and gradient) at the lanes: (1 + m (R - 1), S).

    Leaves: each prefix sums its functions' coefficients times the last
    variable's table (value and, R = 2, its derivative). Level by level up,
    each parent sums its children times the table of its variable: the value,
    the derivative along that variable, and the derivatives carried from
    below. A node of prefix length ``k`` carries the value (slot 0) and
    ``d/dx_j`` for ``j >= k`` (slot ``1 + j - k``).

    The prefixes' sums are added into their parents as soon as they are
    made (one prefix in ``leaf`` at a time): stored for every prefix, they
    outgrow the caches (1.7 MB for the 816 prefixes of a degree-15 space in
    four variables at 128 lanes) and the next level reads them back from
    memory.
    """
    leaf_start, leaf_column = tree[4], tree[5]
    level_start, level_key, node_counts = tree[6], tree[8], tree[9]
    child_order, child_start, child_offset = children
    m = T.shape[0]
    R = T.shape[2]
    if m == 1:  # the root is the only prefix
        _leaf_sums(0, T, leaf_start, leaf_column, leaf_coef, leaf)
        return leaf[0]
    src = leaf
    n_in = R
    for L in range(m - 1):
        v = m - 2 - L  # the variable this level sums (prefixes of length v + 1 into v)
        n_out = 1 if R == 1 else n_in + 1
        dst = cur if L % 2 == 0 else nxt
        order = child_order[level_start[L]:level_start[L + 1]]
        keys = level_key[level_start[L]:level_start[L + 1]]
        starts = child_start[child_offset[L]:child_offset[L + 1]]
        for P in range(node_counts[L + 1]):
            for j in range(starts[P], starts[P + 1]):
                child = order[j]
                row = child
                if L == 0:
                    _leaf_sums(child, T, leaf_start, leaf_column, leaf_coef, leaf)
                    row = 0
                _add_child(dst, P, src, row, T, v, keys[child], n_in, j == starts[P])
        src = dst
        n_in = n_out
    return src[0]


@njit(cache=True, nogil=True, inline="always")
def _leaf_sums(p, T, leaf_start, leaf_column, leaf_coef, leaf):
    """``leaf[0, r, s]``: prefix ``p``'s coefficients times the last variable's table row ``r``."""
    last = T.shape[0] - 1
    R = T.shape[2]
    S = T.shape[3]
    j0 = leaf_start[p]
    c = leaf_column[j0]
    w = leaf_coef[j0]
    # The first term is stored rather than added to zeros (fewer stores).
    for r in range(R):
        for s in range(S):
            leaf[0, r, s] = w * T[last, c, r, s]
    for j in range(j0 + 1, leaf_start[p + 1]):
        c = leaf_column[j]
        w = leaf_coef[j]
        if R == 1:
            for s in range(S):
                leaf[0, 0, s] += w * T[last, c, 0, s]
        else:
            for s in range(S):
                leaf[0, 0, s] += w * T[last, c, 0, s]
                leaf[0, 1, s] += w * T[last, c, 1, s]


@njit(cache=True, nogil=True, inline="always")
def _add_child(dst, P, src, row, T, v, c, n_in, first):
    """Child ``row`` of ``src`` times column ``c`` of variable ``v``, into parent ``P`` of ``dst``.

    The child carries ``n_in`` slots, the parent one more (R = 2). Stored if
    it is the parent's ``first`` child, else added.
    """
    R = T.shape[2]
    S = T.shape[3]
    if first:
        for s in range(S):
            dst[P, 0, s] = src[row, 0, s] * T[v, c, 0, s]
        if R > 1:
            for s in range(S):
                dst[P, 1, s] = src[row, 0, s] * T[v, c, 1, s]
            for t in range(1, n_in):
                for s in range(S):
                    dst[P, t + 1, s] = src[row, t, s] * T[v, c, 0, s]
    elif R == 1:
        for s in range(S):
            dst[P, 0, s] += src[row, 0, s] * T[v, c, 0, s]
    else:
        # The value's two products share their loads.
        for s in range(S):
            x = src[row, 0, s]
            t0 = T[v, c, 0, s]
            dst[P, 0, s] += x * t0
            dst[P, 1, s] += x * T[v, c, 1, s]
            dst[P, 2, s] += src[row, 1, s] * t0
        for t in range(2, n_in):
            for s in range(S):
                dst[P, t + 1, s] += src[row, t, s] * T[v, c, 0, s]


@njit(cache=True, nogil=True)
def evaluate(X, tree, children, leaf_coef, order, lanes, value, grad):
    """Value (n,) and, ``order`` 1, gradient (n, m) of ``sum_j coef[j] phi_j`` at the rows of ``X``.

    In blocks of ``lanes`` states (the last block repeats its last state).
    """
    n, m = X.shape
    R = order + 1
    T, w, leaf, cur, nxt = _work(tree, m, R, lanes)
    for first in range(0, n, lanes):
        count = min(lanes, n - first)
        _tables(X, first, count, tree[0], tree[1], tree[2], tree[3], tree[13], tree[14], T, w)
        root = _contract(T, tree, children, leaf_coef, leaf, cur, nxt)
        for s in range(count):
            value[first + s] = root[0, s]
            if order >= 1:
                for i in range(m):
                    grad[first + s, i] = root[1 + i, s]


@njit(cache=True, nogil=True, inline="always")
def _work(tree, m, R, lanes):
    """Fresh work arrays (allocated here, so that the compiler sees they alias nothing).

    Every entry is written before it is read: the tables up to each
    variable's degree, the nodes' first terms by assignment.
    """
    n_parents = 1
    for L in range(1, tree[9].shape[0]):
        n_parents = max(n_parents, tree[9][L])
    return (np.empty((m, tree[10], R, lanes)), np.empty(lanes), np.empty((1, R, lanes)),
            np.empty((n_parents, 1 + m * (R - 1), lanes)),
            np.empty((n_parents, 1 + m * (R - 1), lanes)))


@njit(cache=True, nogil=True, inline="always")
def _field_lanes(Y, tree, children, leaf_coef, gamma, n, work, F):
    """The field at the first ``n`` rows of ``Y`` (one pass of lanes) into ``F``."""
    T, w, leaf, cur, nxt = work
    m = Y.shape[1]
    d = m // 2
    _tables(Y, 0, n, tree[0], tree[1], tree[2], tree[3], tree[13], tree[14], T, w)
    root = _contract(T, tree, children, leaf_coef, leaf, cur, nxt)
    for s in range(n):
        for i in range(d):
            F[s, i] = -root[1 + d + i, s] - gamma[i] * root[1 + i, s]
            F[s, d + i] = root[1 + i, s]


@njit(cache=True, nogil=True)
def rk4(tree, children, leaf_coef, gamma, periodic, low, high, y0, n_sub, h, lanes, out, failed_at):
    """RK4 of a Hamiltonian's field from every row of ``y0``, the states of a pass in step.

    As :func:`._simulate_jit.integrate` with method 0 (the same steps,
    failure rule and wrapping of periodic variables at output times); the
    states of a pass share each evaluation of the field.
    """
    n, m = y0.shape
    n_times = out.shape[0]
    work = _work(tree, m, 2, lanes)
    Y = np.empty((lanes, m))
    Z = np.empty((lanes, m))
    stages = np.empty((4, lanes, m))
    # The stages' shifts, in units of the step (one call site of the field:
    # each inlined copy of it costs compile time).
    shift = (0.0, 0.5, 0.5, 1.0)
    last = np.empty((lanes, m))
    for first in range(0, n, lanes):
        count = min(lanes, n - first)
        for s in range(count):
            for i in range(m):
                last[s, i] = y0[first + s, i]
            _wrap(last[s], periodic, low, high)
            failed_at[first + s] = n_times
            for i in range(m):
                out[0, first + s, i] = last[s, i]
        for k in range(n_times - 1):
            Y[:count] = last[:count]
            for _ in range(n_sub[k]):
                for stage in range(4):
                    step = shift[stage] * h[k]
                    for s in range(count):
                        for i in range(m):
                            Z[s, i] = Y[s, i] if stage == 0 else Y[s, i] + step * stages[stage - 1, s, i]
                    _field_lanes(Z, tree, children, leaf_coef, gamma, count, work, stages[stage])
                sixth = h[k] / 6.0
                k1, k2, k3, k4 = stages[0], stages[1], stages[2], stages[3]
                for s in range(count):
                    for i in range(m):
                        Y[s, i] = Y[s, i] + sixth * (k1[s, i] + 2.0 * (k2[s, i] + k3[s, i]) + k4[s, i])
            for s in range(count):
                if failed_at[first + s] < n_times:
                    out[k + 1, first + s] = last[s]  # failed before: frozen
                    continue
                finite = True
                for i in range(m):
                    if not math.isfinite(Y[s, i]):
                        finite = False
                if not finite:
                    failed_at[first + s] = k + 1
                    out[k + 1, first + s] = last[s]
                    continue
                _wrap(Y[s], periodic, low, high)
                for i in range(m):
                    last[s, i] = Y[s, i]
                    out[k + 1, first + s, i] = Y[s, i]

