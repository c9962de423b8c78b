"""The model space of a fit, from the estimator's parameters and the training states.

The regressors' parameters say which space to fit in (``degree``,
``periodic``, ``mixed``, ``momentum_degree``, ``separable``,
``max_interaction``, ``couplings``, ``domain``); here they are checked against the data's state
variables and the box is fitted to the training states. :func:`build_space`
does the whole job and returns the :class:`~.space.ModelSpace`; the
regressors' ``fit``, ``partial_fit``, the dask fit and a search over
candidate spaces all call it, with an explicit domain where they share one.
"""

import operator

import numpy as np
from sklearn.utils import check_array

from .index_set import count_index_set, index_set
from .space import ModelSpace

# Thinnest interval of a domain: the map onto the basis window scales
# derivatives by 2 / width, Hessians and Gram products by its square, and
# 1e200 leaves room for both below overflow (1.8e308).
THINNEST_DOMAIN = 1e-100


def build_space(states, *, degree, domain=None, periodic=None, momentum_degree=None,
                separable=False, max_interaction=None, couplings=None,
                include_constant=False, sample_weight=None, check_size=None, mixed=None):
    """The model space of the parameters on the training states, every parameter checked.

    Parameters
    ----------
    states : ndarray of shape (n_samples, n_states)
        Training states; those of positive weight span the default box.
    degree, momentum_degree, separable, max_interaction, couplings
        The estimator's parameters of the same names (see
        :class:`~sk_hamiltonian.HamiltonianRegressor`).
    domain : array-like of shape (n_states, 2), default=None
        An explicit box; None fits the bounding box of the states (and
        ``[-pi, pi)`` for periodic variables).
    periodic : array-like of shape (n_states,) of bool, default=None
        Which variables are angles; None: none.
    mixed : array-like of shape (n_states,) of bool, default=None
        Which variables carry Fourier terms of period ``2 pi`` beside their
        Legendre polynomials (:mod:`.mixed`); None: none.
    include_constant : bool, default=False
        Whether the basis holds the constant (the vector-field baseline's
        does; a Hamiltonian's constant is free).
    sample_weight : ndarray of shape (n_samples,), default=None
        Weights of the states: only those of positive weight span the box.
    check_size : callable, default=None
        ``check_size(n_terms)``, called with the size of the index set
        (counted, not built) before it is built and before the box is
        fitted, to reject a problem with fewer equations than unknowns, or
        too large for memory, before anything large is allocated.

    Returns
    -------
    space : ModelSpace
        Its ``periodic``, ``powers`` and ``domain`` are the fitted
        attributes ``periodic_``, ``powers_`` and ``domain_``.

    Raises
    ------
    ValueError
        For parameters that do not fit the data (each message names the
        parameter and the fix).
    """
    n_states = states.shape[1]
    periodic = fit_periodic(periodic, n_states)
    mixed = fit_mixed(mixed, periodic)
    parameters = dict(
        degree=degree, periodic=periodic, momentum_degree=momentum_degree,
        separable=separable, max_interaction=max_interaction, couplings=couplings,
        include_constant=include_constant, mixed=mixed,
    )
    if check_size is not None:
        check_size(space_size(n_states, **parameters))
    powers = space_index_set(n_states, **parameters)
    spanning = states if sample_weight is None else states[sample_weight > 0]
    return ModelSpace(fit_domain(spanning, domain, periodic), powers, periodic, mixed)


def fit_periodic(periodic, n_states):
    """``periodic`` as a boolean array of one flag per state variable (all False for None)."""
    if periodic is None:
        return np.zeros(n_states, dtype=bool)
    flags = np.asarray(periodic)
    if (
        flags.shape != (n_states,)
        or not (flags.dtype == bool or np.isin(flags, (0, 1)).all())
    ):
        raise ValueError(
            f"periodic must be None or an array of {n_states} booleans, True for "
            f"each state variable that is an angle; got {periodic!r}."
        )
    return flags.astype(bool)


def fit_mixed(mixed, periodic):
    """``mixed`` as a boolean array of one flag per state variable, none of them periodic."""
    n_states = periodic.shape[0]
    if mixed is None:
        return np.zeros(n_states, dtype=bool)
    flags = np.asarray(mixed)
    if flags.shape != (n_states,) or not (flags.dtype == bool or np.isin(flags, (0, 1)).all()):
        raise ValueError(
            f"mixed must be None or an array of {n_states} booleans, True for each state "
            f"variable whose polynomials get Fourier terms of period 2 pi beside them; got "
            f"{mixed!r}."
        )
    flags = flags.astype(bool)
    both = np.flatnonzero(flags & periodic)
    if both.size:
        raise ValueError(
            f"State variable(s) {both.tolist()} are both periodic and mixed: a periodic "
            f"variable (an angle) has only Fourier terms, a mixed one has polynomials and "
            f"Fourier terms. Set one of periodic or mixed to False for them."
        )
    return flags


def space_index_set(n_states, **parameters):
    """The multi-indices of the parameters' space for ``n_states`` variables (checked).

    ``parameters`` are :func:`build_space`'s keywords but ``domain``.
    """
    return index_set(n_states, **_checked(n_states, **parameters))


def space_size(n_states, **parameters):
    """Size of :func:`space_index_set` (checked the same way), counted without building it."""
    return count_index_set(n_states, **_checked(n_states, **parameters))


def _checked(n_states, *, degree, periodic=None, momentum_degree=None, separable=False,
             max_interaction=None, couplings=None, include_constant=False, mixed=None):
    _check_halves(n_states, momentum_degree, separable)
    periodic = fit_periodic(periodic, n_states)
    return dict(
        degree=degree, periodic=periodic, momentum_degree=momentum_degree,
        separable=separable, max_interaction=max_interaction,
        couplings=check_couplings(couplings, n_states), include_constant=include_constant,
        mixed=fit_mixed(mixed, periodic),
    )


def _check_halves(n_states, momentum_degree, separable):
    if (momentum_degree is not None or separable) and n_states % 2:
        raise ValueError(
            f"momentum_degree and separable need states (p_1..p_d, q_1..q_d) with an "
            f"even number of variables; X has {n_states}."
        )


def check_couplings(couplings, n_states):
    """``couplings`` as tuples of variable indices, checked against ``n_states``."""
    if couplings is None:
        return None
    groups = []
    for group in couplings:
        try:
            members = [operator.index(i) for i in group]
        except TypeError:
            members = None
        if (
            members is None or isinstance(group, str)
            or any(isinstance(i, (bool, np.bool_)) for i in group)
            or len(set(members)) < 2 or len(set(members)) != len(members)
            or not all(0 <= i < n_states for i in members)
        ):
            raise ValueError(
                f"couplings must be a list of groups of state-variable indices, each "
                f"naming at least two distinct variables in [0, {n_states}) (momenta "
                f"first: p_1..p_d are 0..d-1, q_1..q_d are d..2d-1); got the group "
                f"{group!r}. For nearest neighbours on a chain of d particles, pass "
                f"[(d + i, d + i + 1) for i in range(d - 1)]."
            )
        groups.append(tuple(members))
    return groups


def fit_domain(states, domain, periodic):
    """The box of the basis: ``domain`` checked, or the bounding box of ``states``.

    Parameters
    ----------
    states : ndarray of shape (n_samples, n_states)
        The states that span the default box.
    domain : array-like of shape (n_states, 2) or None
        The estimator's ``domain``.
    periodic : ndarray of shape (n_states,) of bool
        Periodic variables take ``[-pi, pi)`` by default.

    Returns
    -------
    domain : ndarray of shape (n_states, 2)
    """
    n_states = states.shape[1]
    if domain is None:
        if states.shape[0] < 2:
            raise ValueError(
                f"Found n_samples={states.shape[0]} (with positive weight): at least 2 are "
                f"needed, since the domain is their bounding box."
            )
        # An angle's default period is [-pi, pi); other variables take the
        # bounding box of the training states (those with positive weight).
        box = np.column_stack([states.min(axis=0), states.max(axis=0)])
        box[periodic] = [-np.pi, np.pi]
        width = box[:, 1] - box[:, 0]
        scale = np.maximum(np.abs(box).max(axis=1), np.finfo(float).tiny)
        flat = np.flatnonzero(width <= 1e-9 * scale)  # within round-off of the values
        if flat.size:
            raise ValueError(
                f"State variable(s) {flat.tolist()} are constant in the training "
                f"data (up to round-off), so the bounding box is empty; pass an "
                f"explicit `domain` of shape ({n_states}, 2), or drop the "
                f"variable(s)."
            )
        thin = np.flatnonzero(width < THINNEST_DOMAIN)
        if thin.size:
            raise ValueError(
                f"State variable(s) {thin.tolist()} span less than {THINNEST_DOMAIN:g} "
                f"in the training data ({width[thin].tolist()}): on so thin a "
                f"bounding box (the default domain) the basis' derivatives overflow. "
                f"Rescale the variable(s) to units in which they span about 1."
            )
        return box
    # float64 whatever was given (an integer box too): one dtype for every
    # fitted array, which model files rely on.
    box = check_array(domain, input_name="domain", ensure_2d=False, dtype=np.float64)
    if box.shape != (n_states, 2) or np.any(box[:, 1] <= box[:, 0]):
        raise ValueError(
            f"domain must have shape ({n_states}, 2) with one (low, high) row "
            f"per state variable and low < high; got {np.asarray(domain).tolist()}."
        )
    with np.errstate(over="ignore", invalid="ignore"):
        width = box[:, 1] - box[:, 0]
    thin = np.flatnonzero(~(width >= THINNEST_DOMAIN) | ~np.isfinite(width))
    if thin.size:
        raise ValueError(
            f"domain rows {thin.tolist()} are {width[thin].tolist()} wide: the "
            f"basis' derivatives overflow on an interval narrower than "
            f"{THINNEST_DOMAIN:g} (or one whose width is not finite). Rescale "
            f"the variable(s) to units in which they span about 1."
        )
    return box
