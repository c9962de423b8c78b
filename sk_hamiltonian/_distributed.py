"""``fit`` on dask arrays: normal equations built on the workers and reduced.

A regressor's ``fit`` hands dask arrays here (optional extra ``distributed``).
Each chunk of rows (of states and derivatives, or of whole trajectories in the
derivative layout) becomes, on a worker, the same summary ``partial_fit``
keeps (:class:`~sk_hamiltonian._streaming.PartialFitState`: the chunk's
normal equations and running statistics); the summaries are added pairwise in
a tree, so the client receives one ``n_terms x n_terms`` matrix. The solve is
the ``"normal"`` solver's: Cholesky, refined against the design with one more
distributed pass per step, so the coefficients are those of an in-memory fit.

Only the rows' chunking matters: a chunk of the derivative layout is rechunked
to hold whole trajectories (all times and all columns).
"""

import warnings

import numpy as np

from . import _fit_steps as steps
from ._space.space import outside_domain
from ._streaming import PartialFitState, ShapeOnly
from .exceptions import DomainWarning


def is_dask(X):
    """Whether ``X`` is a dask collection (without importing dask)."""
    return type(X).__module__.split(".")[0] == "dask" and hasattr(X, "__dask_graph__")


class _Counted:
    """A chunk's data as ``_check_size`` sees it, with the total number of rows."""

    def __init__(self, data, n_rows):
        self.states, self.derivatives = data.states, data.derivatives
        self._n_rows = n_rows

    def n_rows(self, fit_on):
        return self._n_rows


class _Box:
    """Training data as the model space's builder sees them: two states spanning the box."""

    def __init__(self, states):
        self.states, self.sample_weight = states, None


def _chunk_state(estimator, design, X, y, weight):
    """On a worker: the normal equations and statistics of one chunk."""
    data = estimator._training_data(X, y, weight, reset=False)
    state = PartialFitState(estimator, design.accumulator(), data.states.shape[1])
    state.add(design, data, data.median_step())
    return state


def _merge(a, b):
    return a.merge(b)


def _chunk_rows(estimator, X, y, weight):
    """On a worker: how many row groups (states or steps) a chunk gives."""
    return estimator._training_data(X, y, weight, reset=False).n_rows(estimator.fit_on)


def _chunk_residual(estimator, design, X, y, weight, coef, keep):
    """On a worker: ``A_k^T (b_k - A_k coef)`` of one chunk, restricted to ``keep``."""
    data = estimator._training_data(X, y, weight, reset=False)
    operator = design.operator(data)
    full = np.zeros((keep.size,) + coef.shape[1:])
    full[keep] = coef
    r = operator.targets - operator.matvec(full if full.ndim == 2 else full[:, None])
    out = operator.rmatvec(r)[keep]
    return out if coef.ndim == 2 else out[:, 0]


def _tree_sum(parts, add):
    """Pairwise reduction of delayed objects (log depth, one result on the client)."""
    import dask

    while len(parts) > 1:
        paired = [dask.delayed(add)(a, b) for a, b in zip(parts[::2], parts[1::2])]
        parts = paired + ([parts[-1]] if len(parts) % 2 else [])
    return parts[0]


def fit_distributed(estimator, X, y=None, sample_weight=None):
    """Fit ``estimator`` on dask arrays; see the module docstring.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        With its parameters validated.
    X : dask.array.Array
        States of shape (n_samples, n_states) with ``y``, or the derivative
        layout of shape (n_trajectories, n_times, 1 + 3 * n_states).
    y : dask.array.Array or array-like or None
        Time derivatives of the states; None with the derivative layout.
    sample_weight : dask.array.Array or array-like or None
        Weights of the states (of the trajectories for the layout).

    Returns
    -------
    estimator : BaseTrajectoryRegressor
        Fitted.
    """
    import dask
    import dask.array as da

    # A fit starts over: no earlier partial_fit state travels to the workers.
    estimator._partial = None
    X = da.asarray(X)
    layout = y is None
    if layout:
        if X.ndim != 3:
            raise ValueError(
                f"A dask X without y must be the derivative layout, a 3-D array "
                f"(n_trajectories, n_times, 1 + 3 * n_states); got {X.ndim} dimensions. "
                f"Pass y with 2-D states, or transform the trajectories first."
            )
        # Whole trajectories per chunk: the steps fit and the layout need them.
        X = X.rechunk({1: -1, 2: -1})
        n_states = (X.shape[-1] - 1) // 3
        states = X[..., 1 : 1 + n_states]
    else:
        y = da.asarray(y)
        if y.shape[0] != X.shape[0]:
            raise ValueError(
                f"X and y have different numbers of samples: {X.shape[0]} and {y.shape[0]}."
            )
        X = X.rechunk({1: -1})
        y = y.rechunk((X.chunks[0],) + ((-1,) if y.ndim == 2 else ()))
        states = X
    rows = X.chunks[0]
    weights = [None] * len(rows)
    if sample_weight is not None:
        w = da.asarray(sample_weight).rechunk((rows,))
        weights = list(w.to_delayed().ravel())
    X_blocks = list(X.to_delayed().ravel())
    y_blocks = [None] * len(rows) if layout else list(y.to_delayed().ravel())

    # Set the estimator up from the first chunk (validation, n_features_in_),
    # with the domain and the size check over all chunks.
    first_X, first_y, first_w = dask.compute(X_blocks[0], y_blocks[0], weights[0])
    data = estimator._training_data(first_X, first_y, first_w)
    n_states = data.states.shape[1]
    flat = states.reshape(-1, n_states)
    if estimator.domain is None:
        if sample_weight is not None:
            positive = da.asarray(sample_weight).rechunk((rows,)) > 0
            if layout:
                positive = da.repeat(positive, X.shape[1])
            flat = flat[positive.rechunk((flat.chunks[0],))]
        box = np.vstack(dask.compute(flat.min(axis=0), flat.max(axis=0)))
    else:
        # The explicit box is checked on its centre (inside it); the states
        # outside are counted over all chunks below.
        explicit = np.asarray(estimator.domain, dtype=float)
        centre = explicit.mean(axis=1) if explicit.ndim == 2 else np.zeros(n_states)
        box = np.vstack([centre, centre])
    # The size check needs the rows of every chunk: after the box.
    space = steps.build_space(estimator, _Box(box), size_data=ShapeOnly(data))
    if estimator.domain is not None:
        outside = flat.map_blocks(
            lambda S: outside_domain(S, space.domain, space.periodic)[:, None],
            chunks=(flat.chunks[0], (1,)), dtype=bool,
        )
        fraction = float(outside.mean().compute())
        if fraction > 0:
            warnings.warn(
                f"{fraction:.1%} of the training states lie outside the domain "
                f"{space.domain.tolist()}, where the model is not trusted.",
                DomainWarning, stacklevel=4,
            )
    template = dask.delayed(estimator, pure=True)
    n_rows = sum(dask.compute(*[
        dask.delayed(_chunk_rows)(template, Xb, yb, wb)
        for Xb, yb, wb in zip(X_blocks, y_blocks, weights)
    ]))
    estimator._check_size(_Counted(data, n_rows))
    design = dask.delayed(estimator._design(space), pure=True)
    parts = [
        dask.delayed(_chunk_state)(template, design, Xb, yb, wb)
        for Xb, yb, wb in zip(X_blocks, y_blocks, weights)
    ]
    state = _tree_sum(parts, _merge).compute()

    def residual(keep):
        def refine(coef):
            terms = [
                dask.delayed(_chunk_residual)(template, design, Xb, yb, wb, coef, keep)
                for Xb, yb, wb in zip(X_blocks, y_blocks, weights)
            ]
            return _tree_sum(terms, np.add).compute()

        return refine

    solution = steps.solve_normal_equations(estimator, space, state.normal_equations(), residual)
    return steps.set_fitted(estimator, space, solution, data, solver="normal", statistics=state)
