"""The least-squares design of a fit as a linear operator, never formed.

``A c`` is the model's gradient (or value) at every sample for coefficients
``c``, which :class:`~sk_hamiltonian._space.contraction.ContractionPlan`
computes one variable at a time, and ``A^T r`` is its transpose (reverse mode
through the same tree). Each costs a few times the number of *prefixes* of the
index set per sample, mostly in one matrix product, against ``n_terms *
n_states`` entries per sample for the explicit design: iterative solvers
apply both dozens of times without ever holding the design. The chunks of
samples of a pass run on the cores that are idle (each pass is NumPy work
that releases the GIL).

Rows are grouped per sample as ``(n_outputs, K, n_samples)`` arrays:
``n_outputs = n_states`` derivative rows of one target for the Hamiltonian
fit, one value row of ``K`` targets for the vector-field fit. Sample weights
scale rows by their square roots; a row group sums over the weighted
points of its :class:`~._design.Quadrature` (a step's Gauss-Legendre nodes,
Simpson's three observations); damping adds one column per degree of
freedom (see :mod:`._design`).
"""

import numpy as np

from ._design import symplectic_targets
from ._threads import map_on_idle_cores
from ._space.contraction import ContractionPlan
from ._space.fourier import fourier_moments
from ._space.legendre import legendre_moments
from ._space.gram import gradient_gram

# Samples per pass chunk: bounds the tables and results held at once.
CHUNK_SAMPLES = 8192


class DesignOperator:
    """``A`` and ``A^T`` of a Hamiltonian (``kind="gradient"``) or vector-field fit.

    Parameters
    ----------
    space : ModelSpace
        The basis.
    data : TrainingData
        The samples.
    fit_on : {"derivatives", "steps", "simpson", "weak"}
        What the rows fit (see :mod:`._design`).
    n_nodes : int
        Gauss-Legendre nodes per step (``fit_on="steps"``).
    kind : {"gradient", "value"}
        Rows are gradients (Hamiltonian fit) or values (vector-field fit).
    damping : bool, default=False
        Append the damping columns (gradient kind only).
    """

    def __init__(self, space, data, fit_on, n_nodes, kind, damping=False):
        self.space = space
        self.kind = kind
        self.order = 1 if kind == "gradient" else 0
        self.plan = ContractionPlan(space.columns, space.width)
        m = space.n_states
        self.quadrature = data.quadrature(space, fit_on, n_nodes)
        rate, weight = self.quadrature.rate, self.quadrature.weight
        self.n_samples = self.quadrature.n_groups
        self.root = None if weight is None else np.sqrt(weight)
        #: Whether coefficients are 1-D (one target).
        self.one_target = kind == "gradient" or rate.ndim == 1
        if kind == "gradient":
            self.targets = symplectic_targets(rate).T[:, None, :]  # (m, 1, S)
            self.rows = self.plan.rows(1, [(i,) for i in range(m)])
            self.n_dof = m // 2 if damping else 0
            # Observed dq/dt, which multiplies gamma in the -dp/dt rows.
            self.friction = rate[:, m // 2 :].T if damping else None  # (d, S)
        else:
            rate = rate if rate.ndim == 2 else rate[:, None]
            self.targets = rate.T[None]  # (1, K, S)
            self.rows = np.zeros(1, dtype=np.intp)
            self.n_dof = 0
            self.friction = None
        if self.root is not None:
            self.targets = self.targets * self.root
        self.n_targets = self.targets.shape[1]
        self.n_columns = space.n_terms + self.n_dof

    # ------------------------------------------------------------ products
    def _chunks(self):
        for start in range(0, self.n_samples, CHUNK_SAMPLES):
            yield slice(start, start + CHUNK_SAMPLES)

    def _tables(self, part, X):
        return self.space.factor_tables(X[part], self.order)

    def matvec(self, x):
        """``A x`` for ``x`` of shape (n_columns, K): ndarray (n_outputs, K, n_samples)."""
        coef, gamma = x[: self.space.n_terms], x[self.space.n_terms :]
        C = self.plan.bind(coef)
        out = np.zeros((self.rows.size, x.shape[1], self.n_samples))

        def chunk(part):
            for X, w in self.quadrature.points:
                results, _ = self.plan.contract(self._tables(part, X), C, self.order)
                out[:, :, part] += self.quadrature.scale(results[self.rows], w, part)

        map_on_idle_cores(chunk, self._chunks())
        if self.n_dof:
            d = self.n_dof
            out[d:, 0] += gamma[:, 0, None] * self.friction
        if self.root is not None:
            out *= self.root
        return out

    def rmatvec(self, r):
        """``A^T r`` for ``r`` of shape (n_outputs, K, n_samples): ndarray (n_columns, K)."""
        if self.root is not None:
            r = r * self.root
        n_patterns = len(self.plan._step(self.order)[1])

        def chunk(part):
            size = min(part.stop, self.n_samples) - part.start
            weights = np.zeros((n_patterns, r.shape[1], size))
            total = 0.0
            for X, w in self.quadrature.points:
                weights[self.rows] = self.quadrature.scale(r[:, :, part].copy(), w, part)
                total = total + self.plan.adjoint(self._tables(part, X), weights, self.order)
            return total

        out = np.zeros((self.n_columns, r.shape[1]))
        # Summed in the order of the chunks, whatever the threads.
        for total in map_on_idle_cores(chunk, self._chunks()):
            out[: self.space.n_terms] += total
        if self.n_dof:
            d = self.n_dof
            out[self.space.n_terms :, 0] = np.einsum("is,is->i", r[d:, 0], self.friction)
        return out

    # ------------------------------------------------------ preconditioner
    def gram_estimate(self):
        """``A^T A`` under the uniform measure on the box: ndarray (n_columns, n_columns).

        The expected normal matrix of samples spread uniformly over the box,
        in closed form (:func:`~sk_hamiltonian._space.gram.gradient_gram`, or
        the diagonal value Gram for the vector-field fit), scaled by the total
        weight; the damping columns get their exact diagonal.
        """
        total = float(self.n_samples if self.root is None else np.sum(self.root**2))
        n = self.space.n_terms
        M = np.zeros((self.n_columns, self.n_columns))
        if self.kind == "gradient":
            M[:n, :n] = total * gradient_gram(self.space).toarray()
        else:
            M[:n, :n] = total * np.diag(value_moments(self.space))
        if self.n_dof:
            friction = self.friction if self.root is None else self.friction * self.root
            diagonal = np.einsum("is,is->i", friction, friction)
            M[n:, n:] = np.diag(np.where(diagonal > 0, diagonal, 1.0))
        return M


def value_moments(space):
    """``E[phi_j**2]`` under the uniform measure on the box, for every basis function."""
    moments = np.ones(space.n_terms)
    for i in range(space.n_states):
        if space.periodic[i]:
            values = np.diag(fourier_moments(space.fourier_degree)[0])
        elif space.mixed[i]:
            # Each family's own moments (they are not orthogonal to each other).
            values = np.concatenate([
                np.diag(legendre_moments(space.legendre_degree)[0]),
                np.diag(fourier_moments(space.fourier_degree)[0])[1:],
            ])
        else:
            values = np.diag(legendre_moments(space.legendre_degree)[0])
        moments *= values[space.columns[:, i]]
    return moments
