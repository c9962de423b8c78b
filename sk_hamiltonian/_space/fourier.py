"""Real Fourier series on a period: the 1-D family for angles.

A sibling of :mod:`.legendre`: a variable ``x`` with period ``[low, high)`` is
mapped to the angle ``theta = 2 pi (x - low) / (high - low)``
(:func:`period_to_angle`), where :func:`fourier_tables` evaluates the real
trigonometric basis and its derivatives. Column ``0`` of a table is ``1``,
column ``2k - 1`` is ``cos(k theta)`` and column ``2k`` is ``sin(k theta)``;
the *frequency* ``k`` is what counts toward a total degree. In a multi-index a
signed frequency names a column: ``+k`` the cosine, ``-k`` the sine
(:func:`fourier_column`). Along a segment a trigonometric factor is not a
polynomial, and :func:`phase_nodes` says how many Gauss-Legendre nodes average
it to round-off.
"""

import math

import numpy as np

#: Gauss-Legendre nodes that trigonometric factors add to a segment's
#: quadrature at the least: enough for phases up to 0.145 (the short
#: segments of sampled data).
MIN_SEGMENT_NODES = 4
#: The most they add: enough for phases up to 144 radians.
MAX_SEGMENT_NODES = 64


def period_to_angle(x, low, high):
    """Map the period ``[low, high)`` onto angles ``[0, 2 pi)`` (without wrapping).

    Parameters
    ----------
    x : ndarray
        Points in the original coordinate; points outside the period are
        not wrapped, since the basis is periodic.
    low, high : float or ndarray
        Ends of the period (broadcast against ``x``).

    Returns
    -------
    theta : ndarray
        Angles.
    scale : float or ndarray
        ``d theta / d x = 2 pi / (high - low)``.
    """
    scale = 2.0 * np.pi / (high - low)
    return (x - low) * scale, scale


def wrap_to_period(x, low, high):
    """Wrap ``x`` into ``[low, high)``.

    Parameters
    ----------
    x : ndarray
        Points.
    low, high : float or ndarray
        Ends of the period.

    Returns
    -------
    wrapped : ndarray
        ``low + (x - low) mod (high - low)``.
    """
    return low + np.mod(x - low, high - low)


def fourier_column(frequency):
    """Table column of a signed frequency: ``0 -> 0``, ``+k -> 2k - 1``, ``-k -> 2k``."""
    frequency = np.asarray(frequency)
    return np.where(frequency > 0, 2 * frequency - 1, -2 * frequency)


def fourier_derivative_matrix(degree):
    """Matrix ``D`` with ``f'_n = sum_k D[k, n] f_k`` for the columns ``f`` of the basis.

    The sibling of :func:`~sk_hamiltonian._space.legendre.legendre_derivative_matrix`:
    with respect to ``theta``, ``cos(k theta)`` (column ``2k - 1``) has the
    derivative ``-k sin(k theta)`` (column ``2k``) and ``sin(k theta)`` the
    derivative ``k cos(k theta)``; the constant has none.

    Parameters
    ----------
    degree : int
        Highest frequency ``K``.

    Returns
    -------
    D : ndarray of shape (2 * degree + 1, 2 * degree + 1)
    """
    D = np.zeros((2 * degree + 1, 2 * degree + 1))
    k = np.arange(1, degree + 1)
    D[2 * k, 2 * k - 1] = -k
    D[2 * k - 1, 2 * k] = k
    return D


def fourier_frequency(column):
    """Signed frequency of a table column, the inverse of :func:`fourier_column`."""
    column = np.asarray(column)
    return np.where(column % 2 == 1, (column + 1) // 2, -(column // 2))


def fourier_tables(theta, degree, n_derivatives=1):
    """The real trigonometric basis and its derivatives at every angle.

    ``cos(k theta)`` and ``sin(k theta)`` come from the angle-addition
    recurrence, which needs one cosine and one sine per point whatever the
    highest frequency.

    Parameters
    ----------
    theta : ndarray of shape (n_samples, n_features)
        Angles.
    degree : int
        Highest frequency ``K``.
    n_derivatives : {0, 1, 2}, default=1
        How many derivatives (with respect to ``theta``) to tabulate as well.

    Returns
    -------
    tables : list of ndarray of shape (n_samples, n_features, 2 * degree + 1)
        ``tables[r][..., j]`` is the ``r``-th derivative of basis function
        ``j``: ``1, cos theta, sin theta, cos 2 theta, sin 2 theta, ...``.
    """
    value = np.empty((2 * degree + 1,) + theta.shape)
    value[0] = 1.0
    if degree >= 1:
        c1, s1 = np.cos(theta), np.sin(theta)
        value[1], value[2] = c1, s1
        for k in range(1, degree):
            c, s = value[2 * k - 1], value[2 * k]
            value[2 * k + 1] = c * c1 - s * s1
            value[2 * k + 2] = s * c1 + c * s1
    tables = [value.transpose(1, 2, 0)]
    k = np.repeat(np.arange(degree + 1), 2)[1:]  # frequency of each column
    # d/dtheta maps cos(k.) to -k sin(k.) and sin(k.) to k cos(k.): swap each
    # (cos, sin) pair of columns and scale.
    swap = np.arange(2 * degree + 1)
    swap[1::2] += 1
    swap[2::2] -= 1
    sign = np.where(np.arange(2 * degree + 1) % 2 == 1, -1.0, 1.0) * k
    for _ in range(n_derivatives):
        tables.append(tables[-1][..., swap] * sign)
    return tables


def fourier_moments(degree):
    """Inner products of the basis and of its derivatives, mean over one period.

    Parameters
    ----------
    degree : int
        Highest frequency.

    Returns
    -------
    values : ndarray of shape (2 * degree + 1, 2 * degree + 1)
        Diagonal: ``1`` for the constant, ``1/2`` for every other column.
    slopes : ndarray of shape (2 * degree + 1, 2 * degree + 1)
        Diagonal: ``k**2 / 2`` for the columns of frequency ``k``.
    """
    k = np.repeat(np.arange(degree + 1), 2)[1:]
    values = np.diag(np.where(k == 0, 1.0, 0.5))
    slopes = np.diag(k**2 / 2.0)
    return values, slopes


def segment_phase_limits(max_nodes=MAX_SEGMENT_NODES):
    """Largest phase that each Gauss-Legendre rule averages to round-off.

    Along a segment ``x0 + xi (x1 - x0)``, ``xi`` in ``[0, 1]``, a factor of
    frequency ``k`` turns through the phase ``w = k |theta1 - theta0|``. The
    ``m``-node rule on ``[0, 1]`` averages ``exp(i w xi)`` with an error of at
    most ``w**(2m) (m!)**4 / ((2m + 1) ((2m)!)**3)`` (the classical remainder,
    within a factor 2 of the true error wherever that error is below 1e-2).

    Parameters
    ----------
    max_nodes : int, default=MAX_SEGMENT_NODES
        Largest rule.

    Returns
    -------
    limits : ndarray of shape (max_nodes + 1,)
        ``limits[m]`` is the largest phase whose error bound with ``m`` nodes
        is at most ``2**-53``; increasing, ``limits[0] = 0``.
    """
    m = np.arange(1, max_nodes + 1)
    log_limit = (
        -53 * math.log(2)
        + np.log(2 * m + 1)
        + np.array([3 * math.lgamma(2 * k + 1) - 4 * math.lgamma(k + 1) for k in m])
    ) / (2 * m)
    return np.concatenate([[0.0], np.exp(log_limit)])


#: ``segment_phase_limits()``, what :func:`phase_nodes` looks up.
PHASE_LIMITS = segment_phase_limits()


def phase_nodes(phase):
    """Gauss-Legendre nodes that average a segment's trigonometric factors.

    Parameters
    ----------
    phase : float
        Largest phase ``sum_j k_j |theta_j(x1) - theta_j(x0)|`` of a factor
        along the segment, in radians.

    Returns
    -------
    n_nodes : int
        The fewest nodes whose rule averages every such factor to round-off
        (:func:`segment_phase_limits`), at least :data:`MIN_SEGMENT_NODES`.
        Beyond 144 radians (or for a phase that is not finite) no rule here
        does, and the answer is :data:`MAX_SEGMENT_NODES`.
    """
    if not phase <= PHASE_LIMITS[-1]:
        return MAX_SEGMENT_NODES
    return max(MIN_SEGMENT_NODES, int(np.searchsorted(PHASE_LIMITS, phase)))
