"""The least-squares problem of a fit, and each regressor's design (the data fit).

Every fit of the package is ``min_c ||A c - b||``, possibly over a subspace
of the coefficients. A :class:`Design` says which rows and columns ``A`` and
``b`` have for one regressor on one model space (in skglm's words, the
*datafit*): :class:`HamiltonianDesign`, gradients of the basis against ``J
dx/dt`` (and the friction columns), or :class:`VectorFieldDesign`, the basis
against each component of ``dx/dt``. Bound to training data it gives the
:class:`LeastSquaresProblem` the solvers take, and its normal equations by
the cheapest route (:meth:`Design.normal_equations`).
"""

import numpy as np

from .._design import (
    column_groups,
    hamiltonian_blocks,
    quadrature_nodes,
    value_blocks,
    vector_field_blocks,
)
from .._design_operator import DesignOperator
from .._factored import FactoredNormalEquations
from .._solvers import NormalEquations
from .column_solvers import _squared_norms, design_residual


class LeastSquaresProblem:
    """The design of one fit, in the forms the solvers take.

    Parameters
    ----------
    blocks : callable
        ``blocks(grouped=False)``: an iterable of row blocks ``(A, b)`` of
        every column, or ``(A, b, group)`` with ``grouped=True`` (see
        ``groups``).
    operator : callable
        ``operator()``: the design as a
        :class:`~sk_hamiltonian._design_operator.DesignOperator`.
    normal_equations : callable
        ``normal_equations(progress=None) -> (A^T A, A^T b, b^T b)``, by the
        estimator's cheapest route (grouped blocks, or
        :mod:`sk_hamiltonian._factored`); ``progress(k, n_rows)`` after each
        block.
    n_columns : int
        Columns of the design (unknowns).
    n_nonnegative : int, default=0
        How many of the last unknowns are constrained to be ``>= 0``.
    groups : list of ndarray of int, default=None
        The columns of each group of ``blocks(grouped=True)``, as the sketch
        accumulates them; None: one group of every column.
    """

    def __init__(self, blocks, operator, normal_equations, n_columns, n_nonnegative=0,
                 groups=None):
        self.blocks = blocks
        self.operator = operator
        self.normal_equations = normal_equations
        self.n_columns = n_columns
        self.n_nonnegative = n_nonnegative
        self.groups = groups

    def column_norms(self, basis=None):
        """Norms of the columns of ``A`` (or ``A @ basis``), from one pass over its blocks."""
        squared = 0.0
        for A, _ in self.blocks():
            squared = squared + _squared_norms(A, basis)
        return np.sqrt(squared)


class Design:
    """One regressor's least-squares design on a model space, for any training data.

    Parameters
    ----------
    space : ModelSpace
        The basis: one column per function (and the friction columns of a
        damped Hamiltonian after them).
    fit_on : {"derivatives", "steps", "simpson", "weak"}
        What the rows fit (see :mod:`sk_hamiltonian._design`).
    """

    def __init__(self, space, fit_on):
        self.space = space
        self.fit_on = fit_on

    @property
    def n_columns(self):
        """Columns of the design (unknowns)."""
        return self.space.n_terms + self.n_nonnegative

    @property
    def n_nonnegative(self):
        """How many of the last unknowns are constrained to be ``>= 0``."""
        return 0

    @property
    def groups(self):
        """Columns each group of rows of the grouped blocks touches; None: one group of all."""
        return None

    def n_rows(self, data):
        """Equations of the design on ``data``."""
        return data.n_rows(self.fit_on) * self.rows_per_sample(data.states.shape[1])

    def rows_per_sample(self, n_states):
        """Equations per sample (state, step or pair of steps)."""
        raise NotImplementedError

    def blocks(self, data, grouped=False):
        """Row blocks ``(A, b)`` of the design (grouped: ``(A, b, group)``)."""
        raise NotImplementedError

    def operator(self, data):
        """The design as a :class:`~sk_hamiltonian._design_operator.DesignOperator`."""
        raise NotImplementedError

    def factored_maps(self):
        """The maps of normal equations factored on a value basis (:mod:`sk_hamiltonian._factored`), or None."""
        return None

    def accumulator(self):
        """An empty accumulator of the normal equations, by the cheapest route.

        Here a :class:`~sk_hamiltonian._solvers.normal.NormalEquations` with
        the design's groups; :meth:`normal_blocks` gives what it takes.
        """
        return NormalEquations(self.n_columns, self.groups)

    def normal_blocks(self, data, accumulator):
        """The blocks of ``data`` that ``accumulator`` (from :meth:`accumulator`) takes."""
        return self.blocks(data, grouped=True)

    def accumulate(self, data, progress=None, accumulator=None):
        """``accumulator`` (default: a new :meth:`accumulator`) with the blocks of ``data`` added.

        ``progress(k, n_rows)`` after each block. Accumulators of several
        pieces of data add up (``+=``): ``partial_fit`` and the dask fit
        build them chunk by chunk.
        """
        if accumulator is None:
            accumulator = self.accumulator()
        return accumulator.add_blocks(self.normal_blocks(data, accumulator), progress)

    def normal_equations(self, data, progress=None):
        """``(A^T A, A^T b, b^T b)`` of the design on ``data``, by the cheapest route.

        Parameters
        ----------
        data : TrainingData
            Any training data: all of a fit's, or some of its trajectories
            (:meth:`~sk_hamiltonian._design.TrainingData.take_trajectories`).
        progress : callable, default=None
            ``progress(k, n_rows)`` after each block.

        Returns
        -------
        gram : ndarray of shape (n_columns, n_columns)
        rhs : ndarray of shape (n_columns,) or (n_columns, n_targets)
        btb : float or ndarray of shape (n_targets, n_targets)
        """
        accumulator = self.accumulate(data, progress)
        gram, rhs = accumulator.result()
        return gram, rhs, accumulator.btb

    def trajectory_normal_equations(self, data):
        """``(A_k^T A_k, A_k^T b_k, b_k^T b_k)`` of every trajectory ``k`` of ``data``, in one pass.

        The rows of a trajectory are a contiguous run of row groups of the
        quadrature (:meth:`~sk_hamiltonian._training_data.TrainingData.groups_per_trajectory`);
        within a block of :meth:`blocks` row ``j * n + s`` is row ``j`` of the
        block's sample ``s`` (its ``n`` samples by ``rows_per_sample``
        rows), so each trajectory's rows are a slice of every block. The sum
        over trajectories is :meth:`normal_equations` (by the plain route:
        every row against every column), and a weighted sum is the normal
        equations of the trajectories weighted so (the resampling of
        :mod:`sk_hamiltonian._resampling`).

        Parameters
        ----------
        data : TrainingData
            With trajectories (the derivative layout).

        Returns
        -------
        grams : ndarray of shape (n_trajectories, n_columns, n_columns)
        rhs : ndarray of shape (n_trajectories, n_columns) or (n_trajectories, n_columns, n_targets)
        btb : ndarray of shape (n_trajectories,) or (n_trajectories, n_targets, n_targets)
        """
        counts = data.groups_per_trajectory(self.fit_on)
        ends = np.cumsum(counts)
        n_trajectories, c = counts.size, self.n_columns
        per_sample = self.rows_per_sample(data.states.shape[1])
        grams = np.zeros((n_trajectories, c, c))
        rhs = btb = None
        start = 0  # the block's first sample
        for A, b in self.blocks(data):
            n = A.shape[0] // per_sample
            rows = A.T.reshape(c, per_sample, n)
            targets = b.reshape((per_sample, n) + b.shape[1:])
            if rhs is None:
                rhs = np.zeros((n_trajectories, c) + b.shape[1:])
                btb = np.zeros((n_trajectories,) + b.shape[1:] * 2)
            # The trajectories with samples in this block, and their slices of it.
            first = int(np.searchsorted(ends, start, side="right"))
            last = int(np.searchsorted(ends, start + n, side="left"))
            for k in range(first, min(last, n_trajectories - 1) + 1):
                low = max(int(ends[k] - counts[k]), start) - start
                high = min(int(ends[k]), start + n) - start
                if high <= low:
                    continue
                part = rows[:, :, low:high].reshape(c, -1)
                target = targets[:, low:high].reshape((-1,) + b.shape[1:])
                grams[k] += part @ part.T
                rhs[k] += part @ target
                btb[k] += target.T @ target
            start += n
        if rhs is None:
            rhs = np.zeros((n_trajectories, c))
            btb = np.zeros(n_trajectories)
        return grams, rhs, btb

    def residual(self, data):
        """``residual(keep)``: refinement of a solve from normal equations against this design on ``data``.

        What the ``"normal"`` solver refines its Cholesky solution with
        (:func:`~.column_solvers.design_residual`); pass it to
        :meth:`~.support.SupportRule.from_normal_equations` for ``fit``'s
        answer.
        """
        return design_residual(self.operator(data), self.n_columns)

    def problem(self, data):
        """The :class:`LeastSquaresProblem` of the design on ``data``."""
        return LeastSquaresProblem(
            lambda grouped=False: self.blocks(data, grouped=grouped),
            lambda: self.operator(data),
            lambda progress=None: self.normal_equations(data, progress),
            self.n_columns, self.n_nonnegative, groups=self.groups,
        )


class HamiltonianDesign(Design):
    """Gradients of the basis against ``J dx/dt``: ``n_states`` rows per sample.

    Parameters
    ----------
    space : ModelSpace
        The basis of ``H~``.
    fit_on : {"derivatives", "steps", "simpson", "weak"}
        What the rows fit.
    damping : bool, default=False
        One friction column per degree of freedom after the basis, its
        coefficient ``>= 0``.
    """

    def __init__(self, space, fit_on, damping=False):
        super().__init__(space, fit_on)
        self.damping = damping
        self._groups = None

    @property
    def n_nonnegative(self):
        return self.space.n_states // 2 if self.damping else 0

    @property
    def groups(self):
        if self._groups is None:
            self._groups = column_groups(self.space, self.damping)
        return self._groups

    def rows_per_sample(self, n_states):
        return n_states

    def blocks(self, data, grouped=False):
        space = self.space
        return hamiltonian_blocks(
            space, data, self.fit_on, quadrature_nodes(space), damping=self.damping,
            grouped=grouped,
        )

    def operator(self, data):
        space = self.space
        return DesignOperator(
            space, data, self.fit_on, quadrature_nodes(space), "gradient", damping=self.damping
        )

    def factored_maps(self):
        # The rows of every variable are gradients of one value basis: where
        # its one Gram matrix costs fewer multiply-adds than the groups' (the
        # dense spaces: n_states times fewer), accumulate that (_factored).
        maps = self.space.derivative_maps()
        return maps if maps.pays(self.groups) else None

    def accumulator(self):
        maps = self.factored_maps()
        if maps is None:
            return super().accumulator()
        d = self.space.n_states // 2
        return FactoredNormalEquations(maps, range(d, 2 * d) if self.damping else ())

    def normal_blocks(self, data, accumulator):
        if not isinstance(accumulator, FactoredNormalEquations):
            return super().normal_blocks(data, accumulator)
        return value_blocks(
            accumulator.maps, data, self.fit_on, quadrature_nodes(self.space),
            damping=self.damping,
        )


class VectorFieldDesign(Design):
    """The basis against each component of ``dx/dt``: one row per sample, one target per component."""

    def rows_per_sample(self, n_states):
        return 1

    def blocks(self, data, grouped=False):
        # Every row touches every column: one group.
        space = self.space
        return vector_field_blocks(
            space, data, self.fit_on, quadrature_nodes(space, of_gradient=False)
        )

    def operator(self, data):
        space = self.space
        return DesignOperator(
            space, data, self.fit_on, quadrature_nodes(space, of_gradient=False), "value"
        )
