"""Refits on resamples of whole trajectories, from one pass over the data.

A regressor with ``n_resamples > 0`` refits its model on that many resamples
of its training trajectories (the bootstrap: as many drawn with replacement;
or half of them without), each with the same support rule, so that the spread
of the refits says how sure each term and coefficient is
(:func:`sk_hamiltonian.inspection.term_intervals`).

A resample only re-weights the rows of the same design: trajectory ``k``
drawn ``w_k`` times contributes ``w_k`` times its normal equations ``(G_k,
r_k)``. So the normal equations of every trajectory are accumulated once
(:meth:`~sk_hamiltonian._least_squares.Design.trajectory_normal_equations`),
each resample's are the weighted sum ``sum_k w_k G_k``, and each refit is a
solve of the support rule on them (:func:`~sk_hamiltonian._fit_steps.solve_normal_equations`):
the data are read once, however many resamples.

Memory: the trajectories' normal equations take ``n_trajectories *
n_columns**2`` floats, the resamples' ``n_resamples * n_columns**2``. Where
either would exceed ``RESAMPLE_ENTRIES``, the trajectories are taken in
groups whose normal equations fit, each group's added into the resamples' sums
and dropped, and the resamples in batches whose sums fit; each batch then
reads the data once more. The answer is the same. What grows with
``n_resamples`` without bound, the draws (``n_resamples * n_trajectories``)
and the refits' coefficients (twice ``n_resamples * n_columns``, as the
batches are joined), is checked against ``memory_limit`` before the fit
(:func:`check_resampling`), so that ``n_resamples=10**12`` is refused at
once instead of failing in numpy.
"""

import warnings

import numpy as np
from sklearn.utils import check_random_state
from sklearn.utils.parallel import Parallel, delayed

from . import _fit_steps as steps
from ._memory import FLOAT, SizeLimitError, bytes_text, describe_limit, memory_limit

# Floats (8 bytes each) held at once by the trajectories' normal equations,
# and again by the resamples' sums: 256 MB each.
RESAMPLE_ENTRIES = 32_000_000
#: What ``resample`` may be.
RESAMPLE_KINDS = ("bootstrap", "subsample")


def resample_weights(n_trajectories, n_resamples, kind, random_state):
    """How many times each resample takes each trajectory.

    Parameters
    ----------
    n_trajectories : int
        Trajectories of the fit.
    n_resamples : int
        Resamples to draw.
    kind : {"bootstrap", "subsample"}
        ``"bootstrap"``: ``n_trajectories`` draws with replacement (multinomial
        counts); ``"subsample"``: half the trajectories (rounded down), each
        once, without replacement.
    random_state : int, RandomState instance or None
        The draws' seed.

    Returns
    -------
    weights : ndarray of shape (n_resamples, n_trajectories)
        Non-negative integers as floats; each row sums to the resample's size.
    """
    rng = check_random_state(random_state)
    n = n_trajectories
    if kind == "bootstrap":
        return rng.multinomial(n, np.full(n, 1.0 / n), size=n_resamples).astype(float)
    weights = np.zeros((n_resamples, n))
    for row in weights:
        row[rng.choice(n, n // 2, replace=False)] = 1.0
    return weights


def resample_bytes(n_resamples, n_trajectories, n_coefficients):
    """Bytes that grow with ``n_resamples``: the draws, and the refits' coefficients twice."""
    return FLOAT * float(n_resamples) * (n_trajectories + 2 * n_coefficients)


def largest_resamples(n_trajectories, n_coefficients):
    """The most resamples whose :func:`resample_bytes` fit ``memory_limit``."""
    return int(memory_limit() // resample_bytes(1, n_trajectories, n_coefficients))


def _coefficients_at_least(estimator, n_states):
    """Unknowns of a refit, counted without building the space (1 if they cannot be counted yet).

    The space's own checks, which follow, say what is wrong with its parameters.
    """
    try:
        return estimator._n_terms(n_states)
    except (ValueError, TypeError):
        return 1


def check_resampling(estimator, data):
    """Refuse a resampling the data cannot give, or memory cannot hold (before any work)."""
    name = type(estimator).__name__
    if data.trajectories is None:
        raise ValueError(
            f"{name}: n_resamples={estimator.n_resamples} resamples whole trajectories, but X "
            f"holds 2-D states with their derivatives, which carry no trajectories. Pass the "
            f"DerivativeTransformer output (the derivative layout), or set n_resamples=0."
        )
    n = len(data.trajectories)
    least = 2 if estimator.resample == "bootstrap" else 4
    if n < least:
        raise ValueError(
            f"{name}: n_resamples={estimator.n_resamples} resamples whole trajectories, but "
            f"the data hold {n} trajector{'y' if n == 1 else 'ies'}; resample="
            f"{estimator.resample!r} needs at least {least} (and tens for intervals worth "
            f"reading). Cut a long record into segments, or set n_resamples=0."
        )
    coefficients = _coefficients_at_least(estimator, data.states.shape[1])
    need = resample_bytes(estimator.n_resamples, n, coefficients)
    if need > memory_limit():
        raise SizeLimitError(
            f"{name}: n_resamples={estimator.n_resamples:,} refits would hold about "
            f"{bytes_text(need)} (each resample's draw of {n:,} trajectories and its "
            f"{coefficients:,} coefficients), beyond {describe_limit()}. Lower n_resamples: "
            f"at most {largest_resamples(n, coefficients):,} fit here (sk-hamiltonian uses 100)."
        )


def fit_resamples(estimator, space, data):
    """The support rule's coefficients on ``n_resamples`` resamples of ``data``'s trajectories.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        Its ``n_resamples``, ``resample``, ``random_state``, ``n_jobs``, and
        support rule.
    space : ModelSpace
        The fitted model's space: every refit is on its box.
    data : TrainingData
        The fit's training data, with trajectories (their weights included).

    Returns
    -------
    coef : ndarray of shape (n_resamples, n_columns) or (n_resamples, n_columns, n_targets)
        Each refit's unknowns: the basis coefficients (zero off its
        support), then the friction ones.
    """
    weights = resample_weights(len(data.trajectories), estimator.n_resamples,
                               estimator.resample, estimator.random_state)
    design = estimator._design(space)
    size = design.n_columns**2
    n_groups = max(1, RESAMPLE_ENTRIES // size)
    batch = max(1, RESAMPLE_ENTRIES // size)
    parts = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for start in range(0, weights.shape[0], batch):
            sums = _weighted_sums(design, data, weights[start : start + batch], n_groups)
            parts.append(_solve_all(estimator, space, sums, estimator.n_jobs))
    _report(estimator, caught, weights.shape[0])
    return np.concatenate(parts)


def _weighted_sums(design, data, weights, n_groups):
    """``(sum_k w_rk G_k, sum_k w_rk r_k)`` of every resample ``r``, trajectories ``n_groups`` at a time."""
    n_trajectories = weights.shape[1]
    grams = rhs = None
    for start in range(0, n_trajectories, n_groups):
        group = np.arange(start, min(start + n_groups, n_trajectories))
        piece = data if group.size == n_trajectories else data.take_trajectories(group)
        g, r, _ = design.trajectory_normal_equations(piece)
        w = weights[:, group]
        g, r = np.tensordot(w, g, axes=1), np.tensordot(w, r, axes=1)
        grams, rhs = (g, r) if grams is None else (grams + g, rhs + r)
    return grams, rhs


def _solve_all(estimator, space, sums, n_jobs):
    """The support rule solved on each resample's normal equations, in ``n_jobs`` threads."""
    grams, rhs = sums
    n = grams.shape[0]
    n_jobs = min(n, _effective_jobs(n_jobs))
    if n_jobs == 1:
        return _solve_range(estimator, space, grams, rhs)
    # Threads: the solves are BLAS calls and small NumPy steps on arrays that
    # processes would have to copy; the order of the answers is the order of
    # the resamples whatever the scheduling.
    bounds = np.linspace(0, n, n_jobs + 1).astype(int)
    parts = Parallel(n_jobs=n_jobs, prefer="threads")(
        delayed(_solve_range)(estimator, space, grams[a:b], rhs[a:b])
        for a, b in zip(bounds[:-1], bounds[1:])
    )
    return np.concatenate(parts)


def _effective_jobs(n_jobs):
    from joblib import effective_n_jobs

    return max(1, effective_n_jobs(n_jobs))


def _solve_range(estimator, space, grams, rhs):
    out = None
    for r in range(grams.shape[0]):
        solution = steps.solve_normal_equations(estimator, space, (grams[r], rhs[r]))
        if out is None:
            out = np.zeros((grams.shape[0],) + solution.coef.shape)
        out[r] = solution.coef
    return out


def _report(estimator, caught, n_resamples):
    """One warning for the refits that warned (a threshold still dropping terms, say), not one each."""
    if not caught:
        return
    first = caught[0]
    warnings.warn(
        f"{type(estimator).__name__}: {len(caught)} warning(s) in the {n_resamples} refits on "
        f"resamples, the first: {first.message}",
        first.category,
        stacklevel=4,
    )
