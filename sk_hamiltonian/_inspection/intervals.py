"""How far the printed coefficients and predictions may move: intervals and bands.

Two sources, one interface. A model fitted with ``fit_on="trajectories"``
carries the covariance of its coefficients from the trajectory fit
(``coef_covariance_``, a sandwich estimate no narrower than the
model-based one): the intervals of the printed coefficients are normal
intervals of that estimate. A model fitted with
``n_resamples > 0`` carries refits on resamples of its trajectories
(``resampled_coef_``): they give each term's inclusion frequency, and the
intervals where there is no covariance (percentile intervals of the refits,
which describe the least-squares fit). :func:`term_intervals` gives both,
:func:`resampled_models` and :func:`prediction_band` turn the refits (or
draws from the covariance) into predictions.
"""

import copy
import warnings
from collections import namedtuple
from numbers import Real

import numpy as np
from scipy.special import ndtri
from sklearn.utils.validation import check_is_fitted

from .terms import _Readable, hamiltonian_terms

#: Draws of the coefficients from the trajectory fit's covariance for the
#: prediction band, and their seed (the band is the same at every call).
N_DRAWS = 100
DRAW_SEED = 0

TermInterval = namedtuple(
    "TermInterval",
    ["text", "powers", "coefficient", "median", "low", "high", "n_kept", "n_resamples"],
)
TermInterval.__doc__ = """One readable term of a learned Hamiltonian: its interval and inclusion.

Parameters
----------
text : str
    The term's factors, as in :class:`HamiltonianTerm`.
powers : tuple of int
    Its multi-index, as in :class:`HamiltonianTerm`.
coefficient : float
    Its coefficient in the fitted model (0 for a term the model dropped).
median : float
    The centre of the interval: the coefficient itself for an interval of
    the trajectory fit; the median of the coefficient over the refits, 0
    for a refit that dropped it, for a percentile interval.
low, high : float
    The interval at the chosen level: the coefficient plus or minus the
    normal quantile times its standard deviation (trajectory fit), or the
    percentiles of the refits (e.g. the 5th and 95th for 90 %).
n_kept : int
    In how many refits the term was kept (0 without refits).
n_resamples : int
    The refits (0 without).
"""


def term_intervals(model, *, level=0.9, state_names=None, rtol=1e-9):
    """Each readable term's coefficient interval, and its inclusion frequency over the refits.

    From a model fitted with ``fit_on="trajectories"`` (whose fit was
    accepted: it has ``coef_covariance_``), the intervals are those of the
    trajectory fit itself: the coefficient plus or minus the normal quantile
    of ``level`` times its standard deviation, from that covariance
    re-expressed in the readable basis. They describe the printed estimate,
    as precise as the trajectories make it; they do not cover a wrong set of
    terms, nor a bias every sample shares.

    Otherwise, from a model fitted with ``n_resamples > 0``, they are
    percentile intervals over its refits on resamples of the training
    trajectories (``resampled_coef_``): each refit is re-expanded in the
    readable basis of :func:`hamiltonian_terms`, and a refit that dropped a
    term gives it coefficient 0, so a term kept in 60 of 100 refits has an
    interval reaching 0. They show how much the least-squares coefficients
    would move with another sample of trajectories, not a bias that every
    sample shares, such as that of the derivative estimate or of noise in
    the states (see :ref:`intervals`).

    With refits, each term's inclusion frequency is theirs (a term counts as
    kept in a refit where its size is above ``rtol`` times that refit's
    largest), whatever gives the interval.

    Parameters
    ----------
    model : HamiltonianRegressor
        Fitted with ``fit_on="trajectories"`` or ``n_resamples > 0``.
    level : float, default=0.9
        The intervals' level: the normal quantile ``(1 + level) / 2``, or the
        ``(1 - level) / 2`` and ``(1 + level) / 2`` percentiles.
    state_names : list of str, default=None
        Names of the state variables, as in :func:`hamiltonian_terms`.
    rtol : float, default=1e-9
        The size below which a term counts as dropped, relative to the
        largest term of the same refit.

    Returns
    -------
    intervals : list of TermInterval
        The model's terms in the order of :func:`hamiltonian_terms`, then the
        terms it dropped that some refit kept, most often kept first.
        ``n_resamples`` is 0 without refits.

    Raises
    ------
    ValueError
        If the model has neither covariance nor refits, or ``level`` is not in
        (0, 1).

    See Also
    --------
    format_hamiltonian : The formula with its intervals (``intervals=True``).

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories, single_pendulum
    >>> from sk_hamiltonian.inspection import term_intervals
    >>> X = make_trajectories(single_pendulum(), 40, 20, 0.05, noise=0.01, random_state=0)
    >>> Xt = DerivativeTransformer(dt=0.05).fit_transform(X)
    >>> model = HamiltonianRegressor(4, periodic=[False, True], threshold=0.03,
    ...                              n_resamples=50, random_state=0).fit(Xt)
    >>> [(t.text, t.n_kept) for t in term_intervals(model)]
    [('cos(q)', 50), ('p^2', 50), ('cos(2 q)', 1), ('p^2*cos(2 q)', 1)]
    """
    check_is_fitted(model, "coef_")
    covariance = getattr(model, "coef_covariance_", None)
    resampled = getattr(model, "resampled_coef_", None)
    if covariance is None:
        _check_resampled(model)
    _check_level(level)
    readable = _Readable(model, state_names)
    main = {t.powers: t.coefficient for t in hamiltonian_terms(model, state_names=state_names,
                                                              rtol=rtol)}
    if resampled is not None:
        coef = readable.from_fitting @ np.asarray(resampled).reshape(resampled.shape[0], -1).T
        kept = readable.kept(coef, rtol)
    else:
        coef = kept = np.zeros((readable.unique.shape[0], 0))
    n = coef.shape[1]
    spread = None
    if covariance is not None:
        F = readable.from_fitting
        F = F.toarray() if hasattr(F, "toarray") else np.asarray(F)
        n_coef = len(np.ravel(model.coef_))
        C = covariance[:n_coef, :n_coef]
        spread = ndtri((1 + level) / 2) * np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", F, C, F),
                                                              0.0))
    tail = 100 * (1 - level) / 2
    out = []
    for j in np.flatnonzero(readable.nonconstant & (kept.any(axis=1) | _listed(readable, main))):
        powers = readable.powers(j)
        value = float(main.get(powers, 0.0))
        if spread is not None and powers in main:
            low, median, high = value - spread[j], value, value + spread[j]
        elif n:
            low, median, high = np.percentile(np.where(kept[j], coef[j], 0.0),
                                              [tail, 50, 100 - tail])
        else:
            continue
        out.append(TermInterval(readable.text(j), powers, value, float(median), float(low),
                                float(high), int(kept[j].sum()), n))
    order = {powers: k for k, powers in enumerate(main)}
    out.sort(key=lambda t: (order.get(t.powers, len(order)), -t.n_kept))
    return out


def _listed(readable, main):
    return np.array([readable.powers(j) in main for j in range(readable.unique.shape[0])])


def resampled_models(model):
    """The refits on resamples of a model fitted with ``n_resamples > 0``, as fitted models.

    Each is a copy of ``model`` with the coefficients (and friction) of one
    refit, on the same box; it predicts and simulates like any fitted model.
    Its other fitted attributes (``time_scale_``, the energy trend, ...) are
    the model's.

    Parameters
    ----------
    model : HamiltonianRegressor or VectorFieldRegressor
        Fitted with ``n_resamples > 0``.

    Returns
    -------
    models : list
        One per resample, in the order of ``resampled_coef_``.

    Raises
    ------
    ValueError
        If the model was fitted without resampling.
    """
    _check_resampled(model)
    resampled = model.resampled_coef_
    damping = getattr(model, "resampled_damping_", None)
    models = []
    for r, coef in enumerate(resampled):
        copied = copy.copy(model)
        for name in ("resampled_coef_", "resampled_damping_"):
            copied.__dict__.pop(name, None)
        copied.coef_ = np.array(coef)
        copied.support_ = coef != 0
        if damping is not None:
            copied.damping_ = np.array(damping[r])
        copied._rebuild_fitted()
        models.append(copied)
    return models


def prediction_band(model, x0, t, *, level=0.9, max_step=None):
    """Where the models the data allow go from ``x0``: the percentile band of their simulations.

    The models are 100 draws of the coefficients from their
    normal distribution under the trajectory fit (a model fitted with
    ``fit_on="trajectories"``: ``coef_covariance_``, seeded, so the band is
    the same every time), or else the refits of :func:`resampled_models`.
    Each is simulated from ``x0`` over ``t`` by RK4, in one batched loop,
    and the band is the percentile interval over them at each time; a model
    whose trajectory becomes non-finite counts as missing from then on. The
    band shows where the learned dynamics would differ with another sample
    of trajectories; it does not contain a bias every sample shares, nor a
    wrong set of terms.

    Parameters
    ----------
    model : HamiltonianRegressor or VectorFieldRegressor
        Fitted with ``fit_on="trajectories"`` (HamiltonianRegressor) or
        ``n_resamples > 0``.
    x0 : array-like of shape (n_states,)
        The initial state, in the order of the model's columns
        (``state_order``).
    t : array-like of shape (n_times,)
        Strictly increasing output times.
    level : float, default=0.9
        The band's level.
    max_step : float, default=None
        Largest RK4 step; None: the model's own RK4 step (a tenth of its
        ``time_scale_``). A model fitted on steps is simulated with AVF by
        default; its refits here by RK4, which differs by ``O(dt**2)``.

    Returns
    -------
    low, median, high : ndarray of shape (n_times, n_states)
        The band's edges and its median, in the columns' order; NaN where
        fewer than half of the models reached a time. A periodic variable
        is continued across its period from ``x0`` (in ``x0``'s chart, not
        wrapped as :meth:`~sk_hamiltonian.HamiltonianRegressor.simulate`
        wraps it).

    Raises
    ------
    ValueError
        If the model has neither a covariance nor refits, ``x0`` is not one
        finite state, or ``level`` is not in (0, 1).

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories, single_pendulum
    >>> from sk_hamiltonian.inspection import prediction_band
    >>> X = make_trajectories(single_pendulum(), 40, 20, 0.05, noise=0.01, random_state=0)
    >>> Xt = DerivativeTransformer(dt=0.05).fit_transform(X)
    >>> model = HamiltonianRegressor(4, periodic=[False, True], threshold=0.03,
    ...                              n_resamples=50, random_state=0).fit(Xt)
    >>> low, median, high = prediction_band(model, [0.0, 1.0], np.linspace(0, 5, 51))
    >>> bool(np.all(low <= high)), low.shape
    (True, (51, 2))
    """
    from .._integrate.ensemble import simulate_ensemble
    from .._integrate.simulation import check_initial_states, check_max_step, check_time

    draws = _drawn_coefficients(model)
    _check_level(level)
    x0, single = check_initial_states(x0, model.n_features_in_)
    if not single:
        raise ValueError(f"x0 must be one state of shape ({model.n_features_in_},).")
    x0 = model._to_model(x0)  # the columns' order (state_order) to the model's
    t = check_time(t)
    check_max_step(max_step)
    step = model._default_step("rk4") if max_step is None else max_step
    field = model._resampled_field() if draws is None else model._resampled_field(*draws)
    n = (model.resampled_coef_ if draws is None else draws[0]).shape[0]
    wrap = model._space.wrap if model.periodic_.any() else None
    runs = simulate_ensemble(field, np.repeat(x0, n, axis=0), t, step, wrap)
    if wrap is not None:
        # An angle's percentiles are taken in one chart, x0's: wrapped runs
        # on either side of the period's edge would span the whole period.
        runs = model._space.unwrap(runs, x0[0])
    reached = np.isfinite(runs).all(axis=2).sum(axis=0)
    tail = 100 * (1 - level) / 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # times no refit reached
        low, median, high = np.nanpercentile(runs, [tail, 50, 100 - tail], axis=0)
    missing = reached < (n + 1) // 2
    for edge in (low, median, high):
        edge[missing] = np.nan
    return tuple(model._to_model(edge) for edge in (low, median, high))


def _drawn_coefficients(model):
    """Draws of ``coef_`` (and ``damping_``) from the trajectory fit's covariance, or None.

    None where the model has no covariance (the refits serve); draws of the
    friction below zero are set to zero, as the fit keeps it.
    """
    check_is_fitted(model, "coef_")
    covariance = getattr(model, "coef_covariance_", None)
    if covariance is None:
        _check_resampled(model)
        return None
    coef = np.ravel(model.coef_)
    damping = getattr(model, "damping_", np.zeros(0))
    mean = np.concatenate([coef, damping]) if len(covariance) > len(coef) else coef
    rng = np.random.default_rng(DRAW_SEED)
    draws = rng.multivariate_normal(mean, covariance, size=N_DRAWS, method="eigh")
    draws[:, : len(coef)] *= model.support_  # the kept terms only
    if len(covariance) == len(coef):
        return draws, None
    return draws[:, : len(coef)], np.maximum(draws[:, len(coef):], 0.0)


def _check_level(level):
    if isinstance(level, bool) or not (isinstance(level, Real) and 0 < level < 1):
        raise ValueError(f"level must be a number in (0, 1), e.g. 0.9; got {level!r}.")


def _check_resampled(model):
    """Refuse a model without refits on resamples, saying how to get them."""
    check_is_fitted(model, "coef_")
    if getattr(model, "resampled_coef_", None) is None:
        raise ValueError(
            f"{type(model).__name__} was fitted without resampling: it has no "
            f"resampled_coef_. Fit it with n_resamples=100 (say) on trajectories (the "
            f"DerivativeTransformer output), or (HamiltonianRegressor) with "
            f"fit_on='trajectories', whose coefficients carry their covariance."
        )


