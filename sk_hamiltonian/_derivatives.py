"""Time derivatives (and de-noised states) estimated from sampled trajectories."""

from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator, TransformerMixin, _fit_context
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from ._trajectories import check_n_states, check_trajectories, pack_derivatives


def finite_difference(X, dt):
    """Second-order finite differences along the time axis.

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


class DerivativeTransformer(TransformerMixin, BaseEstimator):
    """Estimate time derivatives of trajectories, optionally de-noising them.

    Two estimators from Section 2.2 of Wu, Qin & Xiu: second-order finite
    differences for clean data, and for noisy data a least-squares polynomial in
    time fitted to each trajectory and differentiated analytically, whose fitted
    values also replace the noisy states (the paper's de-noising filter).

    The output keeps one sample per trajectory and carries the raw observations
    and their time stamps alongside, so that
    :meth:`HamiltonianRegressor.score` can compare against what was observed
    rather than against this step's own estimates.

    Parameters
    ----------
    dt : float, default=None
        Uniform sampling step of the trajectories. Required; ``None`` raises at
        ``fit``.
    method : {"polynomial", "finite_difference"}, default="polynomial"
        ``"polynomial"``: least-squares polynomial of degree ``degree`` per
        trajectory. ``"finite_difference"``: second-order differences, central
        inside and one-sided at the ends; needs at least 3 samples per trajectory
        and ignores ``degree`` and ``smooth_states``.
    degree : int, default=5
        Degree ``Q`` of the time polynomial. It must be smaller than the number
        of samples per trajectory (equal to ``n_times - 1`` interpolates).
    smooth_states : bool, default=True
        With ``method="polynomial"``, replace the states by the fitted values.

    Attributes
    ----------
    n_features_in_ : int
        Number of state variables ``2d`` seen during :meth:`fit`.

    See Also
    --------
    HamiltonianRegressor : Fits a Hamiltonian to the output of this transformer.
    unpack_derivatives : Splits the output into times, states, derivatives and
        observations.

    Notes
    -----
    The output is the *derivative layout*: the input container (3-D array or
    list) with a last axis ``[t, states, derivatives, observed]`` of width
    ``1 + 3 * n_states``, with ``t = 0, dt, 2 dt, ...``. Fitting is stateless:
    every trajectory is processed on its own.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import DerivativeTransformer
    >>> t = np.arange(50) * 0.1
    >>> X = np.stack([np.column_stack([-np.sin(t + s), np.cos(t + s)]) for s in (0, 1)])
    >>> Xt = DerivativeTransformer(dt=0.1, degree=8).fit_transform(X)
    >>> Xt.shape
    (2, 50, 7)
    """

    _parameter_constraints = {
        "dt": [Interval(Real, 0, None, closed="neither"), None],
        "method": [StrOptions({"polynomial", "finite_difference"})],
        "degree": [Interval(Integral, 1, None, closed="left")],
        "smooth_states": ["boolean"],
    }

    def __init__(self, dt=None, *, method="polynomial", degree=5, smooth_states=True):
        self.dt = dt
        self.method = method
        self.degree = degree
        self.smooth_states = smooth_states

    @_fit_context(prefer_skip_nested_validation=True)
    def fit(self, X, y=None):
        """Check the parameters against the trajectories.

        Parameters
        ----------
        X : array-like of shape (n_trajectories, n_times, n_states) or list of 2-D arrays
            Trajectories sampled every ``dt``.
        y : None
            Ignored.

        Returns
        -------
        self : DerivativeTransformer
            The transformer.
        """
        self._check(X)
        return self

    def transform(self, X):
        """Estimate derivatives (and smoothed states) of each trajectory.

        Parameters
        ----------
        X : array-like of shape (n_trajectories, n_times, n_states) or list of 2-D arrays
            Trajectories sampled every ``dt``.

        Returns
        -------
        Xt : ndarray of shape (n_trajectories, n_times, 1 + 3 * n_states) or list
            The derivative layout ``[t, states, derivatives, observed]``; a list
            of 2-D arrays if ``X`` was a list.
        """
        check_is_fitted(self)
        trajectories, is_array = self._check(X, reset=False)
        by_length = {}
        for k, T in enumerate(trajectories):
            by_length.setdefault(T.shape[0], []).append(k)
        states = [None] * len(trajectories)
        derivatives = [None] * len(trajectories)
        # Trajectories of one length share the same linear operators: one
        # batched product per length instead of one fit per trajectory.
        for n_times, members in by_length.items():
            batch = np.stack([trajectories[k] for k in members])
            smoothed, dXdt = self._estimate(batch, n_times)
            for i, k in enumerate(members):
                states[k], derivatives[k] = smoothed[i], dXdt[i]
        times = [self.dt * np.arange(T.shape[0]) for T in trajectories]
        return pack_derivatives(times, states, derivatives, trajectories, is_array)

    def _estimate(self, batch, n_times):
        if self.method == "finite_difference":
            return batch, finite_difference(batch, self.dt)
        smooth, differentiate = polynomial_operators(n_times, self.dt, self.degree)
        dXdt = np.einsum("ij,bjk->bik", differentiate, batch)
        smoothed = np.einsum("ij,bjk->bik", smooth, batch) if self.smooth_states else batch
        return smoothed, dXdt

    def _check(self, X, reset=True):
        if self.dt is None:
            raise ValueError(
                "DerivativeTransformer needs the sampling step: pass dt, e.g. "
                "DerivativeTransformer(dt=0.01)."
            )
        if self.method == "finite_difference":
            min_times, why = 3, "second-order finite differences need at least 3 samples"
        else:
            min_times = self.degree + 1
            why = (
                f"a polynomial of degree={self.degree} needs at least {min_times} "
                f"samples; lower `degree` or use method='finite_difference'"
            )
        try:
            trajectories, is_array = check_trajectories(X, min_times=min_times)
        except ValueError as error:
            if "sample(s)" in str(error):
                raise ValueError(f"{error} Here {why}.") from None
            raise
        n_states = trajectories[0].shape[1]
        check_n_states(n_states)
        if reset:
            self.n_features_in_ = n_states
        elif n_states != self.n_features_in_:
            raise ValueError(
                f"X has {n_states} state variables, but DerivativeTransformer was "
                f"fitted with {self.n_features_in_}."
            )
        return trajectories, is_array

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False
        tags.input_tags.three_d_array = True
        tags.requires_fit = True
        return tags
