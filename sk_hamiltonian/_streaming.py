"""``partial_fit``: what it keeps between calls (the normal equations, a few running statistics), and one call.

Everything here has a size fixed by the model space (``n_columns**2`` for the
normal matrix) and the number of state variables, never by the number of
samples seen, so fitting a long stream of chunks runs in constant memory.
"""

from functools import update_wrapper, wraps
from types import MethodType

import numpy as np

from . import _fit_steps as steps


# Model-space parameters that must not change between partial_fit calls.
SPACE_PARAMETERS = (
    "degree", "domain", "periodic", "momentum_degree", "separable", "max_interaction",
    "couplings", "fit_on", "damping",
)
# States kept (uniformly at random over everything seen) for the time scale.
RESERVOIR_SIZE = 256


def _same(a, b):
    if a is None or b is None:
        return a is b
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b


def check_partial_fit(estimator):
    """Raise the ``AttributeError`` that says why ``estimator`` has no ``partial_fit``: no domain."""
    # partial_fit exists only with a fixed box: the basis (and so the
    # accumulated normal equations) lives on it.
    if estimator.domain is None:
        raise AttributeError(
            f"{type(estimator).__name__}.partial_fit needs an explicit `domain` (one "
            f"(low, high) row per state variable): the basis must stay on the same box for "
            f"every chunk, and without a domain it would be each chunk's bounding box. "
            f"Pass domain=..., e.g. a box around all the data to come, or use fit."
        )


class available_with_domain:  # noqa: N801 -- a decorator, named as one
    """``partial_fit`` where the estimator has a ``domain``; elsewhere the reason, as the error.

    Like :func:`sklearn.utils.metaestimators.available_if` (``hasattr(est,
    "partial_fit")`` is False without a domain, so scikit-learn's checks and
    meta-estimators see no ``partial_fit``), but the ``AttributeError`` the
    user sees is :func:`check_partial_fit`'s own, which names the fix,
    rather than "has no attribute 'partial_fit'" with the reason chained
    below it.
    """

    def __init__(self, fn):
        self.fn = fn
        update_wrapper(self, fn)

    def __get__(self, obj, owner=None):
        if obj is not None:
            check_partial_fit(obj)
            return MethodType(self.fn, obj)

        # From the class (documentation, an unbound call): checked at the call.
        @wraps(self.fn)
        def unbound(*args, **kwargs):
            check_partial_fit(args[0])
            return self.fn(*args, **kwargs)

        return unbound


class PartialFitState:
    """Normal equations and running statistics accumulated over ``partial_fit`` calls.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        Whose model-space parameters are recorded.
    accumulator : NormalEquations or FactoredNormalEquations
        An empty accumulator of the design's normal equations
        (:meth:`~sk_hamiltonian._least_squares.Design.accumulator`).
    n_states : int
        State variables.
    """

    def __init__(self, estimator, accumulator, n_states):
        params = estimator.get_params()
        self.parameters = {
            name: np.array(params[name], copy=True) if isinstance(params[name], np.ndarray)
            else params[name]
            for name in SPACE_PARAMETERS if name in params
        }
        self.accumulator = accumulator
        self.n_samples = 0
        self.mean = np.zeros(n_states)
        self.m2 = np.zeros(n_states)
        self.mean_square = np.zeros(n_states)
        self.reservoir = np.empty((0, n_states))
        self._rng = np.random.default_rng(0)
        self.steps = []  # (median step, number of steps) per chunk with trajectories

    def check_parameters(self, estimator):
        """Raise if a model-space parameter changed since the first call."""
        params = estimator.get_params()
        for name, first in self.parameters.items():
            if not _same(first, params[name]):
                raise ValueError(
                    f"partial_fit: `{name}` changed from {first!r} to {params[name]!r} since "
                    f"the first call, but the accumulated normal equations belong to the "
                    f"first model space. Keep the model-space parameters fixed between "
                    f"partial_fit calls, or start over with fit (or a clone)."
                )

    def add(self, design, data, step):
        """Accumulate one chunk: its normal equations (by ``design``), states and training step."""
        design.accumulate(data, accumulator=self.accumulator)
        states = data.states
        n = states.shape[0]
        # Chan et al.'s parallel update of the mean and sum of squared deviations.
        chunk_mean = states.mean(axis=0)
        chunk_m2 = ((states - chunk_mean) ** 2).sum(axis=0)
        total = self.n_samples + n
        delta = chunk_mean - self.mean
        self.m2 += chunk_m2 + delta**2 * self.n_samples * n / total
        self.mean += delta * n / total
        self.mean_square += ((states**2).sum(axis=0) - n * self.mean_square) / total
        self.n_samples = total
        self._sample(states)
        if np.isfinite(step):
            self.steps.append((step, data.n_rows("steps")))

    def _sample(self, states):
        """Reservoir sampling (algorithm R) of all states seen, vectorized per chunk."""
        seen = self.n_samples - states.shape[0]
        room = max(0, RESERVOIR_SIZE - self.reservoir.shape[0])
        self.reservoir = np.vstack([self.reservoir, states[:room]])
        rest = states[room:]
        if rest.shape[0]:
            index = np.arange(seen + room, seen + room + rest.shape[0])
            slots = (self._rng.random(rest.shape[0]) * (index + 1)).astype(np.intp)
            chosen = slots < RESERVOIR_SIZE
            # In order, so that a later state replaces an earlier one in the same slot.
            self.reservoir[slots[chosen]] = rest[chosen]

    def merge(self, other):
        """Add another state built over different samples (e.g. on another worker)."""
        self.accumulator += other.accumulator
        n, total = other.n_samples, self.n_samples + other.n_samples
        if n:
            delta = other.mean - self.mean
            self.m2 += other.m2 + delta**2 * self.n_samples * n / total
            self.mean += delta * n / total
            self.mean_square += (other.mean_square - self.mean_square) * n / total
            # Keep each reservoir's share in proportion to the samples it stands for.
            pooled = np.vstack([self.reservoir, other.reservoir])
            if pooled.shape[0] > RESERVOIR_SIZE:
                share = np.r_[
                    np.full(self.reservoir.shape[0], self.n_samples / max(1, self.reservoir.shape[0])),
                    np.full(other.reservoir.shape[0], n / max(1, other.reservoir.shape[0])),
                ]
                keep = self._rng.choice(
                    pooled.shape[0], RESERVOIR_SIZE, replace=False, p=share / share.sum()
                )
                pooled = pooled[np.sort(keep)]
            self.reservoir = pooled
            self.n_samples = total
        self.steps += other.steps
        return self

    def normal_equations(self):
        """The accumulated ``(A^T A, A^T b, b^T b)``."""
        return (*self.accumulator.result(), self.accumulator.btb)

    def scale(self):
        """Standard deviation of every state variable over all samples seen (1 where zero)."""
        std = np.sqrt(self.m2 / max(1, self.n_samples))
        return np.where(std > 0, std, 1.0)

    def magnitude(self):
        """Root mean square of every state variable over all samples seen."""
        return np.sqrt(self.mean_square)

    def training_step(self):
        """Median step over the chunks (weighted median of their medians); NaN without steps."""
        if not self.steps:
            return float("nan")
        medians = np.array([m for m, _ in self.steps])
        counts = np.array([c for _, c in self.steps], dtype=float)
        order = np.argsort(medians)
        cumulative = np.cumsum(counts[order])
        return float(medians[order][np.searchsorted(cumulative, cumulative[-1] / 2)])


class ShapeOnly:
    """A chunk's data as ``_check_size`` sees it: shapes only, never underdetermined.

    Each chunk of ``partial_fit`` may be smaller than the number of
    unknowns: only the accumulated equations must determine them.
    """

    def __init__(self, data):
        self.states, self.derivatives = data.states, data.derivatives

    def n_rows(self, fit_on):
        return np.inf


def partial_fit_chunk(estimator, X, y=None, sample_weight=None):
    """One call of ``estimator.partial_fit``: add the chunk, solve, set the fitted attributes.

    The first call builds the model space (on the explicit ``domain``) and
    starts a :class:`PartialFitState`, kept as ``estimator._partial``; each
    call adds the chunk's normal equations and solves all of them so far
    (steps (c) and (d) of :mod:`sk_hamiltonian._fit_steps`).
    """
    state = getattr(estimator, "_partial", None)
    if state is None:
        estimator._validate_params()
        estimator._check_integer_params()
        if estimator.solver not in ("auto", "normal"):
            raise ValueError(
                f"partial_fit accumulates the normal equations, so it needs "
                f"solver='auto' or 'normal'; got solver={estimator.solver!r}."
            )
    else:
        state.check_parameters(estimator)
    data = estimator._training_data(X, y, sample_weight, reset=state is None)
    if state is None:
        space = steps.build_space(estimator, data, size_data=ShapeOnly(data))
        design = estimator._design(space)
        state = PartialFitState(estimator, design.accumulator(), data.states.shape[1])
    else:
        space = estimator._space
        design = estimator._design(space)
        estimator._check_size(ShapeOnly(data))
        # Frames: _warn_n_outside, _warn_outside, here, partial_fit: the
        # caller is the next.
        estimator._warn_outside(data.states, what="the training states", stacklevel=4)
    state.add(design, data, data.median_step())
    estimator._partial = state
    solution = steps.solve_normal_equations(estimator, space, state.normal_equations())
    return steps.set_fitted(estimator, space, solution, data, solver="normal", statistics=state)
