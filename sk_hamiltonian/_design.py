"""Training data and the least-squares designs built from it.

The regressors fit linear models, so every fit is a least-squares problem
``A c ≈ b`` assembled in row blocks from a
:class:`~sk_hamiltonian._training_data.TrainingData`:

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
- ``fit_on="weak"``: one row group per window of consecutive samples, the
  basis weighted by a smooth bump ``phi`` against ``-int phi' x dt`` (the
  weak form, :meth:`~sk_hamiltonian._training_data.TrainingData.windows`).

Every kind is a :class:`~sk_hamiltonian._training_data.Quadrature`: the
points where a row group evaluates
the basis, with their weights, and the rate it is fitted to.

Blocks stay a few tens of megabytes whatever the number of samples, so the
streaming solvers run in bounded memory.
"""

import math

import numpy as np

from ._space.fourier import phase_nodes
from ._space.workspace import scratch

# Entries of one design block (float64): 8 million is 64 MB, held in the
# thread's workspace; that gives every rank-k BLAS update of the Gram matrix
# thousands of rows, which it needs to run near peak speed (measured on
# double-pendulum fits: 16 MB blocks took 15 % longer).
BLOCK_ENTRIES = 8_000_000


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
    fit_on : {"derivatives", "steps", "simpson", "weak"}
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
    return n + (phase_nodes(0.0) if space.has_fourier else 0)
