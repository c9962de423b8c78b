"""Read a learned Hamiltonian: its terms in the user's own coordinates.

The regressors expand ``H~`` in Legendre polynomials on the box mapped to
``[-1, 1]`` and in Fourier series of angles measured from the start of their
period, which is good for fitting and opaque for reading. :func:`hamiltonian_terms`
re-expands ``H~`` in monomials ``x**k`` of the state variables as the user
gave them, times ``cos(k w x)`` and ``sin(k w x)`` for periodic variables
(``w = 2 pi / period``), and ranks the terms by their size over the domain;
:func:`format_hamiltonian` writes the leading ones as one line. A model fitted
with ``n_resamples > 0`` also carries refits on resamples of its trajectories:
:func:`term_intervals` gives each term's inclusion frequency and interval over
them, :func:`format_hamiltonian` prints them with ``intervals=True``, and
:func:`resampled_models` and :func:`prediction_band` turn them into
predictions.
"""

import copy
import math
import warnings
from collections import namedtuple
from numbers import Real

import numpy as np
from sklearn.utils.validation import check_is_fitted

from ._space.mixed import MIXED_PERIOD, code_frequency
from ._space.readable import ReadableBasis

__all__ = [
    "HamiltonianTerm",
    "TermInterval",
    "format_hamiltonian",
    "hamiltonian_terms",
    "prediction_band",
    "resampled_models",
    "term_intervals",
    "to_sympy",
]

HamiltonianTerm = namedtuple("HamiltonianTerm", ["coefficient", "powers", "text", "size"])
HamiltonianTerm.__doc__ = """One term of a learned Hamiltonian in the user's coordinates.

Parameters
----------
coefficient : float
    Its coefficient.
powers : tuple of int
    Per state variable: the exponent ``k`` of ``x**k``, or for a periodic
    variable a signed frequency (``+k``: ``cos(k w x)``, ``-k``: ``sin(k w x)``);
    for a mixed variable (``mixed=True``) an exponent ``k >= 0`` or a negative
    code of ``cos(k x)`` (``-(2k - 1)``) or ``sin(k x)`` (``-2k``).
text : str
    The term's factors, e.g. ``"p^2"`` or ``"p1*cos(q2)"`` (without coefficient).
size : float
    Its size in the data: ``|coefficient|`` times, for each variable with a
    non-zero exponent ``k``, ``r**k``, where ``r`` is the root-mean-square of
    that variable over the training states (trigonometric factors count 1).
    The ranking key.
"""


TermInterval = namedtuple(
    "TermInterval",
    ["text", "powers", "coefficient", "median", "low", "high", "n_kept", "n_resamples"],
)
TermInterval.__doc__ = """One readable term of a learned Hamiltonian over the refits on resamples.

Parameters
----------
text : str
    The term's factors, as in :class:`HamiltonianTerm`.
powers : tuple of int
    Its multi-index, as in :class:`HamiltonianTerm`.
coefficient : float
    Its coefficient in the fitted model (0 for a term the model dropped).
median : float
    The median of its coefficient over the refits, 0 for a refit that
    dropped it.
low, high : float
    The percentile interval of that coefficient at the chosen level (e.g.
    the 5th and 95th percentiles for 90 %).
n_kept : int
    In how many refits the term was kept.
n_resamples : int
    The refits.
"""


def _factor_size(power, magnitude, periodic):
    if periodic or power <= 0:
        return 1.0
    return float(magnitude) ** int(power)


def _factor_text(name, power, periodic, omega, mixed=False):
    if power == 0:
        return None
    if mixed and power < 0:
        # A mixed variable's Fourier factor, named by its signed frequency.
        return _factor_text(name, int(code_frequency(power)), True, omega)
    if not periodic:
        return name if power == 1 else f"{name}^{power}"
    k = abs(power) * omega
    scale = "" if np.isclose(k, 1.0) else (f"{abs(power)} " if np.isclose(omega, 1.0) else f"{k:.4g} ")
    return f"{'cos' if power > 0 else 'sin'}({scale}{name})"


def _state_names(model, state_names):
    """The given names checked, else ``feature_names_in_``, else ``p, q`` or ``p1.., q1..``."""
    n_states = model.n_features_in_
    if state_names is None:
        names = getattr(model, "feature_names_in_", None)
        return list(names) if names is not None else _default_names(n_states)
    if len(state_names) != n_states:
        raise ValueError(
            f"state_names must have one name per state variable ({n_states}); got "
            f"{len(state_names)}."
        )
    return list(state_names)


def _default_names(n_states):
    d = n_states // 2
    if d == 1:
        return ["p", "q"]
    return [f"p{i + 1}" for i in range(d)] + [f"q{i + 1}" for i in range(d)]


def hamiltonian_terms(model, *, state_names=None, rtol=1e-9):
    """The terms of a learned ``H~`` in the user's coordinates, largest first.

    ``H~`` is re-expanded in products of monomials ``x**k`` (ordinary
    variables, in the units of the data) and of ``cos(k w x)``, ``sin(k w x)``
    (periodic variables with period ``2 pi / w``), and each term is measured by
    its size at the typical magnitude of the training states (see
    :class:`HamiltonianTerm`). Measuring at the data's scale rather than at the
    corners of the box keeps the low-order terms that carry the physics (say
    ``p**2 / 2`` and ``q**2``) ahead of the high-order terms of a truncated
    series, which are large at the corners and largely cancel each other.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the state variables; None uses ``feature_names_in_`` if the
        model has them, else ``p, q`` or ``p1.., q1..``.
    rtol : float, default=1e-9
        Terms smaller than this fraction of the largest are dropped: they are
        round-off of the change of basis.

    Returns
    -------
    terms : list of HamiltonianTerm
        Sorted by decreasing ``size``. The constant is left out (``H~`` is
        defined up to one).

    See Also
    --------
    format_hamiltonian : The leading terms as one line.

    Notes
    -----
    Converting Legendre expansions of high degree to monomials cancels large
    terms against each other; beyond degree ~10 on wide domains the
    coefficients carry fewer digits than the model. The ranking, not the
    last digit, is what this view is for.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.inspection import hamiltonian_terms
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform([-2, 0], [2, 3], size=(200, 2))
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])           # H = (p^2 + q^2) / 2
    >>> model = HamiltonianRegressor(degree=2).fit(X, y)
    >>> [(t.text, round(t.coefficient, 6)) for t in hamiltonian_terms(model)]
    [('q^2', 0.5), ('p^2', 0.5)]
    """
    check_is_fitted(model, "coef_")
    readable = _Readable(model, state_names)
    # Readable coefficients of every output (one for H~), by the change of basis.
    coef = readable.from_fitting @ np.ravel(model.coef_)
    keep = readable.kept(coef, rtol)
    terms = [HamiltonianTerm(float(coef[j]), readable.powers(j), readable.text(j),
                             float(abs(coef[j]) * readable.scale[j]))
             for j in np.flatnonzero(keep)]
    terms.sort(key=lambda term: -term.size)
    return terms


class _Readable:
    """The readable basis of a fitted model: change of basis, term sizes and texts."""

    def __init__(self, model, state_names):
        self.names = _state_names(model, state_names)
        self.unique = np.asarray(model.powers_)
        self.periodic = np.asarray(model.periodic_)
        self.mixed = _mixed(model)
        self.from_fitting = ReadableBasis(self.unique, model.domain_, self.periodic,
                                          self.mixed).from_fitting
        magnitude = model._state_magnitude
        self.scale = np.array([
            np.prod([_factor_size(p, magnitude[i], self.periodic[i])
                     for i, p in enumerate(row)])
            for row in self.unique
        ])
        self.nonconstant = np.any(self.unique != 0, axis=1)
        low, high = model.domain_[:, 0], model.domain_[:, 1]
        self.omega = np.where(self.mixed, 2 * np.pi / MIXED_PERIOD, 2 * np.pi / (high - low))

    def kept(self, coef, rtol):
        """Terms of readable coefficients ``coef`` (last axis: models) above ``rtol`` of the largest."""
        size = np.abs(coef) * (self.scale if coef.ndim == 1 else self.scale[:, None])
        size[~self.nonconstant] = 0.0
        largest = size.max(axis=0)
        return (size > rtol * largest) & (largest > 0)

    def powers(self, j):
        return tuple(int(p) for p in self.unique[j])

    def text(self, j):
        parts = [
            _factor_text(self.names[i], int(p), bool(self.periodic[i]), self.omega[i],
                         bool(self.mixed[i]))
            for i, p in enumerate(self.unique[j])
        ]
        return "*".join(part for part in parts if part)


def format_hamiltonian(model, *, state_names=None, max_terms=8, intervals=False):
    """The leading terms of a learned ``H~`` as one readable line.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the state variables, as in :func:`hamiltonian_terms`.
    max_terms : int, default=8
        How many terms to show; the rest are summarized.
    intervals : bool or float, default=False
        With a model fitted with ``n_resamples > 0``: each coefficient is
        followed by ``(±h)``, half the width of its percentile interval over
        the refits (:func:`term_intervals`), at the level given (True: 0.9),
        and the coefficient is rounded to the interval's first digit; a term
        dropped by some refits says in how many it was kept, and terms the
        model dropped but some refits kept are listed after the formula,
        e.g. ``H~ = -9.8 (±0.04) cos(q) + 0.4995 (±0.002) p^2 + const; every
        term kept in 100/100 resamples (90% intervals)``.

    Returns
    -------
    text : str
        ``"H~ = c1 t1 + c2 t2 + ... + const"``, terms in decreasing size.

    Raises
    ------
    ValueError
        With ``intervals`` and a model fitted without resampling.

    See Also
    --------
    hamiltonian_terms : The terms themselves.
    term_intervals : The intervals themselves.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.inspection import format_hamiltonian
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-1, 1, size=(200, 2))
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])
    >>> print(format_hamiltonian(HamiltonianRegressor(degree=2).fit(X, y)))
    H~ = 0.5 q^2 + 0.5 p^2 + const
    """
    terms = hamiltonian_terms(model, state_names=state_names)
    spread = None
    if intervals is not False and intervals is not None:
        level = 0.9 if intervals is True else intervals
        if isinstance(level, bool) or not (isinstance(level, Real) and 0 < level < 1):
            raise ValueError(
                f"intervals must be True (90% intervals), False, or a level in (0, 1); got "
                f"{intervals!r}."
            )
        spread = {t.powers: t for t in term_intervals(model, level=level,
                                                      state_names=state_names)}
    if not terms:
        return "H~ = const" + ("" if spread is None else _absent(spread.values(), set()))
    parts = []
    for term in terms[:max_terms]:
        sign = "-" if term.coefficient < 0 else "+"
        if spread is None:
            parts.append(f"{sign} {abs(term.coefficient):.4g} {term.text}")
            continue
        interval = spread[term.powers]
        value, half = _rounded(abs(term.coefficient), (interval.high - interval.low) / 2)
        kept = ("" if interval.n_kept == interval.n_resamples
                else f" [kept in {interval.n_kept}/{interval.n_resamples}]")
        parts.append(f"{sign} {value} (±{half}) {term.text}{kept}")
    text = " ".join(parts)
    text = text[2:] if text.startswith("+ ") else "-" + text[2:]
    rest = terms[max_terms:]
    if rest:
        share = rest[0].size / terms[0].size
        # Two significant digits: "0.0%" would hide how small the rest is.
        text += (
            f" + ... ({len(rest)} smaller terms, each below {100 * share:.2g}% of the largest)"
            if len(rest) > 1
            else f" + ... (1 smaller term, below {100 * share:.2g}% of the largest)"
        )
    text = "H~ = " + text + " + const"
    if spread is not None:
        text += _summary(spread, terms, level)
    return text


def _rounded(value, half):
    """``value`` to the first digit of ``half``, and ``half`` to one digit (six digits at most)."""
    if not half > 0:
        return f"{value:.6g}", "0"
    first = math.floor(math.log10(half))
    # Two digits of a half-width that starts with 1 (0.0016, not 0.002).
    first -= int(half < 2 * 10.0**first)
    digits = (math.floor(math.log10(value)) if value > 0 else first) - first + 1
    digits = min(max(digits, 1), 6)
    if 1e-4 <= value < 1e6:
        decimals = max(0, digits - 1 - math.floor(math.log10(value)))
        return f"{value:.{decimals}f}", _one_digit(half, first)
    return f"{value:.{digits}g}", _one_digit(half, first)


def _one_digit(half, first):
    """``half`` to the digit ``10**first``."""
    if -5 <= first < 6:
        return f"{round(half, -first):.{max(0, -first)}f}"
    return f"{half:.{2 if half < 2 * 10.0 ** (first + 1) else 1}g}"


def _summary(spread, terms, level):
    """What follows the formula: how often its terms were kept, and which others were."""
    shown = {term.powers for term in terms}
    n = next(iter(spread.values())).n_resamples
    always = [t for t in terms if spread[t.powers].n_kept == n]
    if len(always) == len(terms):
        kept = f"; every term kept in {n}/{n} resamples"
    elif always:
        kept = f"; the others kept in {n}/{n} resamples"
    else:
        kept = ""
    return kept + _absent(spread.values(), shown) + f" ({level:.0%} intervals)"


def _absent(intervals, shown, most=3):
    """The terms some refits kept but the model did not, most often kept first."""
    others = sorted((t for t in intervals if t.powers not in shown and t.n_kept),
                    key=lambda t: -t.n_kept)
    if not others:
        return ""
    listed = ", ".join(f"{t.text} ({t.n_kept}/{t.n_resamples})" for t in others[:most])
    more = f" and {len(others) - most} more" if len(others) > most else ""
    return f"; not in H~ but kept in some resamples: {listed}{more}"


def term_intervals(model, *, level=0.9, state_names=None, rtol=1e-9):
    """Each readable term's inclusion frequency and coefficient interval over the resampled refits.

    A model fitted with ``n_resamples > 0`` holds the coefficients of its
    refits on resamples of the training trajectories (``resampled_coef_``).
    Each refit is re-expanded in the readable basis of
    :func:`hamiltonian_terms`; a term counts as kept in a refit where its size
    is above ``rtol`` times that refit's largest (the rest is round-off of the
    change of basis). A refit that dropped a term gives it coefficient 0, so
    a term kept in 60 of 100 refits has an interval reaching 0.

    The intervals are percentile intervals of a bootstrap over whole
    trajectories: they show how much the coefficients would move with
    another sample of trajectories from the same experiment. They do not
    show a bias that every sample shares, such as that of the derivative
    estimate or of noise in the states (see :ref:`intervals`).

    Parameters
    ----------
    model : HamiltonianRegressor
        Fitted with ``n_resamples > 0``.
    level : float, default=0.9
        The intervals' level: the ``(1 - level) / 2`` and ``(1 + level) / 2``
        percentiles.
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

    Raises
    ------
    ValueError
        If the model was fitted without resampling, or ``level`` is not in
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
    _check_resampled(model)
    resampled = model.resampled_coef_
    _check_level(level)
    readable = _Readable(model, state_names)
    coef = readable.from_fitting @ np.asarray(resampled).reshape(resampled.shape[0], -1).T
    kept = readable.kept(coef, rtol)
    main = {t.powers: t.coefficient for t in hamiltonian_terms(model, state_names=state_names,
                                                              rtol=rtol)}
    n = coef.shape[1]
    tail = 100 * (1 - level) / 2
    out = []
    for j in np.flatnonzero(readable.nonconstant & (kept.any(axis=1) | _listed(readable, main))):
        low, median, high = np.percentile(np.where(kept[j], coef[j], 0.0),
                                          [tail, 50, 100 - tail])
        powers = readable.powers(j)
        out.append(TermInterval(readable.text(j), powers, float(main.get(powers, 0.0)),
                                float(median), float(low), float(high), int(kept[j].sum()), n))
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
    """Where the resampled models go from ``x0``: the percentile band of their simulations.

    Every refit of :func:`resampled_models` is simulated from ``x0`` over
    ``t`` by RK4, in one batched loop, and the band is the percentile
    interval over them at each time; a refit whose trajectory becomes
    non-finite counts as missing from then on. The band shows where the
    learned dynamics would differ with another sample of trajectories; it
    does not contain a bias every sample shares.

    Parameters
    ----------
    model : HamiltonianRegressor or VectorFieldRegressor
        Fitted with ``n_resamples > 0``.
    x0 : array-like of shape (n_states,)
        The initial state.
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
        The band's edges and its median; NaN where fewer than half of the
        refits reached a time.

    Raises
    ------
    ValueError
        If the model was fitted without resampling, ``x0`` is not one
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
    from ._integrate.ensemble import simulate_ensemble
    from ._integrate.simulation import check_initial_states, check_max_step, check_time

    _check_resampled(model)
    _check_level(level)
    x0, single = check_initial_states(x0, model.n_features_in_)
    if not single:
        raise ValueError(f"x0 must be one state of shape ({model.n_features_in_},).")
    t = check_time(t)
    check_max_step(max_step)
    step = model._default_step("rk4") if max_step is None else max_step
    n = model.resampled_coef_.shape[0]
    wrap = model._space.wrap if model.periodic_.any() else None
    runs = simulate_ensemble(model._resampled_field(), np.repeat(x0, n, axis=0), t, step, wrap)
    reached = np.isfinite(runs).all(axis=2).sum(axis=0)
    tail = 100 * (1 - level) / 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # times no refit reached
        low, median, high = np.nanpercentile(runs, [tail, 50, 100 - tail], axis=0)
    missing = reached < (n + 1) // 2
    for edge in (low, median, high):
        edge[missing] = np.nan
    return low, median, high


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
            f"DerivativeTransformer output)."
        )


def to_sympy(model, *, state_names=None, rtol=1e-9):
    """The learned ``H~`` as a sympy expression in the user's coordinates.

    The terms of :func:`hamiltonian_terms` summed: monomials of the ordinary
    variables times ``cos``/``sin`` of the periodic ones, with float
    coefficients and without the constant. Needs sympy (the ``symbolic``
    extra: ``pip install "sk_hamiltonian[symbolic]"``); the package does not
    depend on it otherwise.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the symbols, as in :func:`hamiltonian_terms`.
    rtol : float, default=1e-9
        Terms smaller than this fraction of the largest are left out, as in
        :func:`hamiltonian_terms`.

    Returns
    -------
    expression : sympy.Expr
        ``H~`` up to its constant; its free symbols are named after the state
        variables.

    Raises
    ------
    ImportError
        If sympy is not installed, with the command that installs it.

    See Also
    --------
    hamiltonian_terms : The same terms as data.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.inspection import to_sympy
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform([-2, -np.pi], [2, np.pi], size=(300, 2))
    >>> y = np.column_stack([-9.8 * np.sin(X[:, 1]), X[:, 0]])  # H = p^2/2 - 9.8 cos q
    >>> model = HamiltonianRegressor(degree=4, periodic=[False, True], threshold=0.01)
    >>> to_sympy(model.fit(X, y)).evalf(4)
    0.5*p**2 - 9.8*cos(q)
    """
    try:
        import sympy
    except ImportError as error:
        raise ImportError(
            'to_sympy needs sympy: pip install "sk_hamiltonian[symbolic]" (or pip install sympy).'
        ) from error
    terms = hamiltonian_terms(model, state_names=state_names, rtol=rtol)
    state_names = _state_names(model, state_names)
    symbols = sympy.symbols(list(state_names), real=True)
    mixed = _mixed(model)
    omega = np.where(mixed, 2 * np.pi / MIXED_PERIOD,
                     2 * np.pi / (model.domain_[:, 1] - model.domain_[:, 0]))
    expression = sympy.Integer(0)
    for term in terms:
        factor = sympy.Float(term.coefficient)
        for i, power in enumerate(term.powers):
            if power == 0:
                continue
            if mixed[i] and power < 0:
                power = int(code_frequency(power))  # as the signed frequency of an angle
            elif not model.periodic_[i]:
                factor *= symbols[i] ** power
                continue
            frequency = abs(power) * omega[i]
            argument = (
                abs(power) * symbols[i] if np.isclose(omega[i], 1.0)
                else sympy.Float(frequency) * symbols[i]
            )
            factor *= sympy.cos(argument) if power > 0 else sympy.sin(argument)
        expression += factor
    return expression


def _mixed(model):
    """The model's mixed variables (none for a model fitted before they existed)."""
    mixed = getattr(model, "mixed_", None)
    return np.zeros(model.n_features_in_, dtype=bool) if mixed is None else np.asarray(mixed)
