"""Training data and the least-squares designs built from it.

The regressors fit linear models, so every fit is a least-squares problem
``A c ≈ b`` assembled in row blocks from a :class:`TrainingData`:

- ``fit_on="derivatives"``: one row group per state, the basis (or its
  gradient) at the state against the estimated time derivative;
- ``fit_on="steps"``: one row group per observed step ``x0 -> x1`` of a
  trajectory, the basis averaged over the segment with Gauss-Legendre nodes
  against ``(x1 - x0) / dt``: the averaged-vector-field map is linear in the
  coefficients, so no derivative is estimated at all.
- ``fit_on="simpson"``: one row group per pair of consecutive steps ``x0 ->
  x1 -> x2``, Simpson's rule for the integral of the field over the pair
  against ``(x2 - x0) / (t2 - t0)``. Also linear and derivative-free, and
  exact to ``O(dt**4)`` for the true field, so it learns the Hamiltonian
  itself rather than the AVF method's modified one.

Every kind is a :class:`Quadrature`: the points where a row group evaluates
the basis, with their weights, and the rate it is fitted to.

Blocks stay a few tens of megabytes whatever the number of samples, so the
streaming solvers run in bounded memory.
"""

import math

import numpy as np

from ._space.fourier import phase_nodes
from ._space.legendre import gauss_on_unit
from ._space.workspace import scratch

# Entries of one design block (float64): 8 million is 64 MB, held in the
# thread's workspace; that gives every rank-k BLAS update of the Gram matrix
# thousands of rows, which it needs to run near peak speed (measured on
# double-pendulum fits: 16 MB blocks took 15 % longer).
BLOCK_ENTRIES = 8_000_000


class TrainingData:
    """States, targets and (optionally) steps and weights of one fit.

    Parameters
    ----------
    states : ndarray of shape (n_samples, n_states)
        States the derivative fit evaluates the basis at.
    derivatives : ndarray of shape (n_samples, n_targets) or None
        Targets of the derivative fit.
    sample_weight : ndarray of shape (n_samples,) or None
        Weights of the states.
    trajectories : list of (times, states) or None
        The trajectories the states came from (derivative layout input), for
        the steps fit and the energy check.
    trajectory_weight : ndarray of shape (n_trajectories,) or None
        Weights of the trajectories, applied to their steps.
    """

    def __init__(self, states, derivatives, sample_weight=None, trajectories=None,
                 trajectory_weight=None):
        self.states = states
        self.derivatives = derivatives
        self.sample_weight = sample_weight
        self.trajectories = trajectories
        self.trajectory_weight = trajectory_weight

    def steps(self, space):
        """Observed steps ``(x0, dx, dt, weight)`` of every trajectory.

        ``dx`` takes periodic variables the short way round the circle, so a
        trajectory given with wrapped angles still has small steps.
        """
        if self.trajectories is None:
            raise ValueError(
                "fit_on='steps' fits the observed steps of trajectories: pass the "
                "output of DerivativeTransformer (trajectories with their times), not "
                "2-D states with derivatives."
            )
        starts, moves, dts, weights = [], [], [], []
        for k, (t, S) in enumerate(self.trajectories):
            starts.append(S[:-1])
            moves.append(space.wrap_difference(np.diff(S, axis=0)))
            dts.append(np.diff(t))
            w = 1.0 if self.trajectory_weight is None else self.trajectory_weight[k]
            weights.append(np.full(S.shape[0] - 1, w))
        x0 = np.concatenate(starts)
        if x0.shape[0] == 0:
            raise ValueError(
                "fit_on='steps' needs trajectories with at least two samples; every "
                "trajectory here has one."
            )
        return x0, np.concatenate(moves), np.concatenate(dts), np.concatenate(weights)

    def pairs(self, space):
        """Pairs of consecutive steps ``(x0, x1, x2, h1, h2, weight)`` of every trajectory."""
        self._check_pairs()
        parts = []
        for k, (t, S) in enumerate(self.trajectories):
            moves = space.wrap_difference(np.diff(S, axis=0))
            h = np.diff(t)
            w = 1.0 if self.trajectory_weight is None else self.trajectory_weight[k]
            parts.append((S[:-2], S[1:-1], S[2:], moves[:-1] + moves[1:], h[:-1], h[1:],
                          np.full(S.shape[0] - 2, w)))
        return tuple(np.concatenate(column) for column in zip(*parts))

    def _check_pairs(self):
        if self.trajectories is None:
            raise ValueError(
                "fit_on='simpson' fits pairs of observed steps of trajectories: pass "
                "the output of DerivativeTransformer (trajectories with their times), "
                "not 2-D states with derivatives."
            )
        short = [k for k, (_, S) in enumerate(self.trajectories) if S.shape[0] < 3]
        if short:
            raise ValueError(
                f"fit_on='simpson' needs at least three samples per trajectory (one pair "
                f"of steps); {len(short)} of {len(self.trajectories)} trajectories have "
                f"fewer (the first is number {short[0]}). Drop them, or fit with "
                f"fit_on='steps'."
            )

    def quadrature(self, space, fit_on, n_nodes):
        """The :class:`Quadrature` of the fit's row groups."""
        if fit_on == "steps":
            x0, dx, dt, weight = self.steps(space)
            nodes, node_weights = gauss_on_unit(n_nodes)
            points = [(x0 + s * dx, w) for s, w in zip(nodes, node_weights)]
            return Quadrature(points, dx / dt[:, None], weight)
        if fit_on == "simpson":
            x0, x1, x2, move, h1, h2, weight = self.pairs(space)
            # Simpson's rule on two intervals of any lengths, normalized to sum to one.
            points = [
                (x0, (2.0 - h2 / h1) / 6.0),
                (x1, (h1 + h2) ** 2 / (6.0 * h1 * h2)),
                (x2, (2.0 - h1 / h2) / 6.0),
            ]
            return Quadrature(points, move / (h1 + h2)[:, None], weight)
        return Quadrature([(self.states, 1.0)], self.derivatives, self.sample_weight)

    def n_rows(self, fit_on):
        """Number of state (or step) row groups the fit will have."""
        if fit_on == "steps" and self.trajectories is not None:
            return sum(max(0, S.shape[0] - 1) for _, S in self.trajectories)
        if fit_on == "simpson":
            self._check_pairs()
            return sum(S.shape[0] - 2 for _, S in self.trajectories)
        return self.states.shape[0]


class Quadrature:
    """Where a fit's row groups evaluate the basis, and what they are fitted to.

    Row group ``r`` fits ``sum_k w_k[r] f(X_k[r]) ≈ rate[r]`` for the model's
    field (or its gradient) ``f``.

    Parameters
    ----------
    points : list of (ndarray of shape (n_groups, n_states), float or ndarray of shape (n_groups,))
        The points ``X_k`` and their weights ``w_k``.
    rate : ndarray of shape (n_groups, n_states) or (n_groups, n_targets)
        The time derivative (or mean rate of change) each group fits.
    weight : ndarray of shape (n_groups,) or None
        Weights of the row groups.
    """

    def __init__(self, points, rate, weight):
        self.points = points
        self.rate = rate
        self.weight = weight
        self.n_groups = rate.shape[0]

    def scale(self, values, w, rows):
        """Multiply ``values`` (rows on the last axis) in place by a point's weights."""
        if np.isscalar(w):
            if w != 1.0:
                values *= w
        else:
            values *= w[rows]
        return values

    def weighted_sum(self, function, rows):
        """``sum_k w_k function(X_k[rows])``, each result with the rows on its last axis."""
        total = None
        for X, w in self.points:
            part = self.scale(function(X[rows]), w, rows)
            total = part if total is None else total + part
        return total


def symplectic_targets(y):
    """``J dx/dt`` for ``J = [[0, I], [-I, 0]]``: the gradient the data ask for."""
    d = y.shape[-1] // 2
    return np.concatenate([y[..., d:], -y[..., :d]], axis=-1)


def _rows_per_block(width):
    return max(1, BLOCK_ENTRIES // max(1, width))


def _weighted(evaluate, quadrature, rows, out):
    """Write ``sum_k w_k evaluate(X_k[rows])`` (terms-major) into ``out``.

    ``evaluate(X, out=...)`` is a space's ``gradients_t`` or ``values_t``.
    """
    spare = scratch("design.node", out.shape) if len(quadrature.points) > 1 else None
    for k, (X, w) in enumerate(quadrature.points):
        target = out if k == 0 else spare
        evaluate(X[rows], out=target)
        quadrature.scale(target, w, rows)
        if k:
            out += target


def column_groups(space, damping=False):
    """Columns of the Hamiltonian design that can be nonzero in the rows of each variable.

    ``d phi_j / d x_i`` vanishes wherever ``phi_j`` does not depend on
    ``x_i`` (its column of variable ``i`` is the constant one), so the rows
    of variable ``i`` touch only the functions that depend on it, plus the
    damping column of degree of freedom ``k`` in the rows of ``q_k``. The
    normal matrix is then a sum of one smaller Gram matrix per variable: for
    total-degree sets in four variables, half the work of the dense one.

    Returns
    -------
    groups : list of ndarray of int
        Per state variable, the sorted column indices.
    """
    m, n_terms = space.n_states, space.n_terms
    d = m // 2
    groups = []
    for i in range(m):
        columns = np.flatnonzero(space.columns[:, i] != 0)
        if damping and i >= d:
            columns = np.append(columns, n_terms + i - d)
        groups.append(columns)
    return groups


def hamiltonian_blocks(space, data, fit_on, n_nodes, damping=False, grouped=False):
    """Row blocks ``(A, b)`` of the structure-preserving fit.

    Each state (or step) gives ``n_states`` rows, ``grad phi(x) . c ≈ J dx/dt``
    (or the gradient averaged over the step). With ``damping``, ``d`` columns
    follow the basis: in the row of ``-dp_i/dt`` the observed ``dq_i/dt``,
    so that ``-dp/dt = dH/dq + gamma * dq/dt`` is linear in ``(c, gamma)``.

    Within a block the rows are ordered by state variable, then by sample.
    A block is a view of the thread's workspace (a Fortran-ordered matrix, as
    LAPACK and the BLAS rank-k update want it): it is valid until the next
    block is requested.

    With ``grouped``, each block is split by state variable ``i`` into the
    columns of ``column_groups(space, damping)[i]`` (the others are zero in
    those rows), yielded as ``(A_i, b_i, i)``.

    Yields
    ------
    A : ndarray of shape (n_rows, n_terms [+ d]) or (n_rows_i, n_group_i)
    b : ndarray of shape (n_rows,) or (n_rows_i,)
    """
    groups = column_groups(space, damping) if grouped else None
    if grouped and space.layout.dense:
        yield from _grouped_blocks(space, data, fit_on, n_nodes, damping, groups)
        return
    m, n_terms = space.n_states, space.n_terms
    d = m // 2
    n_columns = n_terms + (d if damping else 0)
    quadrature = data.quadrature(space, fit_on, n_nodes)
    rate, weight = quadrature.rate, quadrature.weight
    step = _rows_per_block(m * n_columns)
    for start in range(0, quadrature.n_groups, step):
        rows = slice(start, start + step)
        n = rate[rows].shape[0]
        # Terms-major: (column, variable, sample), so that A = block.T.
        block = scratch("design.block", (n_columns, m, n))
        _weighted(space.gradients_t, quadrature, rows, block[:n_terms])
        targets = symplectic_targets(rate[rows]).T  # (variable, sample)
        if damping:
            block[n_terms:] = 0.0
            idx = np.arange(d)
            block[n_terms + idx, d + idx] = rate[rows][:, d:].T  # observed dq/dt in the -dp/dt rows
        if weight is not None:
            root = np.sqrt(weight[rows])
            block *= root
            targets = targets * root
        if not grouped:
            yield block.reshape(n_columns, m * n).T, targets.ravel()
            continue
        for i, columns in enumerate(groups):
            part = scratch("design.group", (columns.size, n))
            np.take(block[:, i, :], columns, axis=0, out=part, mode="clip")
            yield part.T, targets[i], i


def _grouped_blocks(space, data, fit_on, n_nodes, damping, groups):
    """:func:`hamiltonian_blocks` with ``grouped``, assembled group by group (dense layouts).

    Each variable's rows are computed for the functions that depend on it
    only, straight into the group's block: no full block is formed.
    """
    m, n_terms = space.n_states, space.n_terms
    d = m // 2
    quadrature = data.quadrature(space, fit_on, n_nodes)
    rate, weight = quadrature.rate, quadrature.weight
    basis = [g[g < n_terms] for g in groups]
    step = _rows_per_block(sum(g.size for g in groups))
    for start in range(0, quadrature.n_groups, step):
        rows = slice(start, start + step)
        n = rate[rows].shape[0]
        blocks = [scratch(f"design.group{i}", (g.size, n)) for i, g in enumerate(groups)]
        outs = [block[: b.size] for block, b in zip(blocks, basis)]
        if len(quadrature.points) > 1:
            spares = [scratch(f"design.node{i}", out.shape) for i, out in enumerate(outs)]
        for k, (X, w) in enumerate(quadrature.points):
            targets = outs if k == 0 else spares
            space.gradient_rows_t(X[rows], basis, targets)
            for out, target in zip(outs, targets):
                quadrature.scale(target, w, rows)
                if k:
                    out += target
        targets = symplectic_targets(rate[rows]).T  # (variable, sample)
        if damping:
            for i in range(d, m):
                blocks[i][-1] = rate[rows, i]  # observed dq/dt in the -dp/dt rows
        if weight is not None:
            root = np.sqrt(weight[rows])
            targets = targets * root
            for block in blocks:
                block *= root
        for i, block in enumerate(blocks):
            yield block.T, targets[i], i


def value_blocks(maps, data, fit_on, n_nodes, damping=False):
    """Row blocks ``(B, targets)`` of the value design of a Hamiltonian fit.

    The factored form of :func:`hamiltonian_blocks` (see
    :mod:`sk_hamiltonian._factored`): one row per state (or step), the
    functions of the value basis ``maps.value_space`` at the same points,
    quadrature and weights, followed with ``damping`` by the ``d`` friction
    columns of the ``-dp/dt`` rows (the observed ``dq/dt``); the targets are
    those of every variable's rows side by side.

    A block is a Fortran-ordered view of the thread's workspace, valid until
    the next block is requested.

    Parameters
    ----------
    maps : DerivativeMaps
        The gradient of the fit's model space on its value basis.
    data : TrainingData
    fit_on : {"derivatives", "steps", "simpson"}
    n_nodes : int
        Gauss-Legendre nodes of a step (as for :func:`hamiltonian_blocks`).
    damping : bool, default=False

    Yields
    ------
    B : ndarray of shape (n_rows, n_values [+ d])
    targets : ndarray of shape (n_rows, n_states)
        ``J dx/dt`` (or its mean over the step), weighted as ``B``.
    """
    space = maps.value_space
    m = space.n_states
    d = m // 2
    n_values = maps.n_values
    n_columns = n_values + (d if damping else 0)
    quadrature = data.quadrature(space, fit_on, n_nodes)
    rate, weight = quadrature.rate, quadrature.weight
    step = _rows_per_block(n_columns)
    for start in range(0, quadrature.n_groups, step):
        rows = slice(start, start + step)
        n = rate[rows].shape[0]
        block = scratch("design.values", (n_columns, n))
        _weighted(space.values_t, quadrature, rows, block[:n_values])
        if damping:
            block[n_values:] = rate[rows, d:].T  # observed dq/dt, in the -dp/dt rows
        targets = symplectic_targets(rate[rows])
        if weight is not None:
            root = np.sqrt(weight[rows])
            block *= root
            targets = targets * root[:, None]
        yield block.T, targets


def vector_field_blocks(space, data, fit_on, n_nodes):
    """Row blocks ``(A, b)`` of the component-wise fit: ``phi(x) . C ≈ dx/dt``.

    A block is a Fortran-ordered view, valid until the next one is requested.

    Yields
    ------
    A : ndarray of shape (n_rows, n_terms)
    b : ndarray of shape (n_rows, n_targets) or (n_rows,)
    """
    quadrature = data.quadrature(space, fit_on, n_nodes)
    rate, weight = quadrature.rate, quadrature.weight
    step = _rows_per_block(space.n_terms)
    for start in range(0, quadrature.n_groups, step):
        rows = slice(start, start + step)
        At, b = quadrature.weighted_sum(space.values_t, rows), rate[rows]
        if weight is not None:
            root = np.sqrt(weight[rows])
            At = At * root
            b = b * (root if b.ndim == 1 else root[:, None])
        yield At.T, b


def quadrature_nodes(space, of_gradient=True):
    """Gauss-Legendre nodes that average this space's functions exactly along a segment.

    A polynomial of degree ``k`` along a segment needs ``ceil((k + 1) / 2)``
    nodes: ``ceil(n / 2)`` for the gradient of a degree-``n`` basis, ``ceil((n
    + 1) / 2)`` for the basis itself. Trigonometric factors are not
    polynomials along a segment; they add the nodes that average them to
    round-off along a short segment (a phase up to 0.145 radians, see
    :func:`~sk_hamiltonian._space.fourier.phase_nodes`), which is what
    sampled data have. The AVF method adds more to a step that turns them
    further.
    """
    k = space.degree - 1 if of_gradient else space.degree
    n = max(1, math.ceil((k + 1) / 2))
    return n + (phase_nodes(0.0) if space.periodic.any() else 0)
