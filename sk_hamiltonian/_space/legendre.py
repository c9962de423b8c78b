"""Legendre polynomials on an interval: the 1-D family for non-periodic variables.

Plain functions in the spirit of ``numpy.polynomial.legendre``: a variable
``x`` in its domain interval ``[low, high]`` is mapped onto the window
``[-1, 1]`` (:func:`interval_to_window`), where :func:`legendre_tables`
evaluates ``P_0 .. P_n`` and their derivatives. :func:`legendre_moments` gives
the closed-form inner products under the uniform measure that the Gram matrix
of the tensor basis is built from, and :func:`gauss_on_unit` the quadrature
rule that averages along a segment.
"""

from functools import lru_cache

import numpy as np


def interval_to_window(x, low, high):
    """Map ``[low, high]`` affinely onto ``[-1, 1]``.

    Parameters
    ----------
    x : ndarray
        Points in the original coordinate.
    low, high : float or ndarray
        Ends of the interval (broadcast against ``x``).

    Returns
    -------
    xi : ndarray
        Mapped points.
    scale : float or ndarray
        ``d xi / d x = 2 / (high - low)``, the chain-rule factor of derivatives.
    """
    scale = 2.0 / (high - low)
    return (2.0 * x - (low + high)) / (high - low), scale


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
    """Legendre polynomials and their derivatives at every point.

    Values come from the three-term recurrence
    ``(k + 1) P_{k+1} = (2k + 1) x P_k - k P_{k-1}``, derivatives from the
    values through :func:`legendre_derivative_matrix` (one product per order,
    which keeps the cost per call low for small batches).

    Parameters
    ----------
    xi : ndarray of shape (n_samples, n_features)
        Points in the window ``[-1, 1]``.
    degree : int
        Highest degree.
    n_derivatives : {0, 1, 2}, default=1
        How many derivatives (with respect to ``xi``) to tabulate as well.

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


def legendre_moments(degree):
    """Inner products of ``P_a`` and of ``P'_a`` under the uniform measure on ``[-1, 1]``.

    Parameters
    ----------
    degree : int
        Highest degree.

    Returns
    -------
    values : ndarray of shape (degree + 1, degree + 1)
        ``E[P_a P_b] = delta_ab / (2a + 1)`` (mean over the window).
    slopes : ndarray of shape (degree + 1, degree + 1)
        ``E[P'_a P'_b] = min(a, b) (min(a, b) + 1) / 2`` when ``a + b`` is even,
        else 0.
    """
    a = np.arange(degree + 1)
    values = np.diag(1.0 / (2 * a + 1))
    low = np.minimum.outer(a, a)
    slopes = np.where((np.add.outer(a, a) % 2) == 0, low * (low + 1) / 2.0, 0.0)
    return values, slopes


@lru_cache(maxsize=None)
def gauss_on_unit(n_nodes):
    """Gauss-Legendre nodes and weights on ``[0, 1]`` (cached, read-only).

    Parameters
    ----------
    n_nodes : int
        Number of nodes; the rule is exact for polynomials of degree up to
        ``2 n_nodes - 1`` (at least one node).

    Returns
    -------
    nodes, weights : ndarray of shape (max(1, n_nodes),)
        The weights sum to 1: the rule averages over the segment.
    """
    nodes, weights = np.polynomial.legendre.leggauss(max(1, n_nodes))
    nodes, weights = 0.5 * (nodes + 1.0), 0.5 * weights
    nodes.flags.writeable = weights.flags.writeable = False
    return nodes, weights
