"""Trajectories far outside the rest: named after a fit, with what to do about them.

A few corrupt trajectories (reversed in time, spiky, from another system)
among many good ones pull the least-squares fit everywhere and say so
nowhere. After a regressor's fit on trajectories, each trajectory's
residual ``dx/dt - f~(x)`` (its estimated derivatives against the learned
field, every variable in units of the spread of its derivative) is
compared with its own motion (the same root mean square of its
derivatives). A trajectory is named when:

- its relative residual exceeds :data:`RELATIVE_RESIDUAL`: the learned
  field disagrees with its derivatives by more than they move, which noise
  alone does not do (noise adds to both; the ratio tends to 1 where it
  dominates, and a trajectory reversed in time gives about 2);
- that ratio is far outside the rest: above their median by more than
  :data:`MADS` median absolute deviations (scaled to a standard deviation),
  so that a fit that is poor everywhere names none;
- its residual is above the median trajectory's in absolute terms, so that
  a trajectory that barely moves, whose relative residual is noise over
  almost nothing, is not named.

Measured on the paper's noisy pendulum (``make_trajectories(single_pendulum(),
200, 40, 0.01, noise=0.08)``, ``DerivativeTransformer(dt=0.01, degree=5)``,
``HamiltonianRegressor(degree=6)``): see ``docs/measurements.rst``.
"""

import numpy as np

from ._warnings import warn
from .exceptions import OutlierWarning

# A trajectory is named when its residual exceeds its own motion by this factor ...
RELATIVE_RESIDUAL = 1.5
# ... lies this many (scaled) median absolute deviations above the median ...
MADS = 6.0
# ... and (see the module docstring) above the median residual. With fewer
# trajectories than this, "the rest" is too few to judge against.
MIN_TRAJECTORIES = 10
# Indices a message lists before "and n more".
LISTED = 20
# From median absolute deviation to standard deviation, for normal data.
MAD_TO_STD = 1.4826
# How a message numbers the trajectories. An estimator only sees the X its
# fit was given: inside a cross-validation fold (GridSearchCV, cross_val_score)
# or a resample that is a subset of the user's X, and nothing tells it so; it
# cannot claim the user's numbering.
NUMBERING = (
    "numbered within the X this fit was given; in a cross-validation fold or a resample "
    "that is a subset of your data, so check them with a fit on the full data"
)


def robust_limit(values, n_mads):
    """``median + n_mads * 1.4826 * MAD`` of ``values``."""
    median = np.median(values)
    return median + n_mads * MAD_TO_STD * np.median(np.abs(values - median))


def listed(indices):
    """``[3, 17, 42]``, or the first :data:`LISTED` and how many more."""
    indices = [int(k) for k in indices]
    if len(indices) <= LISTED:
        return str(indices)
    return f"{str(indices[:LISTED])[:-1]}, ... and {len(indices) - LISTED} more]"


def residual_outliers(model, data):
    """Trajectories of ``data`` whose residuals under ``model`` are far outside the rest.

    Parameters
    ----------
    model : fitted BaseTrajectoryRegressor
        Its ``_vector_field`` is compared with the data's derivatives.
    data : TrainingData
        The training data, with trajectories.

    Returns
    -------
    outliers : ndarray of int
        Indices of the named trajectories (in the order of the input).
    relative : ndarray of shape (n_trajectories,)
        Every trajectory's relative residual.
    """
    none = np.zeros(0, dtype=np.intp)
    if data.trajectories is None or len(data.trajectories) < MIN_TRAJECTORIES:
        return none, None
    lengths = np.array([S.shape[0] for _, S in data.trajectories])
    group = np.repeat(np.arange(lengths.size), lengths)
    derivatives = data.derivatives
    scale = np.std(derivatives, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    with np.errstate(over="ignore", invalid="ignore"):
        residual = np.sum(((derivatives - model._vector_field(data.states)) / scale) ** 2, axis=1)
        motion = np.sum((derivatives / scale) ** 2, axis=1)
        size = np.sqrt(np.bincount(group, residual, lengths.size) / lengths)
        moving = np.sqrt(np.bincount(group, motion, lengths.size) / lengths)
        relative = np.where(moving > 0, size / np.where(moving > 0, moving, 1.0), 0.0)
    judged = np.isfinite(relative) & np.isfinite(size)
    if data.trajectory_weight is not None:
        judged &= data.trajectory_weight > 0
    if judged.sum() < MIN_TRAJECTORIES:
        return none, relative
    named = (
        judged
        & (relative > RELATIVE_RESIDUAL)
        & (relative > robust_limit(relative[judged], MADS))
        & (size > np.median(size[judged]))
    )
    return np.flatnonzero(named), relative


def warn_residual_outliers(model, data):
    """An :class:`~sk_hamiltonian.OutlierWarning` naming :func:`residual_outliers` (none for none)."""
    outliers, relative = residual_outliers(model, data)
    if not outliers.size:
        return
    name = type(model).__name__
    median = float(np.median(relative[np.isfinite(relative)]))
    worst = float(relative[outliers].max())
    n = len(data.trajectories)
    warn(
        OutlierWarning(
            f"{name}: {outliers.size} of {n} trajectories leave residuals far outside the "
            f"rest, trajectories {listed(outliers)} ({NUMBERING}): the learned field "
            f"disagrees with their estimated derivatives by up to {worst:.2g} times their "
            f"own size, against a median of {median:.2g}. Such trajectories may be corrupt "
            f"(reversed in time, spiky, mislabelled, or from another system), which pulls "
            f"the fit everywhere, or sound but where the model fits worst (the highest "
            f"energies, near a separatrix, at the edge of the data). Inspect them (their "
            f"indices are in this warning's `trajectories` attribute): refit without them "
            f"only if they are corrupt; if they are sound, a higher degree or more data near "
            f"them may fit them. If the DerivativeTransformer named trajectories it could "
            f"not de-noise, drop those first.",
            trajectories=outliers,
        ),
        OutlierWarning,
    )
