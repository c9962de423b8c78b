"""Measures of how well a learned system reproduces a trajectory or conserves ``H~``.

The quantities of the paper's comparisons: the relative error of a solution
over time, the time at which a solution blows up, the deviation of a
Hamiltonian along a numerical solution (the norms of the paper's Table 1) and
observed convergence orders in the step size; and, to set a learned ``H~``
next to a known ``H``, the constant ``H~`` is missing (Theorem 3.5 of the
paper) and the range of ``H~`` over a domain, the scale for relative
deviations. Everything takes plain arrays (or a fitted
:class:`~sk_hamiltonian.HamiltonianRegressor` and a domain) and returns plain
numbers or arrays.
"""

import numbers

import numpy as np
from scipy.integrate import trapezoid
from sklearn.utils.validation import check_is_fitted

from ._state_order import swap_halves

__all__ = [
    "BLOWUP_BOUND",
    "blowup_time",
    "convergence_orders",
    "hamiltonian_deviation",
    "hamiltonian_offset",
    "hamiltonian_range",
    "mask_blowup",
    "relative_error",
]

#: Default bound of :func:`blowup_time`: a state with a component larger than
#: this in absolute value has blown up. Every domain of the paper's examples
#: lies within ``[-2 pi, 2 pi]`` in each variable, so ``10`` is far outside.
BLOWUP_BOUND = 10.0


def _check_trajectories(X, name):
    X = np.asarray(X, dtype=float)
    if X.ndim not in (2, 3) or X.shape[-1] < 1 or X.shape[-2] < 1:
        raise ValueError(
            f"{name} must have shape (n_times, n_states) or (n_trajectories, n_times, "
            f"n_states); got {X.shape}."
        )
    return X


def _check_bound(bound):
    if isinstance(bound, bool) or not isinstance(bound, numbers.Real) or not bound > 0:
        raise ValueError(f"bound must be a positive number; got {bound!r}.")
    return float(bound)


def _blown_up(X, bound):
    """Boolean (..., n_times): the state is non-finite or out of the bound."""
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(X).all(axis=-1) | (np.abs(X) > bound).any(axis=-1)
    # From the first bad time on, whatever the solution does afterwards.
    return np.logical_or.accumulate(bad, axis=-1)


def relative_error(X, X_true):
    """Relative error ``||X(t) - X_true(t)|| / ||X_true(t)||`` at every time.

    The error measure of the paper's figures: the Euclidean norm over the
    state variables, at each output time, relative to the norm of the true
    state.

    Parameters
    ----------
    X : array-like of shape (n_times, n_states) or (n_trajectories, n_times, n_states)
        Approximate solution(s), e.g. from
        :meth:`~sk_hamiltonian.HamiltonianRegressor.simulate`.
    X_true : array-like of the same shape as X
        Reference solution(s) at the same times.

    Returns
    -------
    error : ndarray of shape X.shape[:-1]
        The relative error at each time. It is NaN where ``X`` or ``X_true``
        is NaN: a failed or blown-up solution (``simulate(...,
        on_failure="nan")``, :func:`mask_blowup`) has no error from then on,
        and averages over such an error are NaN too.

    Raises
    ------
    ValueError
        If the shapes differ, or a finite true state is zero (no relative
        error exists there: compare absolute errors,
        ``numpy.linalg.norm(X - X_true, axis=-1)``, instead).

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.metrics import relative_error
    >>> relative_error([[0.0, 1.0], [3.0, 4.0]], [[0.0, 2.0], [3.0, 0.0]])
    array([0.5       , 1.33333333])
    """
    X = _check_trajectories(X, "X")
    X_true = _check_trajectories(X_true, "X_true")
    if X.shape != X_true.shape:
        raise ValueError(
            f"X and X_true must have the same shape; got {X.shape} and {X_true.shape}."
        )
    norms = np.linalg.norm(X_true, axis=-1)
    if np.any(norms == 0):
        where = np.argwhere(norms == 0)[0]
        raise ValueError(
            f"X_true is the zero state at index {tuple(int(i) for i in where)}, where no "
            f"relative error exists; compare absolute errors there, "
            f"numpy.linalg.norm(X - X_true, axis=-1)."
        )
    return np.linalg.norm(X - X_true, axis=-1) / norms


def blowup_time(t, X, *, bound=BLOWUP_BOUND):
    """First time at which a solution has blown up, or ``inf``.

    A solution has blown up at the first output time at which one of its
    state variables exceeds ``bound`` in absolute value or is not finite
    (``NaN`` from a failed simulation with ``on_failure="nan"`` counts).
    This is the one definition used by the examples and the results page.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Output times.
    X : array-like of shape (n_times, n_states) or (n_trajectories, n_times, n_states)
        Solution(s) at ``t``.
    bound : float, default=BLOWUP_BOUND
        Largest absolute value of a state variable that has not blown up
        (``10``). Choose it well outside the region of interest of the system.

    Returns
    -------
    time : float or ndarray of shape (n_trajectories,)
        The first time in ``t`` at which the solution has blown up; ``inf``
        for a solution that stays within the bound at every time. The
        resolution is that of ``t``.

    See Also
    --------
    mask_blowup : The solution with NaN from its blow-up on.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.metrics import blowup_time
    >>> t = np.linspace(0.0, 1.0, 11)
    >>> blowup_time(t, np.column_stack([np.zeros(11), np.exp(5 * t)]))  # e**2.5 > 10
    0.5
    >>> blowup_time(t, np.ones((11, 2)))
    inf
    """
    t = np.asarray(t, dtype=float)
    X = _check_trajectories(X, "X")
    bound = _check_bound(bound)
    if t.ndim != 1 or t.shape[0] != X.shape[-2]:
        raise ValueError(
            f"t must be 1-D with one time per row of X ({X.shape[-2]}); got shape {t.shape}."
        )
    bad = _blown_up(X, bound)
    first = np.argmax(bad, axis=-1)
    times = np.where(bad.any(axis=-1), t[first], np.inf)
    return float(times) if X.ndim == 2 else times


def mask_blowup(X, *, bound=BLOWUP_BOUND):
    """A copy of the solution(s) with NaN from the blow-up on.

    Parameters
    ----------
    X : array-like of shape (n_times, n_states) or (n_trajectories, n_times, n_states)
        Solution(s), e.g. from ``simulate(..., on_failure="nan")`` or
        :meth:`~sk_hamiltonian.datasets.HamiltonianSystem.solve`.
    bound : float, default=BLOWUP_BOUND
        As in :func:`blowup_time`.

    Returns
    -------
    X_masked : ndarray of the same shape as X
        ``X``, with every state from the first blown-up time on (see
        :func:`blowup_time`) set to NaN: plots stop there, and
        :func:`relative_error` is NaN there.

    See Also
    --------
    blowup_time : The definition of a blow-up.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.metrics import mask_blowup
    >>> mask_blowup(np.array([[1.0, 2.0], [30.0, 1.0], [1.0, 1.0]]))
    array([[ 1.,  2.],
           [nan, nan],
           [nan, nan]])
    """
    X = _check_trajectories(X, "X").copy()
    X[_blown_up(X, _check_bound(bound))] = np.nan
    return X


def hamiltonian_deviation(t, H):
    """Deviation ``dH(t) = H(t) - H(t[0])`` along a numerical solution, in three norms.

    For an exactly conserved Hamiltonian (the learned ``H~`` along a solution
    of the learned system) the deviation is the integrator's alone: the
    quantity of the paper's Table 1.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Strictly increasing times.
    H : array-like of shape (n_times,)
        The Hamiltonian along the solution, e.g.
        ``model.hamiltonian(model.simulate(x0, t))``.

    Returns
    -------
    norms : dict
        ``"linf"``: ``max_t |dH|``; ``"l2"``: ``(int dH**2 dt)**(1/2)`` over
        ``[t[0], t[-1]]`` by the trapezoid rule; ``"tv"``: the total
        variation, the sum of ``|dH(t[k + 1]) - dH(t[k])|`` over all steps.

    Raises
    ------
    ValueError
        If ``H`` is not finite (cut a failed or blown-up solution first, at
        :func:`blowup_time`) or the shapes do not match.

    See Also
    --------
    convergence_orders : Orders of these norms in the step size.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.metrics import hamiltonian_deviation
    >>> t = np.linspace(0.0, 1.0, 5)
    >>> hamiltonian_deviation(t, [1.0, 1.0, 1.5, 1.0, 1.0])
    {'linf': 0.5, 'l2': 0.25, 'tv': 1.0}
    """
    t = np.asarray(t, dtype=float)
    H = np.asarray(H, dtype=float)
    if t.ndim != 1 or H.shape != t.shape or t.shape[0] < 1:
        raise ValueError(
            f"t and H must be 1-D arrays of the same, non-zero length; got shapes "
            f"{t.shape} and {H.shape}."
        )
    if np.any(np.diff(t) <= 0):
        raise ValueError("t must be strictly increasing.")
    if not np.isfinite(H).all():
        raise ValueError(
            "H contains NaN or infinity: the solution failed or blew up. Keep the times "
            "before sk_hamiltonian.metrics.blowup_time(t, X) and evaluate H there."
        )
    dH = H - H[0]
    return {
        "linf": float(np.max(np.abs(dH))),
        "l2": float(np.sqrt(trapezoid(dH**2, t))),
        "tv": float(np.sum(np.abs(np.diff(dH)))),
    }


def convergence_orders(steps, errors):
    """Observed orders of convergence between consecutive step sizes.

    ``log(e_k / e_{k+1}) / log(h_k / h_{k+1})`` for steps ``h`` and errors
    ``e``: about ``p`` for a method of order ``p``, until the errors reach
    round-off.

    Parameters
    ----------
    steps : array-like of shape (n_steps,)
        Distinct positive step sizes, e.g. decreasing.
    errors : array-like of shape (n_steps,)
        The error at each step size (e.g. a norm from
        :func:`hamiltonian_deviation`).

    Returns
    -------
    orders : ndarray of shape (n_steps - 1,)
        The order between ``steps[k]`` and ``steps[k + 1]``.

    Raises
    ------
    ValueError
        If there are fewer than two steps, a step repeats, or a step or an
        error is not positive and finite (an error of exactly zero has no
        order: the method is exact there, to round-off).

    Examples
    --------
    >>> from sk_hamiltonian.metrics import convergence_orders
    >>> convergence_orders([0.1, 0.05, 0.025], [1e-4, 6.25e-6, 3.90625e-7])
    array([4., 4.])
    """
    steps = np.asarray(steps, dtype=float)
    errors = np.asarray(errors, dtype=float)
    if steps.ndim != 1 or errors.shape != steps.shape or steps.shape[0] < 2:
        raise ValueError(
            f"steps and errors must be 1-D arrays of the same length, at least 2; got "
            f"shapes {steps.shape} and {errors.shape}."
        )
    for name, values in (("steps", steps), ("errors", errors)):
        if not (np.isfinite(values).all() and (values > 0).all()):
            raise ValueError(
                f"{name} must be positive and finite; got {values.tolist()}. An error of "
                f"zero has no order (the method is exact there): drop that step."
            )
    if np.any(steps[1:] == steps[:-1]):
        raise ValueError(f"consecutive steps must differ; got {steps.tolist()}.")
    return np.log(errors[:-1] / errors[1:]) / np.log(steps[:-1] / steps[1:])


def _domain_sample(model, domain, n_samples, random_state):
    check_is_fitted(model, "domain_")
    # The sample goes to model.hamiltonian and to the user's function, which
    # both read the columns' order: domain_ is in the model's (p, q) order.
    swapped = getattr(model, "_swapped", lambda: False)()
    fitted = swap_halves(model.domain_, axis=0) if swapped else model.domain_
    domain = fitted if domain is None else np.asarray(domain, dtype=float)
    if domain.shape != (model.n_features_in_, 2) or not np.all(domain[:, 0] < domain[:, 1]):
        raise ValueError(
            f"domain must have shape ({model.n_features_in_}, 2), one (low, high) row per "
            f"state variable with low < high; got {domain.tolist()}."
        )
    if isinstance(n_samples, bool) or not isinstance(n_samples, numbers.Integral) or n_samples < 1:
        raise ValueError(f"n_samples must be a positive integer; got {n_samples!r}.")
    rng = np.random.default_rng(random_state)
    return rng.uniform(domain[:, 0], domain[:, 1], size=(n_samples, domain.shape[0]))


def hamiltonian_offset(model, hamiltonian, domain=None, *, n_samples=20_000, random_state=0):
    """The constant ``C`` that makes ``H~ + C`` comparable with a known ``H``.

    A Hamiltonian is only defined up to a constant. Theorem 3.5 of the paper
    compares ``H`` with ``H~ + C``, where ``C`` is the mean of ``H - H~`` over
    the domain under the uniform measure: the constant that brings ``H~``
    closest to ``H`` in ``L2`` of that measure. It is estimated here by
    Monte Carlo.

    Parameters
    ----------
    model : HamiltonianRegressor
        Fitted model.
    hamiltonian : callable
        The true Hamiltonian: ``hamiltonian(X) -> ndarray of shape
        (n_samples,)`` for states ``X`` of shape (n_samples, n_states), e.g.
        :meth:`~sk_hamiltonian.datasets.HamiltonianSystem.hamiltonian`.
    domain : array-like of shape (n_states, 2), default=None
        The box ``(low, high)`` per state variable; None uses the model's
        ``domain_``.
    n_samples : int, default=20_000
        Number of uniform samples.
    random_state : int, Generator or None, default=0
        Seed of the samples.

    Returns
    -------
    C : float
        The mean of ``H - H~`` over the samples.

    Raises
    ------
    ValueError
        If ``hamiltonian`` is not finite on the domain, or the domain is not
        a box of the model's dimension.

    See Also
    --------
    hamiltonian_range : The scale of ``H~`` on the domain.

    Examples
    --------
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories, henon_heiles
    >>> from sk_hamiltonian.metrics import hamiltonian_offset
    >>> system = henon_heiles()
    >>> X = make_trajectories(system, 200, 2, dt=0.01, domain=[[-0.9, 0.9]] * 4,
    ...                       random_state=0)
    >>> Xt = DerivativeTransformer(dt=0.01, method="finite_difference").fit_transform(X)
    >>> model = HamiltonianRegressor(degree=3, domain=system.domain).fit(Xt)
    >>> C = hamiltonian_offset(model, system.hamiltonian)
    >>> x = system.initial_state[None]
    >>> bool(abs(model.hamiltonian(x)[0] + C - system.hamiltonian(x)[0]) < 1e-3)
    True
    """
    X = _domain_sample(model, domain, n_samples, random_state)
    H = np.asarray(hamiltonian(X), dtype=float)
    if H.shape != (X.shape[0],) or not np.isfinite(H).all():
        raise ValueError(
            "hamiltonian(X) must return one finite value per state of X, of shape "
            f"({X.shape[0]},); got shape {H.shape}"
            + ("" if H.shape != (X.shape[0],) else " with NaN or infinity")
            + ". Pass the true Hamiltonian as a function of an (n_samples, n_states) array."
        )
    return float(np.mean(H - model.hamiltonian(X)))


def hamiltonian_range(model, domain=None, *, n_samples=20_000, random_state=0):
    """The range ``max H~ - min H~`` over a domain: the scale of ``H~``.

    ``H~`` is only defined up to a constant, so its value at a state is no
    scale for its deviations; its range over the domain is. The results page
    reports conservation as ``max_t |H~(t) - H~(0)|`` over this range.

    Parameters
    ----------
    model : HamiltonianRegressor
        Fitted model.
    domain : array-like of shape (n_states, 2), default=None
        The box ``(low, high)`` per state variable; None uses the model's
        ``domain_``.
    n_samples : int, default=20_000
        Number of uniform samples; the range is their range, slightly below
        the true one.
    random_state : int, Generator or None, default=0
        Seed of the samples.

    Returns
    -------
    scale : float
        ``max H~ - min H~`` over the samples.

    See Also
    --------
    hamiltonian_deviation : Deviations of ``H~`` along a solution.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.metrics import hamiltonian_range
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-1, 1, size=(200, 2))
    >>> dX = np.column_stack([-X[:, 1], X[:, 0]])  # H = (p**2 + q**2) / 2
    >>> model = HamiltonianRegressor(degree=2, domain=[[-1, 1], [-1, 1]]).fit(X, dX)
    >>> round(hamiltonian_range(model), 1)
    1.0
    """
    X = _domain_sample(model, domain, n_samples, random_state)
    return float(np.ptp(model.hamiltonian(X)))
