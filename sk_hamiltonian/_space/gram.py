"""Closed-form Gram matrices and the stability constant of the paper's Corollary 3.4.

Under the uniform measure on the box the 1-D families are orthogonal (Legendre
on an interval, Fourier on a period), so the Gram matrix of the *gradients* of
a tensor basis,

    G[j, k] = sum_i E[ d_i phi_j  d_i phi_k ],

couples two basis functions only when their multi-indices differ in a single
variable ``i`` at most: it is sparse and known exactly. :func:`gradient_gram`
builds it, and :func:`stability_constant` uses it for the quantity

    K_N = sup_x sum_i  grad_i phi(x)^T G^{-1} grad_i phi(x)

of the paper's Lemma 3.3 (the diagonal of the reproducing kernel of the
gradient space), which :func:`corollary_samples` turns into the number of
samples Corollary 3.4 asks for.
"""

import math

import numpy as np
from scipy import linalg, sparse

from .fourier import fourier_moments
from .legendre import legendre_moments


def _moments(space):
    """Per variable: diagonal value moments, slope moments, and squared chain factors.

    A mixed variable's two families are not orthogonal to each other on its
    interval: its moments are those of each family on its own (block
    diagonal, the chain factors folded in), which makes the Gram matrix an
    approximation there (good enough for a preconditioner).
    """
    values, slopes, chain2 = [], [], []
    for i in range(space.n_states):
        low, high = space.domain[i]
        if space.mixed[i]:
            v_leg, s_leg = legendre_moments(space.legendre_degree)
            v_four, s_four = fourier_moments(space.fourier_degree)
            rate2 = space.factor_tables.mixed_rate ** 2
            v = linalg.block_diag(v_leg, v_four[1:, 1:])
            s = linalg.block_diag(s_leg * (2 / (high - low)) ** 2, s_four[1:, 1:] * rate2)
            chain2.append(1.0)
        elif space.periodic[i]:
            v, s = fourier_moments(space.fourier_degree)
            chain2.append((2 * np.pi / (high - low)) ** 2)
        else:
            v, s = legendre_moments(space.legendre_degree)
            chain2.append((2 / (high - low)) ** 2)
        values.append(np.diag(v))
        slopes.append(s)
    return values, slopes, np.array(chain2)


def _same_group_pairs(keys):
    """All ordered pairs ``(j, k)`` of rows of ``keys`` that are equal."""
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.ravel()
    order = np.argsort(group, kind="stable")
    sorted_group = group[order]
    starts = np.flatnonzero(np.r_[True, sorted_group[1:] != sorted_group[:-1]])
    sizes = np.diff(np.r_[starts, sorted_group.size])
    size_of, start_of = np.repeat(sizes, sizes), np.repeat(starts, sizes)
    J = np.repeat(np.arange(sorted_group.size), size_of)
    offsets = np.arange(J.size) - np.repeat(np.cumsum(size_of) - size_of, size_of)
    return order[J], order[start_of[J] + offsets]


def gradient_gram(space):
    """Gram matrix of the basis gradients under the uniform measure on the box.

    Parameters
    ----------
    space : ModelSpace
        The basis.

    Returns
    -------
    gram : scipy.sparse.csr_array of shape (n_terms, n_terms)
        ``E[grad phi_j . grad phi_k]``, the mean over the box.
    """
    columns = space.columns
    values, slopes, chain2 = _moments(space)
    diagonal = np.stack([values[i][columns[:, i]] for i in range(space.n_states)], axis=1)
    all_values = diagonal.prod(axis=1)
    rows, cols, data = [], [], []
    for i in range(space.n_states):
        keys = columns.copy()
        keys[:, i] = -1
        j, k = _same_group_pairs(keys)
        entry = chain2[i] * slopes[i][columns[j, i], columns[k, i]]
        entry *= all_values[j] / diagonal[j, i]
        keep = entry != 0
        rows.append(j[keep])
        cols.append(k[keep])
        data.append(entry[keep])
    n = space.n_terms
    gram = sparse.coo_array(
        (np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )
    return gram.tocsr()


def stability_constant(space, X=None, random_state=0):
    """The constant ``K_N`` of the paper's Lemma 3.3 for this space and the uniform measure.

    Parameters
    ----------
    space : ModelSpace
        The basis.
    X : ndarray of shape (n_points, n_states), default=None
        Where to take the supremum. None: the corners of the box (of its
        non-periodic variables; the kernel does not depend on a periodic
        one) when there are at most 4 096, and 2 000 uniform points.
    random_state : int, default=0
        Seed of the uniform points.

    Returns
    -------
    K_N : float
        ``max_x sum_i grad_i phi(x)^T G^{-1} grad_i phi(x)`` over ``X``.
    """
    low, high = space.domain[:, 0], space.domain[:, 1]
    if X is None:
        rng = np.random.default_rng(random_state)
        parts = [rng.uniform(low, high, size=(2000, space.n_states))]
        free = np.flatnonzero(~space.periodic)
        if free.size <= 12:
            corners = np.tile((low + high) / 2, (2**free.size, 1))
            bits = (np.arange(2**free.size)[:, None] >> np.arange(free.size)) & 1
            corners[:, free] = np.where(bits == 1, high[free], low[free])
            parts.append(corners)
        X = np.concatenate(parts)
    factor = linalg.cholesky(gradient_gram(space).toarray(), lower=True)
    largest = 0.0
    for start in range(0, X.shape[0], 256):
        G = space.gradients(X[start : start + 256])  # (n, m, N)
        Z = linalg.solve_triangular(factor, G.reshape(-1, space.n_terms).T, lower=True)
        per_point = (Z**2).sum(axis=0).reshape(G.shape[0], space.n_states).sum(axis=1)
        largest = max(largest, float(per_point.max()))
    return largest


def corollary_samples(k_n, r=1.0):
    """Fewest samples ``K`` with ``K_N <= lambda K / log K`` (the paper's Corollary 3.4).

    Parameters
    ----------
    k_n : float
        The stability constant, from :func:`stability_constant`.
    r : float, default=1.0
        The failure probability is at most ``2 K**-r``.

    Returns
    -------
    K : int
        Number of sampled states.
    """
    lam = (3 * math.log(1.5) - 1) / (2 + 2 * r)
    target = k_n / lam
    K = 3.0
    while K / math.log(K) < target:
        K *= 1.01
    # Refine to the integer.
    K = int(K / 1.01)
    while K / math.log(K) < target:
        K += 1
    return K
