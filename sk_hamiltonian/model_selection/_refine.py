"""Stage 4 of the search: the chosen model's coefficients fitted to the raw trajectories.

The fit itself is :func:`sk_hamiltonian._trajectory_fit.refine`; the search
gives it the chosen pipeline's least-squares refit on part of the data, so
that the result is accepted only where the trajectories it was not fitted on
agree (:func:`refine_chosen`).
"""

import warnings

import numpy as np
from sklearn.base import clone

from .._trajectory_fit import refine
from .._trajectory_fit.outliers import warn_left_out
from ._fold_problems import take

# The held-out check holds out every other fold of the search from the second
# (two of five) and fits on the rest: one refit, most of the data to fit on.
# (Holding out each half in turn doubled the check's cost, a quarter of the
# search's on Henon-Heiles, for a verdict that only catches a fit gone wrong.)
CHECK_STRIDE = 2


def refine_on_trajectories(regressor, trajectories, dt, *, least_squares=None, held_out=None):
    """Refit the kept terms of a fitted ``HamiltonianRegressor`` to raw trajectories, in place.

    See :func:`sk_hamiltonian._trajectory_fit.refine`, which this calls.

    Parameters
    ----------
    regressor : HamiltonianRegressor
        Fitted.
    trajectories : list of ndarray of shape (n_times_k, n_columns)
        Raw trajectories, with their time stamps in the first column when
        ``dt`` is None.
    dt : float or None
        Sampling step.
    least_squares : callable, default=None
        ``least_squares(indices)``: the least-squares regressor fitted on the
        trajectories ``indices``, for the held-out check; None: none.
    held_out : list of ndarray of int, default=None
        The check's held-out sets.

    Returns
    -------
    info : dict
        As :func:`sk_hamiltonian._trajectory_fit.refine` returns it.
    """
    return refine(regressor, trajectories, dt, least_squares=least_squares, held_out=held_out)


def check_parts(folds):
    """The held-out set of the check: every other fold from the second (none with one fold)."""
    held_out = folds[1::CHECK_STRIDE]
    return [np.concatenate(held_out)] if held_out else []


def refine_chosen(pipeline, X, trajectories, dt, folds, origin=None):
    """Stage 4: refine the refitted ``pipeline``'s regressor, checked on the search's folds.

    Samples the trajectory fit leaves out (``info["outliers"]``) are numbered
    as in the user's data through ``origin`` and named in an
    :class:`~sk_hamiltonian.OutlierWarning`.

    Parameters
    ----------
    pipeline : Pipeline
        The chosen candidate, fitted on all of ``X`` by least squares.
    X : array-like
        The trajectories as the pipeline takes them.
    trajectories : list of ndarray
        The same, checked (:func:`~sk_hamiltonian._trajectories.check_trajectories`).
    dt : float or None
    folds : list of ndarray of int
        The search's held-out folds.
    origin : ndarray of int of shape (len(trajectories), 3), default=None
        Where each trajectory comes from: the user's trajectory, its first
        sample and its stop; None: the user's trajectories themselves.

    Returns
    -------
    info : dict
    """
    def least_squares(indices):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return clone(pipeline).fit(take(X, indices))[-1]

    info = refine_on_trajectories(pipeline[-1], trajectories, dt, least_squares=least_squares,
                                  held_out=check_parts(folds))
    if info.get("outliers"):
        info["outliers"] = _in_users_numbers(info["outliers"], origin)
        warn_left_out("HamiltonianSearchCV", info["outliers"], "refinement_['outliers']")
    return info


def _in_users_numbers(left_out, origin):
    """``left_out`` (piece to sample indices) as the user's trajectory to sample indices."""
    if origin is None:
        return left_out
    users = {}
    for piece, samples in left_out.items():
        k, start, _ = (int(v) for v in origin[piece])
        users.setdefault(k, []).extend(start + j for j in samples)
    return {k: sorted(v) for k, v in sorted(users.items())}

