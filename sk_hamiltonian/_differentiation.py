"""Time derivatives of sampled signals: finite differences and local polynomials.

The numerical kernels behind :class:`~sk_hamiltonian.DerivativeTransformer`.
Signals are arrays ``(..., n_times, n_features)``; time stamps either a
uniform step ``dt`` or arrays ``(..., n_times)``.

- Finite differences: the second-order three-point formulas, on any grid.
- Local polynomials: the least-squares polynomial of degree ``Q`` in time over
  a window of samples, evaluated (and differentiated) at the sample. A signal
  no longer than the window gets one polynomial (the paper's per-trajectory
  fit); a longer one gets, for each sample, the fit over the window centred on
  it, clipped at the ends. On a uniform grid that is a Savitzky-Golay filter.
- The noise level of a signal, from its high-order differences, against which
  the residuals of the local fits are judged.
"""

from math import comb

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

# A grid whose steps differ by less than this fraction of their mean counts as
# uniform (time stamps computed as k * dt differ by round-off only).
UNIFORM_TOLERANCE = 1e-9
# Order of the differences the noise level is estimated from: high enough
# that a smooth signal sampled several times per oscillation contributes
# little ((omega dt)**6), low enough that few samples suffice.
NOISE_DIFFERENCE_ORDER = 6
# Median absolute deviation to standard deviation, for Gaussian data.
MAD_TO_STD = 1.4826


def finite_difference(X, dt):
    """Second-order finite differences along the time axis, uniform step.

    Central differences inside, second-order one-sided differences at both ends.

    Parameters
    ----------
    X : ndarray of shape (..., n_times, n_features)
        Samples at the uniform step ``dt``; ``n_times >= 3``.
    dt : float
        Time step.

    Returns
    -------
    dXdt : ndarray of the same shape as ``X``
    """
    D = np.empty_like(X)
    D[..., 1:-1, :] = (X[..., 2:, :] - X[..., :-2, :]) / (2.0 * dt)
    D[..., 0, :] = (-3.0 * X[..., 0, :] + 4.0 * X[..., 1, :] - X[..., 2, :]) / (2.0 * dt)
    D[..., -1, :] = (3.0 * X[..., -1, :] - 4.0 * X[..., -2, :] + X[..., -3, :]) / (2.0 * dt)
    return D


def finite_difference_at(X, t):
    """Second-order finite differences on any grid of time stamps.

    The derivative at each sample of the quadratic through it and its two
    neighbours (inside), or through the first or last three samples (at the
    ends). Written with divided differences, so that on a uniform grid it is
    :func:`finite_difference` up to round-off.

    Parameters
    ----------
    X : ndarray of shape (..., n_times, n_features)
        Samples; ``n_times >= 3``.
    t : ndarray of shape (..., n_times)
        Strictly increasing time stamps.

    Returns
    -------
    dXdt : ndarray of the same shape as ``X``
    """
    h = np.diff(t, axis=-1)[..., None]
    slope = np.diff(X, axis=-2) / h  # slope[i]: between samples i and i + 1
    h1, h2 = h[..., :-1, :], h[..., 1:, :]
    s1, s2 = slope[..., :-1, :], slope[..., 1:, :]
    D = np.empty_like(X)
    # Interior: (h2 s1 + h1 s2) / (h1 + h2); uniform: the central difference.
    D[..., 1:-1, :] = (h2 * s1 + h1 * s2) / (h1 + h2)
    curvature_start = (s2[..., 0, :] - s1[..., 0, :]) / (h1[..., 0, :] + h2[..., 0, :])
    D[..., 0, :] = s1[..., 0, :] - h1[..., 0, :] * curvature_start
    curvature_end = (s2[..., -1, :] - s1[..., -1, :]) / (h1[..., -1, :] + h2[..., -1, :])
    D[..., -1, :] = s2[..., -1, :] + h2[..., -1, :] * curvature_end
    return D


def polynomial_operators(n_times, dt, degree):
    """Linear maps from samples to the least-squares polynomial and its derivative.

    The polynomial of degree ``degree`` in time is fitted by least squares to
    ``n_times`` equally spaced samples. It is expanded in Legendre polynomials of
    the time interval mapped to ``[-1, 1]``, which keeps the fit well conditioned
    for high degrees.

    Parameters
    ----------
    n_times : int
        Samples per trajectory; must exceed ``degree``.
    dt : float
        Time step.
    degree : int
        Polynomial degree ``Q``.

    Returns
    -------
    smooth : ndarray of shape (n_times, n_times)
        ``smooth @ x`` gives the fitted values at the sample times.
    differentiate : ndarray of shape (n_times, n_times)
        ``differentiate @ x`` gives the derivative of the fit at the sample times.
    """
    tau = np.linspace(-1.0, 1.0, n_times)
    V = np.polynomial.legendre.legvander(tau, degree)
    dV = np.zeros_like(V)
    for k in range(1, degree + 1):
        unit = np.zeros(k + 1)
        unit[k] = 1.0
        dV[:, k] = np.polynomial.legendre.legval(tau, np.polynomial.legendre.legder(unit))
    pinv = np.linalg.pinv(V)
    # d tau / d t = 2 / (total time span).
    return V @ pinv, (2.0 / ((n_times - 1) * dt)) * (dV @ pinv)


def fit_operators(t, degree):
    """Least-squares polynomial operators on arbitrary time stamps.

    Parameters
    ----------
    t : ndarray of shape (..., n_times)
        Strictly increasing time stamps of each signal; ``n_times > degree``.
    degree : int
        Polynomial degree ``Q``.

    Returns
    -------
    smooth, differentiate : ndarray of shape (..., n_times, n_times)
        As :func:`polynomial_operators`, one pair per signal.
    """
    span = t[..., -1:] - t[..., :1]
    # Legendre polynomials of the interval mapped onto [-1, 1]: conditioning
    # independent of where the times start and of their unit.
    tau = 2.0 * (t - t[..., :1]) / span - 1.0
    V, dV = _legendre_and_derivative(tau, degree)
    pinv = np.linalg.pinv(V)
    return V @ pinv, (2.0 / span[..., None]) * (dV @ pinv)


def _legendre_and_derivative(tau, degree):
    V = np.polynomial.legendre.legvander(tau, degree)
    dV = np.zeros_like(V)
    if degree >= 1:
        dV[..., 1] = 1.0
    # P'_{k+1} = P'_{k-1} + (2k + 1) P_k.
    for k in range(1, degree):
        dV[..., k + 1] = dV[..., k - 1] + (2 * k + 1) * V[..., k]
    return V, dV


def is_uniform(t):
    """Whether the steps of ``t`` (shape ``(n_times,)``) are equal up to round-off."""
    steps = np.diff(t)
    return bool(np.ptp(steps) <= UNIFORM_TOLERANCE * np.mean(steps))


def windowed_uniform(X, steps, degree, window):
    """Local polynomials over sliding windows on uniform grids (Savitzky-Golay).

    Parameters
    ----------
    X : ndarray of shape (n_signals, n_times, n_features)
        Signals of one length, ``n_times > window``.
    steps : ndarray of shape (n_signals,)
        The uniform step of each signal.
    degree : int
        Polynomial degree ``Q < window``.
    window : int
        Samples per local fit.

    Returns
    -------
    smoothed, dXdt : ndarray of the same shape as ``X``
        Values and derivatives of the local fits at the samples.
    """
    n_times, centre = X.shape[1], window // 2
    smooth, differentiate = polynomial_operators(window, 1.0, degree)
    smoothed, dXdt = np.empty_like(X), np.empty_like(X)
    # Interior samples sit at position `centre` of their window: one row of
    # the window's operators, applied to every window at once.
    windows = sliding_window_view(X, window, axis=1)  # (n_signals, n_windows, n_features, window)
    inner = slice(centre, n_times - window + centre + 1)
    smoothed[:, inner] = windows @ smooth[centre]
    dXdt[:, inner] = windows @ differentiate[centre]
    # The first and last samples keep the first and last windows.
    head, tail = slice(0, centre), slice(n_times - window + centre + 1, n_times)
    for rows, samples, positions in (
        (head, X[:, :window], slice(0, centre)),
        (tail, X[:, n_times - window :], slice(centre + 1, window)),
    ):
        smoothed[:, rows] = np.einsum("ij,bjf->bif", smooth[positions], samples)
        dXdt[:, rows] = np.einsum("ij,bjf->bif", differentiate[positions], samples)
    dXdt /= np.asarray(steps, dtype=float)[:, None, None]
    return smoothed, dXdt


def windowed_irregular(X, t, degree, window):
    """Local polynomials over sliding windows of samples, on any grid.

    Parameters
    ----------
    X : ndarray of shape (n_times, n_features)
        One signal, ``n_times > window``.
    t : ndarray of shape (n_times,)
        Its strictly increasing time stamps.
    degree : int
        Polynomial degree ``Q < window``.
    window : int
        Samples per local fit.

    Returns
    -------
    smoothed, dXdt : ndarray of the same shape as ``X``
    """
    n_times = t.shape[0]
    sample = np.arange(n_times)
    start = np.clip(sample - window // 2, 0, n_times - window)
    members = start[:, None] + np.arange(window)  # (n_times, window)
    smooth, differentiate = fit_operators(t[members], degree)
    position = sample - start
    # Only the row of each window's operators at its own sample is needed.
    smoothed = np.einsum("nw,nwf->nf", smooth[sample, position], X[members])
    dXdt = np.einsum("nw,nwf->nf", differentiate[sample, position], X[members])
    return smoothed, dXdt


def noise_level(signals, order=NOISE_DIFFERENCE_ORDER):
    """Robust estimate of the standard deviation of i.i.d. noise on smooth signals.

    The ``order``-th differences of white noise of standard deviation
    ``sigma`` have standard deviation ``sigma * sqrt(C(2 order, order))``,
    while those of a smooth signal sampled finely are tiny; the median
    absolute deviation of the differences, pooled over the signals, ignores
    the few large ones (jumps, gaps).

    Parameters
    ----------
    signals : list of ndarray of shape (n_times_k, n_features)
        Signals; those with at most ``order`` samples are skipped.
    order : int, default=6
        Order of the differences.

    Returns
    -------
    sigma : ndarray of shape (n_features,) or None
        Estimated noise level per feature; None if no signal is long enough.
    """
    differences = [np.diff(S, n=order, axis=0) for S in signals if S.shape[0] > order]
    if not differences:
        return None
    pooled = np.concatenate(differences)
    centred = pooled - np.median(pooled, axis=0)
    return MAD_TO_STD * np.median(np.abs(centred), axis=0) / np.sqrt(comb(2 * order, order))
