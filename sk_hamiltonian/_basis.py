"""Total-degree tensor Legendre basis on a box, with gradients and Hessians.

Plain functions at the core, in the spirit of ``numpy.polynomial.legendre``:
:func:`total_degree_powers` lists the multi-indices, :func:`map_to_window` maps
the domain box to ``[-1, 1]^m``, :func:`legendre_tables` evaluates the 1-D
polynomials and their derivatives, and the ``*_matrix`` functions assemble
values, gradients and Hessians of the tensor-product basis.
"""

from functools import lru_cache
from itertools import combinations_with_replacement
from math import comb

import numpy as np


def n_basis_functions(n_features, degree, include_constant=False):
    """Number of tensor Legendre polynomials of total degree at most ``degree``.

    Parameters
    ----------
    n_features : int
        Number of variables ``m``.
    degree : int
        Total degree ``n``.
    include_constant : bool, default=False
        Whether the constant polynomial is counted.

    Returns
    -------
    n : int
        ``C(n + m, m)``, minus one without the constant.
    """
    return comb(degree + n_features, n_features) - (0 if include_constant else 1)


def total_degree_powers(n_features, degree, include_constant=False):
    """Multi-indices of total degree at most ``degree``, graded order.

    Parameters
    ----------
    n_features : int
        Number of variables ``m``.
    degree : int
        Total degree ``n``.
    include_constant : bool, default=False
        Whether the zero multi-index comes first.

    Returns
    -------
    powers : ndarray of shape (n_terms, n_features)
        Row ``k`` holds the 1-D degrees of the ``k``-th basis function, ordered
        by total degree, then lexicographically from the first variable.
    """
    rows = []
    for total in range(0 if include_constant else 1, degree + 1):
        for combo in combinations_with_replacement(range(n_features), total):
            row = np.zeros(n_features, dtype=np.intp)
            np.add.at(row, list(combo), 1)
            rows.append(row)
    powers = np.array(rows, dtype=np.intp).reshape(-1, n_features)
    total = powers.sum(axis=1)
    order = np.lexsort(tuple(-powers[:, i] for i in reversed(range(n_features))) + (total,))
    return powers[order]


def map_to_window(X, domain):
    """Map points of the box ``domain`` affinely onto ``[-1, 1]^m``.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_features)
        Points in the original coordinates.
    domain : ndarray of shape (n_features, 2)
        One ``(low, high)`` row per variable.

    Returns
    -------
    xi : ndarray of shape (n_samples, n_features)
        Mapped points; the box itself maps to ``[-1, 1]^m``.
    """
    low, high = domain[:, 0], domain[:, 1]
    return (2.0 * X - (low + high)) / (high - low)


@lru_cache(maxsize=32)
def legendre_derivative_matrix(degree):
    """Matrix ``D`` with ``P'_n = sum_k D[k, n] P_k``, for ``n <= degree``.

    From ``P'_{k+1} = P'_{k-1} + (2k + 1) P_k``: ``D[k, n] = 2k + 1`` when
    ``k < n`` and ``n - k`` is odd. Cached (and read-only): simulation calls
    this at every step.
    """
    k = np.arange(degree + 1)[:, None]
    n = np.arange(degree + 1)[None, :]
    D = np.where((k < n) & ((n - k) % 2 == 1), 2.0 * k + 1.0, 0.0)
    D.flags.writeable = False
    return D


def legendre_tables(xi, degree, n_derivatives=1):
    """Legendre polynomials and their derivatives at every coordinate.

    Values come from the three-term recurrence
    ``(k + 1) P_{k+1} = (2k + 1) x P_k - k P_{k-1}``, derivatives from the
    values through :func:`legendre_derivative_matrix` (one product per order,
    which keeps the cost per call low for small batches).

    Parameters
    ----------
    xi : ndarray of shape (n_samples, n_features)
        Points in the window ``[-1, 1]^m``.
    degree : int
        Highest 1-D degree.
    n_derivatives : {0, 1, 2}, default=1
        How many derivatives to tabulate as well.

    Returns
    -------
    tables : list of ndarray of shape (n_samples, n_features, degree + 1)
        ``tables[r][..., k]`` is the ``r``-th derivative of ``P_k``.
    """
    # Degree first, so that every step of the recurrence works on contiguous rows.
    value = np.empty((degree + 1,) + xi.shape)
    value[0] = 1.0
    if degree >= 1:
        value[1] = xi
    for k in range(1, degree):
        value[k + 1] = ((2 * k + 1) / (k + 1)) * xi * value[k] - (k / (k + 1)) * value[k - 1]
    tables = [value.transpose(1, 2, 0)]
    if n_derivatives:
        D = legendre_derivative_matrix(degree)
        for _ in range(n_derivatives):
            tables.append(tables[-1] @ D)
    return tables


def _factors(X, domain, powers, n_derivatives):
    """Per-variable factors of each basis function, gathered in one indexing.

    Returns a list over derivative orders ``r`` of arrays of shape
    ``(n_samples, n_terms, n_features)`` holding ``P^{(r)}_{powers[j, i]}(xi_i)``.
    """
    xi = map_to_window(X, domain)
    tables = legendre_tables(xi, int(powers.max(initial=0)), n_derivatives)
    columns = np.arange(X.shape[1])
    return [table[:, columns, powers] for table in tables]


def _products_but_one(F):
    """``prod_{l != i} F[..., l]`` for every ``i``, without dividing by ``F``."""
    left = np.ones_like(F)
    right = np.ones_like(F)
    np.cumprod(F[..., :-1], axis=-1, out=left[..., 1:])
    right[..., :-1] = np.cumprod(F[..., :0:-1], axis=-1)[..., ::-1]
    return left * right


def value_matrix(X, domain, powers):
    """Values of the basis functions.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_features)
        Points.
    domain : ndarray of shape (n_features, 2)
        The box the basis is defined on.
    powers : ndarray of shape (n_terms, n_features)
        Multi-indices, as from :func:`total_degree_powers`.

    Returns
    -------
    V : ndarray of shape (n_samples, n_terms)
        ``V[k, j] = phi_j(X[k])``.
    """
    (values,) = _factors(X, domain, powers, 0)
    return values.prod(axis=-1)


def gradient_matrix(X, domain, powers):
    """Gradients of the basis functions.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_features)
        Points.
    domain : ndarray of shape (n_features, 2)
        The box the basis is defined on.
    powers : ndarray of shape (n_terms, n_features)
        Multi-indices.

    Returns
    -------
    G : ndarray of shape (n_samples, n_features, n_terms)
        ``G[k, i, j]`` is the derivative of ``phi_j`` along variable ``i`` at
        ``X[k]``, in the original (unmapped) coordinates.
    """
    return np.moveaxis(_gradient_factors(X, domain, powers), -1, 1)


def gradient_dot(X, domain, powers, coef):
    """Gradient of ``sum_j coef[j] phi_j`` at each point.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_features)
        Points.
    domain : ndarray of shape (n_features, 2)
        The box the basis is defined on.
    powers : ndarray of shape (n_terms, n_features)
        Multi-indices.
    coef : ndarray of shape (n_terms,)
        Expansion coefficients.

    Returns
    -------
    grad : ndarray of shape (n_samples, n_features)
        Gradients in the original coordinates.
    """
    return np.einsum("skm,k->sm", _gradient_factors(X, domain, powers), coef)


def _gradient_factors(X, domain, powers):
    """``d phi_j / d x_i`` laid out as ``(n_samples, n_terms, n_features)``."""
    values, slopes = _factors(X, domain, powers, 1)
    chain = 2.0 / (domain[:, 1] - domain[:, 0])
    return _products_but_one(values) * slopes * chain


def hessian_dot(X, domain, powers, coef):
    """Hessian of ``sum_j coef[j] phi_j`` at each point.

    Parameters
    ----------
    X : ndarray of shape (n_samples, n_features)
        Points.
    domain : ndarray of shape (n_features, 2)
        The box the basis is defined on.
    powers : ndarray of shape (n_terms, n_features)
        Multi-indices.
    coef : ndarray of shape (n_terms,)
        Expansion coefficients.

    Returns
    -------
    hess : ndarray of shape (n_samples, n_features, n_features)
        Symmetric Hessian matrices in the original coordinates.
    """
    m = X.shape[1]
    values, slopes, curvatures = _factors(X, domain, powers, 2)
    chain = 2.0 / (domain[:, 1] - domain[:, 0])
    hess = np.empty((X.shape[0], m, m))
    for i in range(m):
        for j in range(i, m):
            parts = values.copy()
            if i == j:
                parts[..., i] = curvatures[..., i]
            else:
                parts[..., i] = slopes[..., i]
                parts[..., j] = slopes[..., j]
            hess[:, i, j] = hess[:, j, i] = (parts.prod(axis=-1) @ coef) * (chain[i] * chain[j])
    return hess
