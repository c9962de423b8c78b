"""Small plotting helpers for learned and true trajectories (needs matplotlib).

Every function takes plain arrays and an optional matplotlib ``Axes``, draws on
it (or on a new figure) and returns the ``Axes``. matplotlib is imported only
when a function is called, so the package does not depend on it. Functions
that draw one panel per state variable take and return an array of ``Axes``.
NaN values (a failed or blown-up solution, see
:func:`sk_hamiltonian.metrics.mask_blowup`) leave gaps: the curves stop there.
"""

import numpy as np

__all__ = [
    "plot_energy",
    "plot_errors",
    "plot_phase",
    "plot_prediction_band",
    "plot_states",
    "plot_threshold_path",
    "plot_trajectories",
]


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
    return ax


def _state_names(n_states, state_names):
    if state_names is not None:
        if len(state_names) != n_states:
            raise ValueError(
                f"state_names must have one name per state variable ({n_states}); "
                f"got {len(state_names)}."
            )
        return list(state_names)
    d = n_states // 2
    if d == 1:
        return ["p", "q"]
    return [f"p{i + 1}" for i in range(d)] + [f"q{i + 1}" for i in range(d)]


def _check_curves(curves, n_times=None, what="curves"):
    if not isinstance(curves, dict) or not curves:
        raise ValueError(f"{what} must be a non-empty dict mapping labels to arrays.")
    out = {}
    for label, Y in curves.items():
        Y = np.asarray(Y, dtype=float)
        if n_times is not None and Y.shape[0] != n_times:
            raise ValueError(
                f"{what}[{label!r}] has {Y.shape[0]} times, but t has {n_times}."
            )
        out[label] = Y
    return out


def plot_trajectories(t, trajectories, *, state_names=None, ax=None):
    """Plot every state variable of one or several trajectories against time.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Times.
    trajectories : dict of str to array-like of shape (n_times, n_states)
        Labelled trajectories, e.g. ``{"true": U, "learned": V}``. The first
        one is drawn solid, the others dashed.
    state_names : list of str, default=None
        Names of the state variables; None uses ``p, q`` or ``p1.., q1..``.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.

    Returns
    -------
    ax : matplotlib Axes
        The Axes drawn on.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.plotting import plot_trajectories
    >>> t = np.linspace(0, 6, 50)
    >>> ax = plot_trajectories(t, {"true": np.column_stack([-np.sin(t), np.cos(t)])})
    """
    t = np.asarray(t, dtype=float)
    curves = _check_curves(trajectories, t.shape[0], "trajectories")
    ax = _axes(ax)
    n_states = next(iter(curves.values())).shape[1]
    names = _state_names(n_states, state_names)
    colors = [f"C{i}" for i in range(n_states)]
    for k, (label, Y) in enumerate(curves.items()):
        style = "-" if k == 0 else ("--", ":", "-.")[(k - 1) % 3]
        for i in range(n_states):
            ax.plot(t, Y[:, i], style, color=colors[i], lw=1.2,
                    label=f"{names[i]} ({label})")
    ax.set_xlabel("t")
    ax.legend(fontsize="small", ncol=max(1, len(curves)))
    return ax


def plot_phase(trajectories, *, pair=0, state_names=None, ax=None, scatter=None):
    """Phase portrait of one or several trajectories: ``(q_i, p_i)``, or any two states.

    Parameters
    ----------
    trajectories : dict of str to array-like of shape (n_times, n_states)
        Labelled trajectories.
    pair : int or tuple of (int, int), default=0
        An int ``i``: the degree of freedom ``i``, drawn as ``(q_i, p_i)``. A
        tuple ``(i, j)``: state variable ``j`` (vertical) against state
        variable ``i`` (horizontal), any two of ``p_1..p_d, q_1..q_d`` (in 4-D,
        ``(2, 1)`` draws ``p2`` against ``q1``).
    state_names : list of str, default=None
        Names of the state variables, for the axis labels.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.
    scatter : array-like of shape (n_points, n_states), default=None
        Points drawn faintly underneath, e.g. the training observations.

    Returns
    -------
    ax : matplotlib Axes
        The Axes drawn on.
    """
    curves = _check_curves(trajectories, what="trajectories")
    n_states = next(iter(curves.values())).shape[1]
    i, j = _phase_variables(pair, n_states)
    names = _state_names(n_states, state_names)
    ax = _axes(ax)
    if scatter is not None:
        S = np.asarray(scatter, dtype=float).reshape(-1, n_states)
        ax.plot(S[:, i], S[:, j], ".", color="0.8", ms=1, label="observations")
    for k, (label, Y) in enumerate(curves.items()):
        style = "-" if k == 0 else ("--", ":", "-.")[(k - 1) % 3]
        ax.plot(Y[:, i], Y[:, j], style, lw=1.2, label=label)
    ax.set_xlabel(names[i])
    ax.set_ylabel(names[j])
    ax.legend(fontsize="small")
    return ax


def _phase_variables(pair, n_states):
    """Horizontal and vertical state indices of a phase plot."""
    d = n_states // 2
    if isinstance(pair, (tuple, list)):
        if len(pair) == 2 and all(
            isinstance(k, (int, np.integer)) and not isinstance(k, bool) and 0 <= k < n_states
            for k in pair
        ):
            return int(pair[0]), int(pair[1])
        raise ValueError(
            f"pair as a tuple must be two state indices (i, j) in [0, {n_states - 1}]; "
            f"got {pair!r}."
        )
    if isinstance(pair, (int, np.integer)) and not isinstance(pair, bool) and 0 <= pair < d:
        return d + int(pair), int(pair)
    raise ValueError(
        f"pair must be a degree of freedom in [0, {d - 1}] or a tuple (i, j) of state "
        f"indices; got {pair!r}."
    )


def plot_energy(t, energies, *, deviation=True, ax=None):
    """Energy (or its deviation from the start) along trajectories.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Times.
    energies : dict of str to array-like of shape (n_times,)
        Labelled energies, e.g. ``{"RK4": H_rk4, "AVF": H_avf}``.
    deviation : bool, default=True
        Plot ``|H(t) - H(0)|`` on a logarithmic axis (values below 1e-17,
        exact conservation, are drawn at 1e-17); otherwise ``H(t)``.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.

    Returns
    -------
    ax : matplotlib Axes
        The Axes drawn on.
    """
    t = np.asarray(t, dtype=float)
    curves = _check_curves(energies, t.shape[0], "energies")
    ax = _axes(ax)
    for label, H in curves.items():
        if deviation:
            ax.semilogy(t, np.maximum(np.abs(H - H[0]), 1e-17), lw=1.2, label=label)
        else:
            ax.plot(t, H, lw=1.2, label=label)
    ax.set_xlabel("t")
    ax.set_ylabel("|H(t) - H(0)|" if deviation else "H(t)")
    ax.legend(fontsize="small")
    return ax


def plot_prediction_band(model, x0, t, *, level=0.9, state_names=None, ax=None,
                         max_step=None):
    """Shade where the resampled refits of a model go from ``x0``: a prediction band.

    The band of :func:`sk_hamiltonian.inspection.prediction_band`, one shaded
    region per state variable in the colours of :func:`plot_trajectories`
    (``C0``, ``C1``, ...), so that it sits under the model's own curves drawn
    there. Needs a model fitted with ``n_resamples > 0``.

    Parameters
    ----------
    model : HamiltonianRegressor or VectorFieldRegressor
        Fitted with ``n_resamples > 0``.
    x0 : array-like of shape (n_states,)
        The initial state.
    t : array-like of shape (n_times,)
        Output times.
    level : float, default=0.9
        The band's level.
    state_names : list of str, default=None
        Names of the state variables, for the legend.
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.
    max_step : float, default=None
        Largest RK4 step, as in :func:`~sk_hamiltonian.inspection.prediction_band`.

    Returns
    -------
    ax : matplotlib Axes
        The Axes drawn on.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories, single_pendulum
    >>> from sk_hamiltonian.plotting import plot_prediction_band, plot_trajectories
    >>> X = make_trajectories(single_pendulum(), 40, 20, 0.05, noise=0.01, random_state=0)
    >>> Xt = DerivativeTransformer(dt=0.05).fit_transform(X)
    >>> model = HamiltonianRegressor(4, periodic=[False, True], threshold=0.03,
    ...                              n_resamples=30, random_state=0).fit(Xt)
    >>> t = np.linspace(0, 5, 101)
    >>> ax = plot_trajectories(t, {"learned": model.simulate([0.0, 1.0], t)})
    >>> ax = plot_prediction_band(model, [0.0, 1.0], t, ax=ax)
    """
    from .inspection import prediction_band

    t = np.asarray(t, dtype=float)
    low, _, high = prediction_band(model, x0, t, level=level, max_step=max_step)
    ax = _axes(ax)
    names = _state_names(low.shape[1], state_names)
    n = model.resampled_coef_.shape[0]
    for i, name in enumerate(names):
        ax.fill_between(t, low[:, i], high[:, i], color=f"C{i}", alpha=0.25, lw=0,
                        label=f"{name} ({level:.0%} band of {n} refits)")
    ax.set_xlabel("t")
    ax.legend(fontsize="small")
    return ax


def plot_errors(t, errors, *, ax=None):
    """Relative errors over time, on a logarithmic axis.

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Times.
    errors : dict of str to array-like of shape (n_times,)
        Labelled errors, e.g. from :func:`sk_hamiltonian.metrics.relative_error`.
        A curve stops where its error is NaN (its solution blew up).
    ax : matplotlib Axes, default=None
        Where to draw; None creates a figure.

    Returns
    -------
    ax : matplotlib Axes
        The Axes drawn on.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.plotting import plot_errors
    >>> t = np.linspace(0, 10, 50)
    >>> ax = plot_errors(t, {"SP": 1e-3 * (1 + t), "non-SP": 1e-3 * (1 + t) ** 2})
    >>> ax.get_yscale()
    'log'
    """
    t = np.asarray(t, dtype=float)
    curves = _check_curves(errors, t.shape[0], "errors")
    for label, e in curves.items():
        if e.ndim != 1:
            raise ValueError(
                f"errors[{label!r}] must be 1-D, one error per time; got shape {e.shape}."
            )
    ax = _axes(ax)
    for label, e in curves.items():
        ax.semilogy(t, e, lw=1.2, label=label)
    ax.set_xlabel("t")
    ax.set_ylabel("relative error")
    ax.legend(fontsize="small")
    return ax


def plot_states(t, trajectories, *, state_names=None, n_markers=120, axes=None):
    """One panel per state variable: a reference solution and others over time.

    The first trajectory, the reference (e.g. the true solution), is drawn as
    a thin black line; the others as coloured lines carrying about
    ``n_markers`` open circles, so that the reference stays visible under
    them (the style of the paper's figures).

    Parameters
    ----------
    t : array-like of shape (n_times,)
        Times.
    trajectories : dict of str to array-like of shape (n_times, n_states)
        Labelled trajectories, the reference first, e.g.
        ``{"exact": U, "SP": V}``.
    state_names : list of str, default=None
        Names of the state variables; None uses ``p, q`` or ``p1.., q1..``.
    n_markers : int, default=120
        Approximate number of circles on each non-reference curve; 0 draws
        none.
    axes : array-like of matplotlib Axes, default=None
        One Axes per state variable, in the order ``p_1..p_d, q_1..q_d``;
        None creates a figure with the ``p`` panels in the top row and the
        ``q`` panels below them.

    Returns
    -------
    axes : ndarray of matplotlib Axes, of shape (n_states,)
        The panels, in the order of the state variables.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.plotting import plot_states
    >>> t = np.linspace(0, 6, 60)
    >>> exact = np.column_stack([-np.sin(t), np.cos(t)])
    >>> axes = plot_states(t, {"exact": exact, "learned": 1.01 * exact})
    >>> [ax.get_ylabel() for ax in axes]
    ['p', 'q']
    """
    t = np.asarray(t, dtype=float)
    curves = _check_curves(trajectories, t.shape[0], "trajectories")
    n_states = next(iter(curves.values())).shape[1]
    names = _state_names(n_states, state_names)
    if (isinstance(n_markers, bool) or not isinstance(n_markers, (int, np.integer))
            or n_markers < 0):
        raise ValueError(f"n_markers must be a non-negative integer; got {n_markers!r}.")
    if axes is None:
        import matplotlib.pyplot as plt

        d = max(1, n_states // 2)
        _, grid = plt.subplots(2, d, figsize=(max(9.0, 4.8 * d), 5.5), squeeze=False)
        # Row 0 holds p_1..p_d and row 1 q_1..q_d, matching the state order.
        axes = grid.ravel()
    axes = np.asarray(axes, dtype=object).ravel()
    if axes.shape[0] != n_states:
        raise ValueError(
            f"axes must hold one Axes per state variable ({n_states}); got {axes.shape[0]}."
        )
    every = max(1, t.shape[0] // n_markers) if n_markers else None
    for i, ax in enumerate(axes):
        for k, (label, Y) in enumerate(curves.items()):
            if k == 0:
                ax.plot(t, Y[:, i], "k-", lw=1, label=label)
            else:
                ax.plot(t, Y[:, i], "-o" if every else "-", lw=0.8, ms=3, mfc="none",
                        markevery=every, color=f"C{k - 1}", label=label)
        ax.set_xlabel("t")
        ax.set_ylabel(names[i])
    axes[0].legend(fontsize="small")
    return axes


def plot_threshold_path(path, *, ax=None):
    """Plot cross-validated score against model size along a threshold path.

    Each threshold is a point at its number of terms (logarithmic axis) with
    its mean score and one standard error as a bar; the thresholds that tie
    with the best (within one standard error) are filled, the others hollow,
    and each point is labelled with its threshold.

    Parameters
    ----------
    path : sklearn.utils.Bunch
        The output of :func:`sk_hamiltonian.model_selection.threshold_path`.
    ax : matplotlib.axes.Axes, default=None
        Where to draw; None makes a new figure.

    Returns
    -------
    ax : matplotlib.axes.Axes
        The axes drawn on.

    See Also
    --------
    sk_hamiltonian.model_selection.threshold_path : Computes the path.
    """
    missing = [key for key in ("thresholds", "n_terms", "mean_score", "std_error", "tied")
               if key not in path]
    if missing:
        raise ValueError(
            f"path must be the output of model_selection.threshold_path; it lacks "
            f"{', '.join(missing)}."
        )
    ax = _axes(ax)
    terms = np.asarray(path["n_terms"], dtype=float)
    mean, error = np.asarray(path["mean_score"]), np.asarray(path["std_error"])
    tied = np.asarray(path["tied"], dtype=bool)
    ax.errorbar(terms, mean, yerr=error, fmt="none", ecolor="0.5", capsize=3)
    ax.plot(terms[tied], mean[tied], "o", color="C0", label="within one standard error of the best")
    ax.plot(terms[~tied], mean[~tied], "o", mfc="none", color="C0", label="worse")
    for x, y, value in zip(terms, mean, path["thresholds"]):
        ax.annotate(f"{value:g}", (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("terms of the model")
    ax.set_ylabel("cross-validated score")
    ax.legend(loc="best", fontsize=8)
    return ax
