"""Stage 1 of the search: the model spaces, screened on one layout and fit target.

:func:`auto_spaces` offers each position coordinate as a polynomial, an angle
or both (beyond :data:`PER_COORDINATE_DOF` degrees of freedom, spaces of
pairwise couplings, with angles only where :func:`angle_like` finds them);
:func:`screen` fits every space at the smallest degree on one derivative
layout and fit target, where their held-out equation errors are measured
against the same targets, and keeps the spaces the data cannot reject against
the best (:func:`kept_spaces`), the smallest models first.
"""

import itertools
import warnings

import numpy as np
from sklearn.utils.parallel import Parallel, delayed

from .._derivatives import DerivativeTransformer
from ..exceptions import SmoothingWarning
from ._degrees import failure_reason, search_unit
from ._results import transformer_params
from ._selection import equation_ties, pick_within

FAMILIES = ("polynomial", "periodic", "mixed")
# Position coordinates searched one by one, in full total-degree spaces, up to
# this many degrees of freedom. Beyond, 3**d combinations and C(n + 2d, 2d)
# unknowns per space grow too fast: the spaces couple variables pairwise.
PER_COORDINATE_DOF = 2
# Most variables one basis function of an automatic space depends on beyond
# PER_COORDINATE_DOF: pairwise couplings, C(2d, 2) pairs, as in lattices and
# chains, where C(n + 2d, 2d) functions would be needed for any coupling.
AUTO_INTERACTION = 2
# A position whose observed values span this much of a full turn (2 pi) or
# more looks like an angle: a wrapped angle spans just under 2 pi, a rotating
# one more, and a polynomial of low degree cannot follow cos q over a turn.
ANGLE_SPAN = 0.9 * 2 * np.pi
# Spaces kept after the screen, at most.
MAX_SPACES = 3
# A derivative layout whose de-noising polynomials leave residuals this many
# times the noise level is left out of the search (unless all are), whatever
# the degrees of freedom. Sampled ten times per period, the anharmonic
# spring's polynomial layouts read 39 to 41 and their finalists won the
# rollout scores, judged in units of their own smoothed states' spread, with
# a law of q alone; the study's scenes read at most 8 (Henon-Heiles' cubics).
GROSS_MISFIT = 20.0


def angle_like(states):
    """Which position coordinates look like angles: their values span nearly a full turn or more.

    Parameters
    ----------
    states : array-like of shape (..., n_states) or list of arrays of shape (n_times, n_states)
        Observed states ``(p_1..p_d, q_1..q_d)``, without time stamps: one
        array (samples, or trajectories of samples) or one per trajectory.

    Returns
    -------
    angles : ndarray of shape (n_states // 2,) of bool
        True for each position ``q_i`` whose observed span
        ``max q_i - min q_i`` is at least ``ANGLE_SPAN`` (90 % of
        ``2 pi``), NaN samples aside.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.model_selection import angle_like
    >>> t = np.linspace(0, 10, 200)
    >>> angle_like(np.column_stack([t, 0 * t, np.sin(3 * t) - 2, 2 * t]))
    array([False,  True])
    """
    if isinstance(states, (list, tuple)):
        states = np.concatenate([np.asarray(T, dtype=float) for T in states])
    states = np.asarray(states, dtype=float)
    if states.ndim < 2 or states.shape[-1] % 2 or states.shape[-1] == 0:
        raise ValueError(
            f"states must hold an even number of state variables (p, q) in its last axis; "
            f"got shape {states.shape}. Pass the states without their time stamps.")
    flat = states.reshape(-1, states.shape[-1])
    positions = flat[:, flat.shape[1] // 2:]
    with warnings.catch_warnings():
        # A position never observed (all NaN) spans nothing.
        warnings.simplefilter("ignore", RuntimeWarning)
        span = np.nanmax(positions, axis=0) - np.nanmin(positions, axis=0)
    return np.nan_to_num(span, nan=0.0) >= ANGLE_SPAN


def auto_spaces(n_states, angles=None):
    """The model spaces ``spaces="auto"`` searches for data with ``n_states`` variables.

    Up to two degrees of freedom, each position
    coordinate is polynomial, periodic (an angle of period ``2 pi``) or mixed
    (both families); each combination is offered as a general Hamiltonian and
    as a mechanical one (``momentum_degree=2``): 6 spaces for one degree of
    freedom, 18 for two.

    Beyond, the spaces couple variables pairwise (``max_interaction=2``),
    whose size grows like ``d**2`` rather than ``C(n + 2d, 2d)``: a general
    Hamiltonian, a mechanical one and a separable mechanical one
    (``H = T(p) + V(q)``), fitted from their normal equations
    (``solver="normal"``). The positions ``angles`` marks are offered as
    periodic, then as mixed, in a copy of each (all of them alike); the
    other positions are polynomial.

    Parameters
    ----------
    n_states : int
        Number of state variables ``2d``.
    angles : array-like of shape (n_states // 2,) of bool, default=None
        Which positions look like angles (:func:`angle_like` of the data);
        used beyond two degrees of freedom only. None: no position is an
        angle.

    Returns
    -------
    spaces : list of dict
        Parameters of :class:`~sk_hamiltonian.HamiltonianRegressor`.

    Examples
    --------
    >>> from sk_hamiltonian.model_selection import auto_spaces
    >>> len(auto_spaces(2)), len(auto_spaces(4))
    (6, 18)
    >>> auto_spaces(6)[1]
    {'momentum_degree': 2, 'max_interaction': 2, 'solver': 'normal'}
    >>> len(auto_spaces(6, angles=[False, True, False]))
    9
    """
    d = n_states // 2
    if d <= PER_COORDINATE_DOF:
        return _per_coordinate_spaces(d)
    if angles is None:
        angles = np.zeros(d, dtype=bool)
    angles = np.asarray(angles)
    if angles.shape != (d,) or angles.dtype != bool:
        raise ValueError(
            f"angles must be an array of {d} booleans, one per position (n_states={n_states}); "
            f"got {angles!r}. Use angle_like(states) of the data, or None for no angle.")
    families = [{}]
    if angles.any():
        flags = [False] * d + angles.tolist()
        families += [{"periodic": flags}, {"mixed": flags}]
    structures = [{}, {"momentum_degree": 2}, {"momentum_degree": 2, "separable": True}]
    # The candidates are solved from normal equations already; so is the
    # refit, which then holds n x n matrices rather than the design twice
    # (FPU chain of 8 particles: 245 MB against 1.2 GB with "lstsq", the
    # same coefficients to 2e-14).
    return [{**family, **structure, "max_interaction": AUTO_INTERACTION, "solver": "normal"}
            for family in families for structure in structures]


def _per_coordinate_spaces(d):
    """Each position polynomial, periodic or mixed, general and mechanical."""
    spaces = []
    for families in itertools.product(FAMILIES, repeat=d):
        space = {}
        for name in ("periodic", "mixed"):
            flags = [False] * d + [family == name for family in families]
            if any(flags):
                space[name] = flags
        for structure in ({}, {"momentum_degree": 2}):
            spaces.append({**space, **structure})
    return spaces


def derivative_layouts(X, dt, denoise, strict=False):
    """Each derivative layout of trajectories ``X``, and the biased ones.

    A layout is biased when its de-noising polynomials leave residuals more
    than :data:`GROSS_MISFIT` times the noise level, or with ``strict`` any
    :class:`~sk_hamiltonian.SmoothingWarning` of
    :class:`~sk_hamiltonian.DerivativeTransformer`: they cannot follow the
    trajectories. The warnings reach the caller either way.

    Returns
    -------
    layouts : dict
        Each entry of ``denoise`` to its layout.
    misfits : set
        The entries whose polynomials are biased.
    """
    layouts, misfits = {}, set()
    bound = 0.0 if strict else GROSS_MISFIT
    for key in denoise:
        transformer = DerivativeTransformer(dt=dt, **transformer_params(key))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            layouts[key] = transformer.fit_transform(X)
        for w in caught:
            if issubclass(w.category, SmoothingWarning) and not w.message.ratio <= bound:
                misfits.add(key)
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return layouts, misfits


def screen_layout(denoise, misfits=()):
    """The layout the spaces are screened on: the middle de-noising degree.

    Layouts in ``misfits`` are passed over: the middle degree of the others,
    else finite differences, else the largest degree. A biased layout makes
    a larger space look needed, whose extra functions absorb the bias (FPU-beta
    chain of 4 particles, 200 trajectories of 41 samples, dt = 0.05, 1 %
    noise: with Q = 5 the separable mechanical space of the law is rejected
    against the mechanical one, with finite differences it is kept alone).
    """
    usable = [v for v in denoise if v not in misfits]
    polynomial = sorted(v for v in usable if v != "finite_difference")
    if polynomial:
        return polynomial[len(polynomial) // 2]
    if "finite_difference" in denoise:
        return "finite_difference"
    return max(denoise)


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


def screen_ties(records):
    """Which screened candidates the data cannot reject, overall or at their own threshold.

    A candidate ties when :func:`~._selection.equation_ties` cannot reject
    it against the lowest mean equation error of all, or against the lowest
    at its own threshold where that one ties with the lowest of all. The
    second way keeps a space whose few terms are as good as another space's
    at the same sparsity, when the lowest error of all belongs to a dense fit
    of a richer space: with relative noise the derivative targets carry an
    error that grows with the state, which dozens of terms absorb in part and
    the law's terms cannot (a spring at 2 % multiplicative noise: its three
    exact terms 10 % above a mixed space's 34, 3 % above a periodic space's
    five at the same threshold).

    Returns the row :func:`~._selection.pick_within` picks among the overall
    ties (None when no candidate has finite errors in every fold) and the ties.
    """
    errors = np.array([r["errors"] for r in records])
    best, tied = pick_within(errors, np.array([r["n_terms"] for r in records]),
                             np.array([r["size"] for r in records]))
    if best is None:
        return best, tied
    with np.errstate(invalid="ignore"):
        means = np.where(np.isfinite(errors).all(axis=1), errors.mean(axis=1), np.inf)
    thresholds = np.array([r["threshold"] for r in records])
    for threshold in np.unique(thresholds):
        rows = np.flatnonzero(thresholds == threshold)
        lowest = int(np.argmin(means[rows]))
        if tied[rows[lowest]]:
            tied[rows] |= equation_ties(errors[rows], lowest)
    return best, tied


def kept_spaces(records, failures, spaces):
    """The spaces whose screened candidates tie with the best, the smallest of each nest.

    Ties are those of :func:`screen_ties`: the data cannot reject them
    against the best. A tied space is dropped when a space within it
    (:func:`within`) ties with as few terms: it adds only functions the data
    do not need. At most :data:`MAX_SPACES` are kept, the smallest models
    first.
    """
    if not records:
        raise ValueError(
            "No model space could be set up on the screening layout." + failure_reason(failures))
    best, tied = screen_ties(records)
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
