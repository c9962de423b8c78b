"""Training data and the least-squares designs built from it.

The regressors fit linear models, so every fit is a least-squares problem
``A c ≈ b`` assembled in row blocks from a :class:`TrainingData`:

- ``fit_on="derivatives"``: one row group per state, the basis (or its
  gradient) at the state against the estimated time derivative;
- ``fit_on="steps"``: one row group per observed step ``x0 -> x1`` of a
  trajectory, the basis averaged over the segment with Gauss-Legendre nodes
  against ``(x1 - x0) / dt``: the averaged-vector-field map is linear in the
  coefficients, so no derivative is estimated at all.

Blocks stay a few tens of megabytes whatever the number of samples, so the
streaming solvers run in bounded memory.
"""

import math

import numpy as np

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

    def n_rows(self, fit_on):
        """Number of state (or step) row groups the fit will have."""
        if fit_on == "steps" and self.trajectories is not None:
            return sum(max(0, S.shape[0] - 1) for _, S in self.trajectories)
        return self.states.shape[0]


def segment_nodes(n_nodes):
    """Gauss-Legendre nodes and weights on ``[0, 1]``."""
    nodes, weights = np.polynomial.legendre.leggauss(max(1, n_nodes))
    return 0.5 * (nodes + 1.0), 0.5 * weights


def averaged(evaluate, x0, dx, n_nodes):
    """``int_0^1 evaluate(x0 + s dx) ds`` by Gauss-Legendre quadrature."""
    nodes, weights = segment_nodes(n_nodes)
    total = None
    for s, w in zip(nodes, weights):
        part = w * evaluate(x0 + s * dx)
        total = part if total is None else total + part
    return total


def symplectic_targets(y):
    """``J dx/dt`` for ``J = [[0, I], [-I, 0]]``: the gradient the data ask for."""
    d = y.shape[-1] // 2
    return np.concatenate([y[..., d:], -y[..., :d]], axis=-1)


def _rows_per_block(width):
    return max(1, BLOCK_ENTRIES // max(1, width))


def _averaged_gradients(space, x0, dx, n_nodes, out):
    """Write ``int_0^1 grad phi(x0 + s dx) ds`` (terms-major) into ``out``."""
    nodes, weights = segment_nodes(n_nodes)
    node_values = scratch("design.node", out.shape)
    for k, (s, w) in enumerate(zip(nodes, weights)):
        target = out if k == 0 else node_values
        space.gradients_t(x0 + s * dx, out=target)
        target *= w
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
    if fit_on == "steps":
        x0, dx, dt, weight = data.steps(space)
        rate = dx / dt[:, None]
    else:
        x0, rate, weight = data.states, data.derivatives, data.sample_weight
    step = _rows_per_block(m * n_columns)
    for start in range(0, x0.shape[0], step):
        rows = slice(start, start + step)
        n = x0[rows].shape[0]
        # Terms-major: (column, variable, sample), so that A = block.T.
        block = scratch("design.block", (n_columns, m, n))
        if fit_on == "steps":
            _averaged_gradients(space, x0[rows], dx[rows], n_nodes, block[:n_terms])
        else:
            space.gradients_t(x0[rows], out=block[:n_terms])
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
    if fit_on == "steps":
        x0, dx, dt, weight = data.steps(space)
        rate = dx / dt[:, None]
        nodes, node_weights = segment_nodes(n_nodes)
    else:
        x0, rate, weight = data.states, data.derivatives, data.sample_weight
    basis = [g[g < n_terms] for g in groups]
    step = _rows_per_block(sum(g.size for g in groups))
    for start in range(0, x0.shape[0], step):
        rows = slice(start, start + step)
        n = x0[rows].shape[0]
        blocks = [scratch(f"design.group{i}", (g.size, n)) for i, g in enumerate(groups)]
        outs = [block[: b.size] for block, b in zip(blocks, basis)]
        if fit_on == "steps":
            node_outs = [scratch(f"design.node{i}", out.shape) for i, out in enumerate(outs)]
            for k, (s, w) in enumerate(zip(nodes, node_weights)):
                space.gradient_rows_t(x0[rows] + s * dx[rows], basis, outs if k == 0 else node_outs)
                for out, node_out in zip(outs, node_outs):
                    if k == 0:
                        out *= w
                    else:
                        node_out *= w
                        out += node_out
        else:
            space.gradient_rows_t(x0[rows], basis, outs)
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


def vector_field_blocks(space, data, fit_on, n_nodes):
    """Row blocks ``(A, b)`` of the component-wise fit: ``phi(x) . C ≈ dx/dt``.

    A block is a Fortran-ordered view, valid until the next one is requested.

    Yields
    ------
    A : ndarray of shape (n_rows, n_terms)
    b : ndarray of shape (n_rows, n_targets) or (n_rows,)
    """
    if fit_on == "steps":
        x0, dx, dt, weight = data.steps(space)
        rate = dx / dt[:, None]

        def basis(rows):
            return averaged(space.values_t, x0[rows], dx[rows], n_nodes)
    else:
        x0, rate, weight = data.states, data.derivatives, data.sample_weight

        def basis(rows):
            return space.values_t(x0[rows])
    step = _rows_per_block(space.n_terms)
    for start in range(0, x0.shape[0], step):
        rows = slice(start, start + step)
        At, b = basis(rows), rate[rows]
        if weight is not None:
            root = np.sqrt(weight[rows])
            At = At * root
            b = b * (root if b.ndim == 1 else root[:, None])
        yield At.T, b


def quadrature_nodes(space, of_gradient=True, extra_for_periodic=4):
    """Gauss-Legendre nodes that average this space's functions exactly along a segment.

    A polynomial of degree ``k`` along a segment needs ``ceil((k + 1) / 2)``
    nodes: ``ceil(n / 2)`` for the gradient of a degree-``n`` basis, ``ceil((n
    + 1) / 2)`` for the basis itself. Trigonometric factors are not
    polynomials along a segment; a few more nodes bring the quadrature error
    to round-off for the short segments of sampled data and integration steps.
    """
    k = space.degree - 1 if of_gradient else space.degree
    n = max(1, math.ceil((k + 1) / 2))
    return n + (extra_for_periodic if space.periodic.any() else 0)
