"""The command's resampling of its chosen model: refits on resampled trajectories.

After the search, the chosen pipeline's regressor is refitted with
``n_resamples`` (``--resamples``, default 100; 0 or ``--no-resample`` turns
it off), so that the report, the model file and ``sk-hamiltonian show`` carry
each term's inclusion and interval, and the figure the prediction band.
"""

import time
import warnings

from ..inspection import prediction_band
from .words import counted

#: Resamples of the command unless told (--resamples).
DEFAULT_RESAMPLES = 100


def resample_chosen(args, data, best):
    """Refit ``best``'s regressor with resampling (in place); the seconds it took, or None.

    Resamples whole trajectories (the segments, when a record was cut into
    them) by the bootstrap, seeded by ``--seed``. Skipped, with a note, when
    turned off or with fewer than two trajectories.
    """
    n = args.resamples
    if n == 0:
        return None
    n_trajectories = len(data.X)
    if n_trajectories < 2:
        print("note: no resampling: the data hold one trajectory (intervals need several)")
        return None
    start = time.perf_counter()
    Xt = best[:-1].transform(data.X)
    with warnings.catch_warnings():
        # The search reported the chosen model's warnings already.
        warnings.simplefilter("ignore")
        best[-1].set_params(n_resamples=n, random_state=args.seed).fit(Xt)
    seconds = time.perf_counter() - start
    unit = "segments" if data.groups is not None else "trajectories"
    print(
        f"resampling: {counted(n, 'bootstrap resample')} of the {n_trajectories} {unit}, "
        f"each refitted with the chosen threshold, in {seconds:.1f} s: how often each term is "
        f"kept; the intervals below are the trajectory fit's own where the coefficients were "
        f"refined, else these refits' 90% percentile intervals (the spread from one sample "
        f"of {unit} to another, not a bias every sample shares, such as the de-noising's)"
    )
    return seconds


def band_or_none(model, x0, t):
    """The 90 % prediction band from ``x0`` over ``t`` (the trajectory fit's, else the refits'), or None."""
    if (getattr(model, "resampled_coef_", None) is None
            and getattr(model, "coef_covariance_", None) is None):
        return None
    low, _, high = prediction_band(model, x0, t)
    return low, high
