"""The compiled (numba) contraction kernels; imported only when numba is.

One state at a time, scalar loops: the factor tables of every variable
(Legendre by its three-term recurrence, Fourier by cosines and sines), then
the contraction of the coefficients along the prefix tree of the index set
(see :mod:`sk_hamiltonian._space.contraction` for the idea): the leaves sum
the last variable's table against each prefix's coefficients, and every level
sums its nodes into their parents, carrying the value, the derivatives along
the variables summed so far and (order 2) their second derivatives. Each
sum over a column runs over the nodes that have it (``column_counts``),
never over the zeros of the dense arrays.

A *tree* is the tuple built by :func:`sk_hamiltonian._space.kernel_tree.tree_arrays`::

    (family, degree, slope, offset, leaf_start, leaf_column, level_start,
     level_parent, level_key, node_counts, width, level_pos, column_counts,
     trig_degree, trig_rate)

and the coefficients are bound to it as a dense ``(width, K, n_prefixes)``
array (:func:`sk_hamiltonian._space.compiled.bound_kernels`). The carried derivatives
of the nodes of a level are ``P = 1 + m + m * m`` rows of nodes: the value,
``d/dx_i`` at ``1 + i`` and ``d2/dx_i dx_j`` (``i <= j``) at ``1 + m + i * m
+ j``.
"""

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def fill_tables(x, family, degree, slope, offset, trig, rate, order, T):
    """``T[i, r, c]``: r-th derivative of column c of variable i's family at ``x[i]``.

    Family 0 is Legendre, 1 Fourier, 2 mixed: Legendre columns ``0..degree``,
    then ``trig[i]`` Fourier frequencies at the angle ``rate[i] * x[i]``.
    """
    m = x.shape[0]
    for i in range(m):
        s = slope[i]
        w = x[i] * s + offset[i]
        n = degree[i]
        if family[i] != 1:
            T[i, 0, 0] = 1.0
            if n >= 1:
                T[i, 0, 1] = w
            for k in range(1, n):
                T[i, 0, k + 1] = ((2 * k + 1) / (k + 1)) * w * T[i, 0, k] - (k / (k + 1)) * T[i, 0, k - 1]
            # P'_{k+1} = P'_{k-1} + (2k + 1) P_k, and the same one order up,
            # with the chain-rule factor s**r carried along (no pass of
            # powers afterwards): row r holds s**r times the r-th derivative.
            for r in range(1, order + 1):
                T[i, r, 0] = 0.0
                if n >= 1:
                    T[i, r, 1] = s if r == 1 else 0.0
                for k in range(1, n):
                    T[i, r, k + 1] = T[i, r, k - 1] + ((2 * k + 1) * s) * T[i, r - 1, k]
            if family[i] == 2:
                _fill_fourier(x[i] * rate[i], rate[i], trig[i], n, order, T, i)
        else:
            T[i, 0, 0] = 1.0
            for r in range(1, order + 1):
                T[i, r, 0] = 0.0
            _fill_fourier(w, s, n, 0, order, T, i)


@njit(cache=True, nogil=True, inline="always")
def _fill_fourier(w, s, n, first, order, T, i):
    """Columns ``first + 2k - 1`` and ``first + 2k``: cos and sin of ``k w``, ``k = 1..n``."""
    for k in range(1, n + 1):
        angle = k * w
        c = math.cos(angle)
        sn = math.sin(angle)
        T[i, 0, first + 2 * k - 1] = c
        T[i, 0, first + 2 * k] = sn
        if order >= 1:
            T[i, 1, first + 2 * k - 1] = -(k * sn) * s
            T[i, 1, first + 2 * k] = (k * c) * s
        if order >= 2:
            T[i, 2, first + 2 * k - 1] = -(k * k * c) * (s * s)
            T[i, 2, first + 2 * k] = -(k * k * sn) * (s * s)


@njit(cache=True, nogil=True)
def contract_tables(T, tree, C, order, cur, nxt, pad):
    """Contract the bound coefficients ``C`` with the tables ``T``; returns the root's results.

    ``C`` is (width, K, n_prefixes): ``C[c, k, p]`` the coefficient for target
    ``k`` of the function with prefix ``p`` and last column ``c``.
    ``cur`` and ``nxt`` are work arrays of shape (P, K, max nodes) and
    ``pad`` the levels' padded arrays (zero where no node); the result
    is ``out[q, k]`` (pattern, target) of the root, a view of one of them.
    Every inner loop runs over nodes (contiguous, independent sums), which
    the compiler vectorizes; loops over each node's children would end in a
    mispredicted branch every few terms.
    """
    level_start, node_counts, counts = tree[6], tree[9], tree[12]
    m = T.shape[0]
    width, K, n_prefixes = C.shape
    last = m - 1
    rows = (0, 1 + last, 1 + m + last * m + last)
    for r in range(order + 1):
        for kk in range(K):
            out = cur[rows[r], kk]
            for p in range(n_prefixes):
                out[p] = 0.0
            for c in range(width):
                t = T[last, r, c]
                if t != 0.0:
                    coef = C[c, kk]
                    for p in range(counts[0, c]):
                        out[p] += coef[p] * t
    # Level k (prefixes of length k, k = m - 1 .. 1) sums variable k - 1.
    # Each carried row of nodes is scattered into the level's padded
    # (column, parent) array, whose other entries stay zero for good; the
    # sum over children is then a dense product over the parents, which the
    # compiler vectorizes (a loop adding children into parents one by one
    # waits on the previous addition to the same parent).
    level_pos, pads = tree[11], pad
    offset = 0
    for L in range(m - 1):
        k = m - 1 - L
        v = k - 1
        n_parents = node_counts[L + 1]
        first, stop = level_start[L], level_start[L + 1]
        pos = level_pos[first:stop]
        level_pad = pads[offset : offset + width * n_parents]
        offset += width * n_parents
        for kk in range(K):
            _scatter(cur[0, kk], level_pad, pos)
            _dense_sum(level_pad, T[v, 0], nxt[0, kk], n_parents, counts[L + 1])
            if order >= 1:
                _dense_sum(level_pad, T[v, 1], nxt[1 + v, kk], n_parents, counts[L + 1])
            if order >= 2:
                _dense_sum(level_pad, T[v, 2], nxt[1 + m + v * m + v, kk], n_parents, counts[L + 1])
            if order >= 1:
                for j in range(k, m):
                    _scatter(cur[1 + j, kk], level_pad, pos)
                    _dense_sum(level_pad, T[v, 0], nxt[1 + j, kk], n_parents, counts[L + 1])
                    if order >= 2:
                        _dense_sum(level_pad, T[v, 1], nxt[1 + m + v * m + j, kk], n_parents, counts[L + 1])
            if order >= 2:
                for i in range(k, m):
                    for j in range(i, m):
                        q = 1 + m + i * m + j
                        _scatter(cur[q, kk], level_pad, pos)
                        _dense_sum(level_pad, T[v, 0], nxt[q, kk], n_parents, counts[L + 1])
        cur, nxt = nxt, cur
    return cur[:, :, 0]


@njit(cache=True, nogil=True, inline="always")
def _scatter(row, pad, pos):
    for n in range(pos.shape[0]):
        pad[pos[n]] = row[n]


@njit(cache=True, nogil=True, inline="always")
def _dense_sum(pad, table, out, n_parents, counts):
    """``out[p] = sum_c pad[c * n_parents + p] * table[c]``, over ``p < counts[c]`` (the rest are zeros)."""
    for p in range(n_parents):
        out[p] = 0.0
    for c in range(table.shape[0]):
        t = table[c]
        if t != 0.0:
            for p in range(counts[c]):
                out[p] += pad[c * n_parents + p] * t


@njit(cache=True, nogil=True, inline="always")
def flat_contract(T, keys, rows, W, root):
    """The flat contraction (:mod:`sk_hamiltonian._space.flat`) into ``root`` (P, K).

    ``T`` is the work table (m, 3, width); ``keys`` index it flattened;
    function ``f`` adds ``W[f, k] * prod_t T[keys[f, t]]`` to ``root[rows[f], k]``.
    """
    table = T.reshape(T.size)
    K = root.shape[1]
    for q in range(root.shape[0]):
        for kk in range(K):
            root[q, kk] = 0.0
    n_slots = keys.shape[1]
    for f in range(keys.shape[0]):
        v = table[keys[f, 0]]
        for t in range(1, n_slots):
            v *= table[keys[f, t]]
        r = rows[f]
        for kk in range(K):
            root[r, kk] += W[f, kk] * v
    return root


@njit(cache=True, nogil=True, inline="always")
def contract_root(x, tree, C, flat, order, T, cur, nxt, pad):
    """Tables at the state ``x``, then the root's results by the flat or the tree contraction.

    ``flat`` is the last item of :func:`sk_hamiltonian._space.compiled.bound_kernels`:
    ``(use, keys0, rows0, W0, keys1, rows1, W1, keys2, rows2, W2)``,
    ``use[order]`` saying whether order ``order`` contracts flat (into the
    work array ``cur``, as the tree does).
    """
    fill_tables(x, tree[0], tree[1], tree[2], tree[3], tree[13], tree[14], order, T)
    if flat[0][order]:
        root = cur[:, :, 0]
        if order == 0:
            return flat_contract(T, flat[1], flat[2], flat[3], root)
        if order == 1:
            return flat_contract(T, flat[4], flat[5], flat[6], root)
        return flat_contract(T, flat[7], flat[8], flat[9], root)
    return contract_tables(T, tree, C, order, cur, nxt, pad)


@njit(cache=True, nogil=True)
def _work(tree, K, m):
    width = tree[10]
    size = 0
    for count in tree[9]:
        size = max(size, count)
    P = 1 + m + m * m
    n_pad = 0
    for L in range(tree[9].shape[0] - 1):
        n_pad += width * tree[9][L + 1]
    # The tables and the padded arrays must start at zero (entries no state
    # writes are read as zeros); the node rows are written before being read.
    return (np.zeros((m, 3, width)), np.empty((P, K, size)), np.empty((P, K, size)),
            np.zeros(n_pad))


@njit(cache=True, nogil=True)
def _store(root, s, order, m, value, grad, hess):
    K = root.shape[1]
    for kk in range(K):
        value[s, kk] = root[0, kk]
        if order >= 1:
            for i in range(m):
                grad[s, i, kk] = root[1 + i, kk]
        if order >= 2:
            for i in range(m):
                for j in range(i, m):
                    hess[s, i, j, kk] = root[1 + m + i * m + j, kk]
                    hess[s, j, i, kk] = root[1 + m + i * m + j, kk]


@njit(cache=True, nogil=True)
def evaluate(X, tree, coef, flat, order, value, grad, hess, T, cur, nxt, pad):
    """Value (n, K), gradient (n, m, K) and Hessian (n, m, m, K) of ``coef`` at the rows of ``X``.

    With the work arrays of :func:`work` (kept between calls: allocating
    them costs more than contracting one state). A flat contraction
    (``flat[0][order]``) fills only the results of ``order`` itself.
    """
    m = X.shape[1]
    for s in range(X.shape[0]):
        root = contract_root(X[s], tree, coef, flat, order, T, cur, nxt, pad)
        _store(root, s, order, m, value, grad, hess)


@njit(cache=True, nogil=True)
def work(tree, K, m):
    """The work arrays of :func:`evaluate`."""
    return _work(tree, K, m)


@njit(cache=True, nogil=True, inline="always")
def field_at(kind, tree, C, flat, gamma, x, T, cur, nxt, pad, f):
    """The field at one state into ``f``.

    Kind 0: ``(J^{-1} - Gamma) grad H``; kind 1: ``f_c = sum_j C[j, c] phi_j``.
    """
    m = x.shape[0]
    if kind == 0:
        root = contract_root(x, tree, C, flat, 1, T, cur, nxt, pad)
        d = m // 2
        for i in range(d):
            f[i] = -root[1 + d + i, 0] - gamma[i] * root[1 + i, 0]
            f[d + i] = root[1 + i, 0]
    else:
        root = contract_root(x, tree, C, flat, 0, T, cur, nxt, pad)
        for c in range(m):
            f[c] = root[0, c]


@njit(cache=True, nogil=True)
def fields(kind, X, tree, C, flat, gamma, out, T, cur, nxt, pad):
    """The field (:func:`field_at`) at the rows of ``X`` into ``out``.

    With the work arrays of :func:`work`.
    """
    for s in range(X.shape[0]):
        field_at(kind, tree, C, flat, gamma, X[s], T, cur, nxt, pad, out[s])
