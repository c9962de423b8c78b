"""Stage 1 of the search: the model spaces, screened on one layout and fit target.

:func:`auto_spaces` offers each position coordinate as a polynomial, an angle
or both; :func:`screen` fits every space at the smallest degree on one
derivative layout and fit target, where their held-out equation errors are
measured against the same targets, and keeps the spaces the data cannot
reject against the best (:func:`kept_spaces`), the smallest models first.
"""

import itertools

import numpy as np
from sklearn.utils.parallel import Parallel, delayed

from ._degrees import failure_reason, search_unit
from ._selection import pick_within

FAMILIES = ("polynomial", "periodic", "mixed")
# Position coordinates searched one by one up to this many degrees of
# freedom; beyond, all positions share one family (3**d spaces grow fast).
PER_COORDINATE_DOF = 2
# Spaces kept after the screen, at most.
MAX_SPACES = 3


def auto_spaces(n_states):
    """The model spaces ``spaces="auto"`` searches for data with ``n_states`` variables.

    Each position coordinate is polynomial, periodic (an angle of period
    ``2 pi``) or mixed (both families); each combination is offered as a
    general Hamiltonian and as a mechanical one (``momentum_degree=2``).

    Parameters
    ----------
    n_states : int
        Number of state variables ``2d``.

    Returns
    -------
    spaces : list of dict
        Parameters of :class:`~sk_hamiltonian.HamiltonianRegressor`.
    """
    d = n_states // 2
    if d <= PER_COORDINATE_DOF:
        choices = list(itertools.product(FAMILIES, repeat=d))
    else:
        choices = [(family,) * d for family in FAMILIES]
    spaces = []
    for families in choices:
        space = {}
        for name in ("periodic", "mixed"):
            flags = [False] * d + [family == name for family in families]
            if any(flags):
                space[name] = flags
        for structure in ({}, {"momentum_degree": 2}):
            spaces.append({**space, **structure})
    return spaces


def screen_layout(denoise):
    """The layout the spaces are screened on: the middle de-noising degree."""
    polynomial = sorted(v for v in denoise if v != "finite_difference")
    return polynomial[len(polynomial) // 2] if polynomial else "finite_difference"


def within(inner, outer):
    """Whether every function of model space ``inner`` is one of ``outer`` (same variables).

    A polynomial or periodic variable lies within a mixed one (the Fourier
    terms of an angle of period ``2 pi`` are a mixed variable's), a
    mechanical Hamiltonian within a general one, a separable one within a
    non-separable one; other parameters must agree.
    """
    keys = (set(inner) | set(outer)) - {"periodic", "mixed", "momentum_degree", "separable"}
    if any(inner.get(key) != outer.get(key) for key in keys):
        return False
    flags = {name: (np.asarray(space.get("periodic") or [], bool),
                    np.asarray(space.get("mixed") or [], bool))
             for name, space in (("inner", inner), ("outer", outer))}
    size = max(f.size for pair in flags.values() for f in pair)
    (p_in, m_in), (p_out, m_out) = [
        tuple(np.resize(f, size) if f.size else np.zeros(size, bool) for f in pair)
        for pair in flags.values()
    ]
    # Per variable: polynomial (neither), periodic, or mixed (both families).
    if np.any(p_out & ~p_in) or np.any(p_in & ~p_out & ~m_out) or np.any(m_in & ~m_out):
        return False
    if np.any(~p_in & ~m_in & p_out):  # a polynomial variable is no angle
        return False
    degree_in, degree_out = inner.get("momentum_degree"), outer.get("momentum_degree")
    if degree_out is not None and (degree_in is None or degree_in > degree_out):
        return False
    return bool(inner.get("separable", False) or not outer.get("separable", False))


def kept_spaces(records, failures, spaces):
    """The spaces whose screened candidates tie with the best, the smallest of each nest.

    Ties are those of :func:`~._selection.equation_ties`: the data cannot
    reject them against the best. A tied space is dropped when a space within
    it (:func:`within`) ties with as few terms: it adds only functions the
    data do not need. At most :data:`MAX_SPACES` are kept, the smallest models
    first.
    """
    if not records:
        raise ValueError(
            "No model space could be set up on the screening layout." + failure_reason(failures))
    errors = np.array([r["errors"] for r in records])
    best, tied = pick_within(errors, np.array([r["n_terms"] for r in records]),
                             np.array([r["size"] for r in records]))
    if best is None:
        raise ValueError(
            "No model space could be fitted in every fold on the screening layout: give more "
            "trajectories or lower degrees."
        )
    ranking = {}
    for record, flag in zip(records, tied):
        if flag:
            key = (record["n_terms"], record["size"], float(np.mean(record["errors"])))
            ranking[record["space"]] = min(ranking.get(record["space"], key), key)
    kept = [k for k in ranking
            if not any(j != k and within(spaces[j], spaces[k]) and ranking[j][0] <= ranking[k][0]
                       for j in ranking)]
    return sorted(kept, key=ranking.get)[:MAX_SPACES]


def screen_target(fit_on, clean):
    """The fit target the spaces are screened on.

    The derivative fit, unless the data are exact (``clean``): then the least
    biased of Simpson's pairs and the weak form, whose truncation error is
    ``O(dt**4)`` where the derivatives' is ``O(dt**2)``, so that the exact law
    reaches the floor of :func:`~._selection.equation_ties`.
    """
    if clean:
        for target in ("simpson", "weak"):
            if target in fit_on:
                return target
    return "derivatives" if "derivatives" in fit_on else fit_on[0]


def screen(layout, folds, spaces, target, degree, thresholds, damping, domain, denoise, n_jobs):
    """Stage 1: every space at ``degree`` on one layout and target; the kept spaces' indices.

    Returns the records (``stage="screen"``, ``space`` the index into
    ``spaces``), the failures' messages and the indices of the kept spaces.
    """
    screened = Parallel(n_jobs=n_jobs)(
        delayed(search_unit)(layout, folds, [space], target, [degree], thresholds, damping,
                             domain, denoise, rollout=False)
        for space in spaces
    )
    records, failures = [], []
    for k, (unit_records, _, unit_failures) in enumerate(screened):
        failures.extend(unit_failures)
        for record in unit_records:
            record.update(space=k, stage="screen")
        records.extend(unit_records)
    return records, failures, kept_spaces(records, failures, spaces)
