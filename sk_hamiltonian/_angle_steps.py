"""Refuse periodic or mixed coordinates whose trajectories cannot resolve a period.

A periodic variable's basis is ``cos k theta``, ``sin k theta`` with
``theta = 2 pi (x - low) / (high - low)``, a mixed variable's ``cos k x``,
``sin k x`` in the variable's own units. Either way the data must say where
along the circle each sample lies: consecutive samples of a trajectory a
large fraction of a period apart (a position in metres spanning millions,
an angle in degrees declared periodic over ``[-pi, pi)``) alias the cosine
series, and the fit returns finite but meaningless terms without a word.

Many periods in a record are no problem (an unwrapped rotor over a long run
is still an angle in radians); a long step is. So the rule looks at steps
along the trajectories, not at the span of the data.
"""

import numpy as np

from ._space.mixed import MIXED_PERIOD
from ._state_order import swap_halves

#: Largest median step, in radians of the basis' angle, between consecutive
#: samples of a periodic or mixed coordinate along the trajectories. A
#: quarter period is four samples per turn: beyond it the samples miss the
#: shape of even ``cos theta`` (a central difference of ``sin`` at step
#: ``h`` is off by ``1 - sin(h) / h``, 36 % at ``pi / 2``), and at half a
#: period (the Nyquist limit) the turn's direction is lost altogether. The
#: median, not the largest step, so that a trajectory given wrapped into its
#: period (a jump of about one period at each crossing, at most a quarter of
#: the steps below this limit) still passes.
LONGEST_ANGLE_STEP = np.pi / 2


def check_angle_steps(estimator, space, data):
    """Raise a ``ValueError`` for a periodic or mixed coordinate whose steps exceed the limit.

    Only trajectory input (the derivative layout) has steps; 2-D states with
    derivatives are passed unchecked, since their span alone cannot tell an
    unwrapped rotor over many turns from a coordinate in wrong units.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        For the message: its class, ``periodic`` or ``mixed`` as given, its
        state order and state names.
    space : ModelSpace
        The space about to be fitted (model order ``(p, q)``): its
        ``periodic``, ``mixed`` and ``domain``.
    data : TrainingData
        The training data; without ``trajectories`` nothing is checked.

    Raises
    ------
    ValueError
        Naming the argument, the coordinate, its median step in periods,
        and the fixes.
    """
    trajectories = getattr(data, "trajectories", None)
    angles = space.periodic | space.mixed
    if trajectories is None or not angles.any():
        return
    columns = np.flatnonzero(angles)
    # One vectorised difference over the stacked states, the steps across
    # the boundary between two trajectories left out: fast for any number of
    # trajectories.
    lengths = np.array([S.shape[0] for _, S in trajectories], dtype=np.intp)
    keep = np.ones(max(int(lengths.sum()) - 1, 0), dtype=bool)
    keep[np.cumsum(lengths)[:-1] - 1] = False
    if data.sample_weight is not None:
        # Trajectories left out by a zero weight do not count.
        keep &= data.sample_weight[:-1] > 0
    if not keep.any():
        return
    steps = np.abs(np.diff(data.states[:, columns], axis=0)[keep])
    period = np.where(space.mixed, MIXED_PERIOD, space.domain[:, 1] - space.domain[:, 0])[columns]
    median = np.median(steps, axis=0)
    angle = 2 * np.pi * median / period
    for j in np.flatnonzero(~(angle <= LONGEST_ANGLE_STEP)):
        i = columns[j]
        raise ValueError(_message(estimator, space, i, median[j], period[j]))


def _message(estimator, space, i, median, period):
    """The error for model column ``i``: which argument, which coordinate, what was measured, the fix."""
    n = space.periodic.shape[0]
    swapped = getattr(estimator, "state_order", "pq") == "qp"
    column = int(swap_halves(np.arange(n))[i]) if swapped else int(i)
    names = getattr(estimator, "state_names", None)
    if names is None:
        names = getattr(estimator, "feature_names_in_", None)
    label = f"state variable {column}" + (f" ({names[column]!r})" if names is not None else "")
    model = type(estimator).__name__
    if space.mixed[i]:
        argument = "mixed"
        basis = (f"gives {label} the Fourier terms cos(k x), sin(k x) of period 2 pi in its "
                 f"own units")
        fix = ("Rescale it so that its unit is the radian (its Fourier terms have period "
               "2 pi), or set mixed to False for it (polynomials only).")
    else:
        argument = "periodic"
        basis = f"makes {label} an angle of period {period:.6g} (its domain's width)"
        fix = ("Rescale it to radians, or give its true period through `domain` (e.g. "
               "[-180, 180] for degrees), or set periodic to False for it if it is not an "
               "angle.")
    return (
        f"{model}: {argument}={getattr(estimator, argument)!r} {basis}, but along the "
        f"training trajectories its median step between consecutive samples is "
        f"{median:.3g}, {median / period:.3g} periods, above the limit of a quarter period: "
        f"the samples cannot resolve one period, the Fourier series aliases, and the fitted "
        f"model would be poor. {fix}"
    )
