"""The trajectory data model and the layout that carries time derivatives.

Trajectories are a 3-D array ``(n_trajectories, n_times, n_states)`` or a list
of 2-D arrays ``(n_times_k, n_states)``; one sample is one trajectory, so every
scikit-learn splitter splits whole trajectories. ``n_states = 2d`` is even and
ordered as ``(p_1..p_d, q_1..q_d)``.

:class:`~sk_hamiltonian.DerivativeTransformer` returns the same container with a
wider last axis, the *derivative layout*::

    [ t | states (n_states) | time derivatives (n_states) | observed (n_states) ]

``states`` are what the regressor is fitted on (the smoothed states when
de-noising, the observations otherwise); ``observed`` are the raw observations
and ``t`` their time stamps, which the regressors' ``score`` compares rollouts
against. Carrying them through the pipeline keeps the default cross-validation
score independent of the derivative estimate being tuned.
"""

from collections import namedtuple

import numpy as np

DerivativeData = namedtuple("DerivativeData", ["times", "states", "derivatives", "observed"])
DerivativeData.__doc__ = """Fields of the derivative layout.

Each field is a 3-D array (or a list of 2-D arrays, one per trajectory, when the
layout was a list); ``times`` has a last axis of length 1 dropped, so it is 2-D
(or a list of 1-D arrays).
"""


def layout_width(n_states):
    """Width of the last axis of the derivative layout."""
    return 1 + 3 * n_states


def check_time_stamps(trajectories):
    """Raise unless each trajectory's first column (its time stamps) is finite and increases.

    Parameters
    ----------
    trajectories : list of ndarray of shape (n_times_k, 1 + n_states)

    Raises
    ------
    ValueError
        Naming the first trajectory and sample where time is not finite or does
        not strictly increase.
    """
    for k, T in enumerate(trajectories):
        t = T[:, 0]
        if not np.isfinite(t).all():
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise ValueError(
                f"X[{k}]: the time stamps (first column, as dt=None) must be finite; sample "
                f"{i} has t={float(t[i])!r}. Drop that sample, or give its time."
            )
        steps = np.diff(t)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            raise ValueError(
                f"X[{k}]: the time stamps (first column, as dt=None) must be strictly "
                f"increasing; sample {i + 1} has t={float(t[i + 1])!r} after "
                f"t={float(t[i])!r}. Sort the samples and drop repeated times."
            )


def check_trajectories(X, *, name="X", min_times=1, allow_missing=False):
    """Validate trajectories and return them as a list of float arrays.

    Parameters
    ----------
    X : array-like of shape (n_trajectories, n_times, n_features) or list of 2-D arrays
        The trajectories.
    name : str, default="X"
        Argument name used in error messages.
    min_times : int, default=1
        Fewest samples a trajectory may have.
    allow_missing : bool, default=False
        Whether NaN or infinite values may stand (missing readings, which the
        caller leaves out); False raises a ValueError naming the trajectory.

    Returns
    -------
    trajectories : list of ndarray of shape (n_times_k, n_features)
    is_array : bool
        Whether ``X`` was a single 3-D array (rather than a list).
    """
    if hasattr(X, "tocsr") or hasattr(X, "toarray"):
        raise TypeError(
            f"{name} is a sparse matrix; trajectories must be dense arrays of shape "
            f"(n_trajectories, n_times, n_features)."
        )
    if isinstance(X, np.ndarray) or not isinstance(X, (list, tuple)):
        array = np.asarray(X)
        if array.ndim != 3:
            hint = (
                " If these are one trajectory T of shape (n_times, n_features), pass "
                "T[np.newaxis] or [T]; if they are states at which to evaluate a fitted "
                "pipeline's learned vector field, call its last step directly, "
                "pipe[-1].predict(states) (the pipeline's first step expects "
                "trajectories)." if array.ndim == 2 else ""
            )
            raise ValueError(
                f"{name} must be a 3-D array (n_trajectories, n_times, n_features) "
                f"or a list of 2-D arrays (n_times, n_features); got an array of shape "
                f"{array.shape}.{hint}"
            )
        trajectories, is_array = list(_as_float(array, name)), True
    else:
        trajectories, is_array = [], False
        for k, item in enumerate(X):
            item = _as_float(np.asarray(item), f"{name}[{k}]")
            if item.ndim != 2:
                raise ValueError(
                    f"{name}[{k}] must be a 2-D array (n_times, n_features); got shape "
                    f"{item.shape}."
                )
            trajectories.append(item)
    if not trajectories:
        raise ValueError(f"{name} holds no trajectory; at least one is required.")
    widths = {T.shape[1] for T in trajectories}
    if len(widths) > 1:
        transposed = _transposed_hint(name, trajectories, is_array, min_times)
        raise ValueError(transposed or (
            f"The trajectories in {name} have different numbers of features "
            f"{sorted(widths)}; all must have the same."
        ))
    lengths = [T.shape[0] for T in trajectories]
    shortest = int(np.argmin(lengths))
    if lengths[shortest] < min_times:
        transposed = _transposed_hint(name, trajectories, is_array, min_times)
        if transposed:
            raise ValueError(transposed)
        which = f"{name}[{shortest}]" if not is_array else f"Every trajectory in {name}"
        raise ValueError(
            f"{which} has {lengths[shortest]} sample(s); at least {min_times} are required."
        )
    for k, T in enumerate(trajectories):
        if not allow_missing and not np.isfinite(T).all():
            raise ValueError(
                f"{name}[{k}] contains NaN or infinity; remove or interpolate those "
                f"samples first (HamiltonianSearchCV's fit leaves them out itself)."
            )
    return trajectories, is_array


def _transposed_hint(name, trajectories, is_array, min_times):
    """A one-line message for trajectories given as (n_states, n_times), or None.

    They look so when every one has fewer samples than variables, too few
    samples for the fit, and as many (even) rows as the others: the time
    axis is then the long one.
    """
    rows = {T.shape[0] for T in trajectories}
    n_rows, n_columns = trajectories[0].shape
    if not (len(rows) == 1 and n_rows % 2 == 0 and n_rows < min_times
            and all(T.shape[1] >= max(min_times, n_rows + 1) for T in trajectories)):
        return None
    if is_array:
        n = len(trajectories)
        return (
            f"{name} has shape ({n}, {n_rows}, {n_columns}): {n_rows} samples of {n_columns} "
            f"variables per trajectory, which looks transposed; trajectories are "
            f"(n_trajectories, n_times, n_states): pass {name}.transpose(0, 2, 1), of shape "
            f"({n}, {n_columns}, {n_rows})."
        )
    fewest = min(T.shape[1] for T in trajectories)
    columns = f"{fewest}" if fewest == max(T.shape[1] for T in trajectories) else f"{fewest}+"
    return (
        f"Each trajectory in {name} has {n_rows} rows and {columns} columns, which looks "
        f"transposed; each must be (n_times, n_states): pass [T.T for T in {name}]."
    )


def check_n_states(n_states, name="X"):
    """Raise if a state dimension is not even and positive."""
    if n_states < 2 or n_states % 2:
        raise ValueError(
            f"{name} has {n_states} feature(s), but the states of a Hamiltonian "
            f"system come in pairs (p_1..p_d, q_1..q_d): the number of state "
            f"variables must be even. Check the last axis of {name}."
        )


def _as_float(array, name):
    if array.dtype == object or not (
        np.issubdtype(array.dtype, np.number) or array.dtype == bool
    ):
        raise ValueError(f"{name} must be numeric; got dtype {array.dtype}.")
    if np.iscomplexobj(array):
        raise ValueError(f"{name} must be real; got complex values.")
    return array.astype(float, copy=False)


def pack_derivatives(times, states, derivatives, observed, as_array):
    """Assemble the derivative layout from per-trajectory pieces."""
    packed = [
        np.column_stack([t, s, d, o])
        for t, s, d, o in zip(times, states, derivatives, observed)
    ]
    return np.stack(packed) if as_array else packed


def is_trajectory_container(X):
    """Whether ``X`` is a 3-D array or a list of 2-D arrays (trajectories)."""
    if hasattr(X, "ndim") and not hasattr(X, "columns"):
        return X.ndim == 3
    if isinstance(X, (list, tuple)) and len(X) > 0:
        return np.ndim(X[0]) == 2
    return False


def unpack_derivatives(Xt):
    """Split the output of :class:`~sk_hamiltonian.DerivativeTransformer`.

    Parameters
    ----------
    Xt : ndarray of shape (n_trajectories, n_times, 1 + 3 * n_states) or list
        The derivative layout.

    Returns
    -------
    data : DerivativeData
        Named tuple ``(times, states, derivatives, observed)`` holding arrays of
        shapes ``(n_trajectories, n_times)`` and ``(n_trajectories, n_times,
        n_states)`` (lists of per-trajectory arrays when ``Xt`` is a list).

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import DerivativeTransformer, unpack_derivatives
    >>> X = np.random.default_rng(0).normal(size=(3, 10, 2))
    >>> Xt = DerivativeTransformer(dt=0.1, method="finite_difference").fit_transform(X)
    >>> unpack_derivatives(Xt).derivatives.shape
    (3, 10, 2)
    """
    trajectories, is_array = check_trajectories(Xt, name="Xt")
    width = trajectories[0].shape[1]
    n_states, remainder = divmod(width - 1, 3)
    if remainder or n_states < 2 or n_states % 2:
        hint = (
            " It looks like raw trajectories: pass them through "
            "DerivativeTransformer first, or fit on 2-D states X with their time "
            "derivatives y."
            if width % 2 == 0
            else ""
        )
        raise ValueError(
            f"Expected the derivative layout of DerivativeTransformer, whose last "
            f"axis has 1 + 3 * n_states entries [t, states, derivatives, observed] "
            f"with n_states even; got {width}.{hint}"
        )
    s = slice(1, 1 + n_states)
    d = slice(1 + n_states, 1 + 2 * n_states)
    o = slice(1 + 2 * n_states, width)
    if is_array:
        A = np.stack(trajectories)
        return DerivativeData(A[..., 0], A[..., s], A[..., d], A[..., o])
    return DerivativeData(
        [T[:, 0] for T in trajectories],
        [T[:, s] for T in trajectories],
        [T[:, d] for T in trajectories],
        [T[:, o] for T in trajectories],
    )
