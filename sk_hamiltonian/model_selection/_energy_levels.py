"""Whether the trajectories reach more than one level of the learned energy.

A conservative system's trajectory stays on one level set of its Hamiltonian,
and so do the segments cut from one record. Data on a single level set
``H = E`` determine the law only there: ``H`` and ``H + (H - E)^2 g`` have the
same gradient wherever ``H = E``, for any ``g``, so laws that differ by such
terms explain the data alike (a pendulum's ``cos q``, ``p^2``, ``p^2 cos q``
and ``cos 2q`` on one orbit), and the search chooses among them by their
number of terms alone. :func:`one_level` says when the data are so: the
trajectories' energies differ by less than a small fraction of the range the
learned energy covers over the box the data fill, beyond what the noise of a
single sample's energy leaves between them.
"""

import warnings

import numpy as np

from .._outliers import MAD_TO_STD
from ..exceptions import DomainWarning, IllConditionedWarning

# The trajectories' energies spread over less than this fraction of the
# learned energy's range over the data's box: one level. Records at energies
# drawn across a box spread over a good part of it (a tenth or more).
MAX_LEVEL_SPAN = 0.01
# ... beyond this many times one sample's energy spread along a trajectory:
# the medians of pieces of one record, tens of samples each, spread over
# about one sample's spread (their own noise, and the noise's bias of the
# energy, which changes along an orbit).
NOISE_SPREADS = 2.0
# Points of the data's box at which the learned energy's range is taken.
N_BOX_POINTS = 2048


def one_level(hamiltonian, pieces):
    """The spread of the trajectories' energies when they lie on one level, else None.

    Parameters
    ----------
    hamiltonian : callable
        ``hamiltonian(X)``: the learned energy at the rows of ``X``.
    pieces : list of ndarray of shape (n_times_k, n_states)
        The states of the trajectories (or of the segments of records).

    Returns
    -------
    found : dict or None
        None when the trajectories' (median) energies spread over more than
        :data:`MAX_LEVEL_SPAN` of the learned energy's range (1st to 99th
        percentile) over the box of the data's bulk (each variable's 1st to
        99th percentile) plus :data:`NOISE_SPREADS` times the robust spread
        of one sample's energy along a trajectory; else ``span``, their
        spread as a fraction of that range, ``n_trajectories`` and
        ``energy``, the median energy of the data.
    """
    states = np.concatenate(pieces)
    along = np.split(hamiltonian(states), np.cumsum([len(P) for P in pieces])[:-1])
    energies = np.array([np.median(E) for E in along])
    # One sample's energy spread along a trajectory (the noise's, for a
    # conserved law): levels closer than it cannot be told apart.
    spread = np.median([MAD_TO_STD * np.median(np.abs(E - np.median(E))) for E in along])
    # The box of the data's bulk: a few records that escape to states ten
    # times larger (Henon-Heiles') would make a polynomial's range over the
    # whole box so wide that every spread of energies looks small.
    low, high = np.quantile(states, [0.01, 0.99], axis=0)
    # A fixed draw: the same data always give the same verdict.
    box = np.random.default_rng(0).uniform(low, high, size=(N_BOX_POINTS, states.shape[1]))
    with np.errstate(all="ignore"):
        over_box = hamiltonian(box)
    over_box = over_box[np.isfinite(over_box)]
    if not over_box.size or not np.all(np.isfinite(energies)):
        return None
    # Quantiles again: a corner of the box far from the data (a polynomial's)
    # should not make every spread look small.
    width = np.subtract(*np.quantile(over_box, [0.99, 0.01]))
    if not width > 0:
        return None
    span = float(np.ptp(energies) / width)
    if np.ptp(energies) > MAX_LEVEL_SPAN * width + NOISE_SPREADS * spread:
        return None
    return {"span": span, "n_trajectories": len(pieces), "energy": float(np.median(energies))}


def one_level_message(found):
    """What :func:`one_level`'s finding means for the law, in a few sentences."""
    return (
        f"The data lie on one level of the learned energy: every trajectory is at H~ = "
        f"{found['energy']:.4g} (their median energies within {100 * found['span']:.2g} % of "
        f"its range over the box the data fill), as the segments of one record are. "
        f"Trajectories on one energy level determine the law only on that level (H and "
        f"H + (H - E)^2 g agree there for any g): the search prefers few terms among laws "
        f"that explain these data alike, but one with more terms may be kept, and a law that "
        f"fits this level may be wrong off it. Record trajectories at other energies to pin "
        f"the law down."
    )


def warn_one_level(model, X, dt):
    """:func:`one_level` of the chosen model on the search's data, with a warning when found.

    Parameters
    ----------
    model : HamiltonianRegressor
        The chosen model, fitted.
    X : list of ndarray
        The prepared trajectories in the columns' order (time first when
        ``dt`` is None).
    dt : float or None
        The search's ``dt`` (None: time stamps in the first column).

    Returns
    -------
    found : dict or None
        :func:`one_level`'s finding, with its ``message``.
    """
    offset = 1 if dt is None else 0
    pieces = [np.asarray(T, dtype=float)[:, offset:] for T in X]
    with warnings.catch_warnings():
        # Points of the data's box may lie beyond a periodic model's domain.
        warnings.simplefilter("ignore", DomainWarning)
        found = one_level(model.hamiltonian, pieces)
    if found is not None:
        found["message"] = one_level_message(found)
        warnings.warn(f"HamiltonianSearchCV: {found['message']}", IllConditionedWarning,
                      stacklevel=3)
    return found
