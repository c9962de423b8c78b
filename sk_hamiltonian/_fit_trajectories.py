"""``HamiltonianRegressor(fit_on="trajectories")``: the least-squares start, then the raw trajectories.

The regressor fits the paper's least squares on the layout's states and
derivatives, then fits the kept terms' coefficients (and the friction) to the
raw observations the layout carries, with time stamps and uneven lengths, by
the trajectory fit of :func:`sk_hamiltonian._trajectory_fit.refine`: the same
implementation as :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV`'s
last stage, checked on every other training trajectory held out, then the
rest, against the least-squares fit of the other half. Its outcome is set as
fitted attributes: ``trajectory_fit_status_``, and when it was accepted the
noise model ``noise_``, each trajectory's misfit in its units
``trajectory_misfit_`` and the covariance ``coef_covariance_`` of
``coef_`` (then ``damping_``), from which the intervals of the printed
coefficients come (:func:`~sk_hamiltonian.inspection.term_intervals`).
Samples the trajectory fit leaves out are named in an
:class:`~sk_hamiltonian.OutlierWarning`.
"""

import warnings

import numpy as np
from sklearn.base import clone

from ._trajectories import is_trajectory_container, unpack_derivatives
from ._trajectory_fit import refine
from ._trajectory_fit.outliers import warn_left_out

# Trajectories the held-out check needs: each half holds out at least two.
MIN_CHECKED = 4


def check_input(estimator, X, y, sample_weight):
    """Refuse what a fit on trajectories cannot take, naming the fix."""
    name = type(estimator).__name__
    if not is_trajectory_container(X) or y is not None:
        raise ValueError(
            f"{name}(fit_on='trajectories') fits the raw trajectories the derivative layout "
            f"carries: pass the output of DerivativeTransformer (a 3-D array or a list of "
            f"trajectories) with y=None, e.g. in make_pipeline(DerivativeTransformer(dt), "
            f"{name}(fit_on='trajectories')); for states with derivatives, use "
            f"fit_on='derivatives'."
        )
    if sample_weight is not None:
        raise ValueError(
            f"{name}(fit_on='trajectories') does not take sample_weight: the trajectory fit "
            f"weighs each observation by its noise. Drop the weights, or use "
            f"fit_on='derivatives'."
        )


def fit_on_trajectories(estimator, X):
    """The trajectory fit of a fitted least-squares ``estimator`` on layout ``X``, set in place.

    ``X`` is in the user's column order: the refits of the held-out check
    (clones, with the same ``state_order``) take it so, while the trajectory
    fit itself reads the observations in the model's ``(p, q)`` order.
    """
    layout = unpack_derivatives(estimator._layout_to_model(X))
    trajectories = [np.column_stack([t, O]) for t, O in zip(layout.times, layout.observed)]
    n = len(trajectories)
    held_out = ([np.arange(start, n, 2) for start in (0, 1)] if n >= MIN_CHECKED else None)

    def least_squares(indices):
        part = X[indices] if isinstance(X, np.ndarray) else [X[k] for k in indices]
        with warnings.catch_warnings():
            # The halves' own checks are the check's business, not the user's.
            warnings.simplefilter("ignore")
            return clone(estimator).set_params(fit_on="derivatives", n_resamples=0).fit(part)

    info = refine(estimator, trajectories, None, least_squares=least_squares,
                  held_out=held_out)
    if info.get("outliers"):
        warn_left_out(type(estimator).__name__, info["outliers"])
    return info
