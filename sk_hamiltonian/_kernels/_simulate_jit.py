"""Compiled fixed-step integrations (numba); imported only when numba is.

Each initial state is integrated on its own, the whole run in one compiled
call, with the model's field evaluated by the contraction of :mod:`._jit`:
the same steps as :mod:`sk_hamiltonian._integrate` (RK4, the averaged vector
field with its simplified Newton iteration, leapfrog and its compositions),
the same failure rule (a state non-finite at an output time freezes the
trajectory there) and the same wrapping of periodic variables at output
times. The integrators of :mod:`sk_hamiltonian._integrate` stay the
reference; :mod:`sk_hamiltonian._integrate.compiled` decides when this path applies.

Model kinds: 0, a Hamiltonian ``f = (J^{-1} - Gamma) grad H`` (``tree`` and
``C`` describe ``H``); 1, a vector field ``f_c = sum_j C[j, c] phi_j``.
Methods: 0 RK4, 1 AVF, 2 leapfrog compositions (``tree`` is ``V(q)`` and
``tree2`` is ``T(p)``).
"""

import math

import numpy as np
from numba import njit

from ._jit import _work, contract_root, field_at

# The field, Jacobian and gradient are inlined (inline="always") into the
# steps: a call of a compiled function that takes the tree and flat tuples
# (some 20 arrays) counts references of every array, which cost more than
# the contraction of a sparse model's dozen functions (measured: 16 x 2000
# RK4 steps of the sparse Henon-Heiles model, 0.106 s CPU before, 0.050 s
# after; benchmarks/bench_sparse.py).


@njit(cache=True, nogil=True, inline="always")
def _jacobian(kind, tree, C, flat, gamma, x, T, cur, nxt, pad, J):
    m = x.shape[0]
    if kind == 0:
        root = contract_root(x, tree, C, flat, 2, T, cur, nxt, pad)
        d = m // 2
        for i in range(d):
            for j in range(m):
                a, b = min(d + i, j), max(d + i, j)
                a2, b2 = min(i, j), max(i, j)
                H_pj = root[1 + m + a * m + b, 0]
                H_ij = root[1 + m + a2 * m + b2, 0]
                J[i, j] = -H_pj - gamma[i] * H_ij
                J[d + i, j] = H_ij
    else:
        root = contract_root(x, tree, C, flat, 1, T, cur, nxt, pad)
        for c in range(m):
            for i in range(m):
                J[c, i] = root[1 + i, c]


@njit(cache=True, nogil=True, inline="always")
def _gradient(tree, C, flat, x, T, cur, nxt, pad, g):
    root = contract_root(x, tree, C, flat, 1, T, cur, nxt, pad)
    for i in range(x.shape[0]):
        g[i] = root[1 + i, 0]


@njit(cache=True, nogil=True)
def _invert(A, out):
    """``out = A^{-1}`` by Gauss-Jordan elimination with partial pivoting (NaN if singular)."""
    n = A.shape[0]
    W = A.copy()
    for i in range(n):
        for j in range(n):
            out[i, j] = 1.0 if i == j else 0.0
    for col in range(n):
        pivot = col
        for r in range(col + 1, n):
            if abs(W[r, col]) > abs(W[pivot, col]):
                pivot = r
        if W[pivot, col] == 0.0 or W[pivot, col] != W[pivot, col]:
            out[:, :] = np.nan
            return
        if pivot != col:
            for j in range(n):
                W[col, j], W[pivot, j] = W[pivot, j], W[col, j]
                out[col, j], out[pivot, j] = out[pivot, j], out[col, j]
        scale = 1.0 / W[col, col]
        for j in range(n):
            W[col, j] *= scale
            out[col, j] *= scale
        for r in range(n):
            if r != col and W[r, col] != 0.0:
                factor = W[r, col]
                for j in range(n):
                    W[r, j] -= factor * W[col, j]
                    out[r, j] -= factor * out[col, j]


@njit(cache=True, nogil=True)
def _rk4(kind, tree, C, flat, gamma, y, h, T, cur, nxt, pad, k1, k2, k3, k4, tmp):
    m = y.shape[0]
    field_at(kind, tree, C, flat, gamma, y, T, cur, nxt, pad, k1)
    for i in range(m):
        tmp[i] = y[i] + (0.5 * h) * k1[i]
    field_at(kind, tree, C, flat, gamma, tmp, T, cur, nxt, pad, k2)
    for i in range(m):
        tmp[i] = y[i] + (0.5 * h) * k2[i]
    field_at(kind, tree, C, flat, gamma, tmp, T, cur, nxt, pad, k3)
    for i in range(m):
        tmp[i] = y[i] + h * k3[i]
    field_at(kind, tree, C, flat, gamma, tmp, T, cur, nxt, pad, k4)
    for i in range(m):
        y[i] = y[i] + (h / 6.0) * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i])


@njit(cache=True, nogil=True)
def _avf(kind, tree, C, flat, gamma, y, h, rules, rtol, max_iter, T, cur, nxt, pad, J, M, f, y1, avg, point):
    """One AVF step of ``y`` in place; NaN where Newton does not converge (see AveragedVectorField).

    ``rules`` is ``(nodes, weights, phase_limits, phase_rates)``: row ``e`` of
    ``nodes`` and ``weights`` is the rule with ``e`` nodes more than row 0
    (padded), which a segment turning trigonometric factors through a phase
    up to ``phase_limits[e]`` takes (see :func:`simulate.avf_rules`).
    """
    nodes, weights, phase_limits, phase_rates = rules
    n_first = nodes.shape[1] - nodes.shape[0] + 1
    m = y.shape[0]
    _jacobian(kind, tree, C, flat, gamma, y, T, cur, nxt, pad, J)
    for i in range(m):
        for j in range(m):
            J[i, j] = (1.0 if i == j else 0.0) - (0.5 * h) * J[i, j]
    _invert(J, M)
    field_at(kind, tree, C, flat, gamma, y, T, cur, nxt, pad, f)
    scale = 1.0
    for i in range(m):
        s = 0.0
        for j in range(m):
            s += M[i, j] * f[j]
        y1[i] = y[i] + h * s
        scale = max(scale, abs(y[i]))
    tolerance = rtol * scale
    previous = np.inf
    converged = False
    for _ in range(max_iter):
        phase = 0.0
        for i in range(m):
            avg[i] = 0.0
            phase += phase_rates[i] * abs(y1[i] - y[i])
        # As fourier.phase_nodes: the first rule that covers the phase, else the last.
        e = 0
        while e < phase_limits.shape[0] - 1 and not phase <= phase_limits[e]:
            e += 1
        for q in range(n_first + e):
            for i in range(m):
                point[i] = y[i] + nodes[e, q] * (y1[i] - y[i])
            field_at(kind, tree, C, flat, gamma, point, T, cur, nxt, pad, f)
            for i in range(m):
                avg[i] += weights[e, q] * f[i]
        for i in range(m):
            point[i] = y1[i] - y[i] - h * avg[i]  # the residual
        size = 0.0
        finite = True
        for i in range(m):
            delta = 0.0
            for j in range(m):
                delta += M[i, j] * point[j]
            y1[i] -= delta
            if not math.isfinite(delta):
                finite = False
            size = max(size, abs(delta))
        if not finite:
            break
        if size <= tolerance or (size >= 0.5 * previous and size <= 1e3 * tolerance):
            converged = True
            break
        previous = size
    for i in range(m):
        y[i] = y1[i] if converged else np.nan


@njit(cache=True, nogil=True)
def _leapfrog(tree, C, flat, tree2, C2, flat2, y, h, lf_weights, T, cur, nxt, pad, T2, cur2, nxt2, pad2, g):
    d = y.shape[0] // 2
    p = y[:d]
    q = y[d:]
    for w in lf_weights:
        _gradient(tree, C, flat, q, T, cur, nxt, pad, g)
        for i in range(d):
            p[i] -= (0.5 * w * h) * g[i]
        _gradient(tree2, C2, flat2, p, T2, cur2, nxt2, pad2, g)
        for i in range(d):
            q[i] += (w * h) * g[i]
        _gradient(tree, C, flat, q, T, cur, nxt, pad, g)
        for i in range(d):
            p[i] -= (0.5 * w * h) * g[i]


@njit(cache=True, nogil=True)
def _wrap(y, periodic, low, high):
    for i in range(y.shape[0]):
        if periodic[i]:
            y[i] = low[i] + (y[i] - low[i]) % (high[i] - low[i])


@njit(cache=True, nogil=True)
def _run(method, kind, tree, C, flat, tree2, C2, flat2, gamma, lf_weights, rules, rtol, max_iter,
         periodic, low, high, y0, n_sub, h, out, failed_at, first, stop):
    """Integrate the initial states ``first .. stop - 1`` (see :func:`integrate`)."""
    m = y0.shape[1]
    n_times = out.shape[0]
    K = C.shape[1]
    T, cur, nxt, pad = _work(tree, K, tree[0].shape[0])
    T2, cur2, nxt2, pad2 = _work(tree2, C2.shape[1], tree2[0].shape[0])
    J = np.empty((m, m))
    M = np.empty((m, m))
    k1 = np.empty(m)
    k2 = np.empty(m)
    k3 = np.empty(m)
    k4 = np.empty(m)
    tmp = np.empty(m)
    y = np.empty(m)
    last = np.empty(m)
    for s in range(first, stop):
        for i in range(m):
            last[i] = y0[s, i]
        _wrap(last, periodic, low, high)
        out[0, s] = last
        failed_at[s] = n_times
        for k in range(n_times - 1):
            y[:] = last
            for _ in range(n_sub[k]):
                if method == 0:
                    _rk4(kind, tree, C, flat, gamma, y, h[k], T, cur, nxt, pad, k1, k2, k3, k4, tmp)
                elif method == 1:
                    _avf(kind, tree, C, flat, gamma, y, h[k], rules, rtol, max_iter,
                         T, cur, nxt, pad, J, M, k1, k2, k3, k4)
                else:
                    _leapfrog(tree, C, flat, tree2, C2, flat2, y, h[k], lf_weights, T, cur, nxt, pad,
                              T2, cur2, nxt2, pad2, k1)
            finite = True
            for i in range(m):
                if not math.isfinite(y[i]):
                    finite = False
            if not finite:
                failed_at[s] = k + 1
                for later in range(k + 1, n_times):
                    out[later, s] = last
                break
            _wrap(y, periodic, low, high)
            last[:] = y
            out[k + 1, s] = last


@njit(cache=True, nogil=True)
def integrate(method, kind, tree, C, flat, tree2, C2, flat2, gamma, lf_weights, rules, rtol,
              max_iter, periodic, low, high, y0, n_sub, h, out, failed_at):
    """Integrate every initial state of ``y0`` into ``out`` (n_times, n, m).

    Releases the GIL: callers run chunks of initial states in threads.
    """
    _run(method, kind, tree, C, flat, tree2, C2, flat2, gamma, lf_weights, rules, rtol, max_iter,
         periodic, low, high, y0, n_sub, h, out, failed_at, 0, y0.shape[0])
