"""The noise of observed trajectories: a variance model per variable, and weights from it.

Each variable's noise variance is modelled as ``a_i + b_i x_i^2``: additive
noise, relative (multiplicative) noise, or both. Two estimates of it serve
the trajectory fit:

- :func:`difference_noise_model`, from the data alone: the ``m``-th
  differences of a finely sampled smooth signal are tiny, while those of
  white noise keep the noise, with variance ``sum_k c_k^2 sigma_{j+k}^2``
  (``c_k`` the binomial coefficients of the difference). Regressing the
  squared differences on ``sum_k c_k^2`` and ``sum_k c_k^2 y_{j+k}^2`` gives
  ``(a_i, b_i)`` with no model at all; what the signal leaves in the
  differences makes it an upper estimate where the sampling is coarse.
- :func:`residual_noise_model`, from a fitted model's residuals: the same
  regression on the squared residuals themselves.

:func:`noise_weights` turns a variance model into the weights ``1 / sigma``
of each observation, never giving one sample more weight than
:data:`MAX_RELATIVE_WEIGHT` times the average's.
"""

import numpy as np
from scipy.optimize import nnls
from scipy.special import comb

# A variance model never gives a sample more weight than this many times the
# average sample's (a variable near zero under relative noise would otherwise
# weigh without bound, and with it the model's own error at that sample).
MAX_RELATIVE_WEIGHT = 10.0
# Order of the differences the data-only estimate uses (as for the noise
# level of DerivativeTransformer's misfit check).
DIFFERENCE_ORDER = 6
# Noise below this fraction of a variable's root-mean-square is round-off and
# integration error of "exact" data: weights are never larger than it allows.
NOISE_FLOOR = 1e-9


def _fit_variance(regressors, squared):
    """``(a, b) >= 0`` minimising ``||regressors @ (a, b) - squared||``."""
    scale = np.maximum(np.abs(regressors).max(axis=0), np.finfo(float).tiny)
    target = np.max(np.abs(squared))
    if not np.isfinite(target) or target == 0:
        return np.zeros(2)
    solution, _ = nnls(regressors / scale, squared / target)
    return solution / scale * target


def difference_noise_model(states, order=DIFFERENCE_ORDER):
    """The variance model ``a_i + b_i x_i^2`` of each variable, from the data alone.

    Parameters
    ----------
    states : list of ndarray of shape (n_times_k, n_states)
        Observed trajectories (states only); those with at most ``order``
        samples are skipped.
    order : int, default=6
        Order of the differences; lowered (down to 2) when no trajectory has
        more samples than it.

    Returns
    -------
    noise : ndarray of shape (n_states, 2) or None
        ``(a_i, b_i)`` per variable; None if no trajectory has 3 samples.
    """
    longest = max(len(Y) for Y in states)
    order = min(order, longest - 1)
    if order < 2:
        return None
    c = np.array([(-1) ** k * comb(order, k) for k in range(order + 1)])
    differences, regressors = [], []
    for Y in states:
        if Y.shape[0] <= order:
            continue
        n = Y.shape[0] - order
        windows = np.stack([Y[k : k + n] for k in range(order + 1)])  # (order + 1, n, d)
        differences.append(np.tensordot(c, windows, axes=1))
        regressors.append(np.tensordot(c**2, windows**2, axes=1))
    if not differences:
        return None
    D = np.concatenate(differences)
    R = np.concatenate(regressors)
    total = np.sum(c**2)
    noise = np.empty((D.shape[1], 2))
    for i in range(D.shape[1]):
        design = np.column_stack([np.full(len(D), total), R[:, i]])
        noise[i] = _fit_variance(design, D[:, i] ** 2)
    return noise


def residual_noise_model(states, residuals):
    """The variance model ``a_i + b_i x_i^2`` of each variable, from residuals.

    Parameters
    ----------
    states : ndarray of shape (n_samples, n_states)
        States at which the residuals were taken.
    residuals : ndarray of shape (n_samples, n_states)
        Observations less the model's states.

    Returns
    -------
    noise : ndarray of shape (n_states, 2)
    """
    noise = np.empty((states.shape[1], 2))
    for i in range(states.shape[1]):
        design = np.column_stack([np.ones(len(states)), states[:, i] ** 2])
        noise[i] = _fit_variance(design, residuals[:, i] ** 2)
    return noise


def mean_variance(noise, states):
    """Each variable's noise variance averaged over ``states``, shape (n_states,)."""
    return noise[:, 0] + noise[:, 1] * np.mean(states**2, axis=0)


def noise_weights(noise, states, scale, mask=None):
    """Weights ``1 / sigma`` of the observations at ``states`` under a variance model.

    Parameters
    ----------
    noise : ndarray of shape (n_states, 2)
        ``(a_i, b_i)`` per variable.
    states : ndarray of shape (..., n_states)
        Where the variances are taken.
    scale : ndarray of shape (n_states,)
        Each variable's root-mean-square over the data, for the floor
        :data:`NOISE_FLOOR`.
    mask : ndarray of bool of shape ``states.shape[:-1]``, default=None
        The states that count for the average variance (all when None).

    Returns
    -------
    weights : ndarray of the shape of ``states``
    """
    a, b = noise[:, 0], noise[:, 1]
    flat = states[mask] if mask is not None else states.reshape(-1, states.shape[-1])
    floor = np.maximum(mean_variance(noise, flat) / MAX_RELATIVE_WEIGHT**2,
                       (NOISE_FLOOR * scale) ** 2)
    floor = np.where(floor > 0, floor, 1.0)
    return 1.0 / np.sqrt(np.maximum(a + b * states**2, floor))
