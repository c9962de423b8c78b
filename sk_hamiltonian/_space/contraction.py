"""Contract a coefficient vector with a tensor-product basis, one variable at a time.

The value of ``f = sum_j c_j prod_i T_i[alpha_ji]`` at a state needs no
per-function product: grouping the functions by their first ``m - 1``
indices, the last variable is summed first,

    f_p = sum_{c} C[p, c] T_{m-1}[c],        C[p, c] = coefficient of (p, c),

which, with the coefficients arranged once into the matrix ``C``, is one
matrix product for a whole batch of states; then variable ``m - 2`` is summed
into the prefixes of length ``m - 2``, and so on to the root (the tree of
:mod:`.trie`). Derivatives ride along: a derivative with respect to ``x_i``
uses the derivative table of variable ``i`` at the step that sums variable
``i``, so value, gradient and Hessian come out of one pass. The work per state
is the size of ``C`` (a few times the number of functions) plus the number of
tree nodes, against ``n_terms * n_states`` products per state for the
gradient of every function.

The plan is built once per model space and the coefficient matrix once per
coefficient vector (:meth:`ContractionPlan.bind`), so a simulation pays only
for the products.
"""

from itertools import combinations_with_replacement

import numpy as np
from scipy import sparse

from .trie import Level, prefix_ids
from .workspace import scratch

# Up to this many samples, contract with padded children and one matrix
# product per level (a fixed number of numpy calls, what one state costs);
# beyond, with segment sums over the tree's nodes (work proportional to them).
FEW_SAMPLES = 16
# Largest temporary of a chunk of samples in the many-samples contraction.
CHUNK_BYTES = 8 * 2**20


def _patterns(n_vars, order):
    """Derivative patterns up to ``order``, sorted by order: (), (i,), (i, j) with i <= j."""
    return [p for r in range(order + 1) for p in combinations_with_replacement(range(n_vars), r)]


class ContractionPlan:
    """The prefix tree of an index set, for contractions with coefficients.

    Parameters
    ----------
    columns : ndarray of shape (n_terms, n_states)
        Table column of every variable in every basis function (any
        non-negative integers below ``width``; 0 is the constant column).
    width : int
        Columns per table.
    """

    def __init__(self, columns, width):
        self.n_terms, self.n_states = columns.shape
        self.width = width
        ids = prefix_ids(columns)
        m = self.n_states
        #: Leaves: each function's prefix of length m - 1 and its last column.
        self.leaf_parent = ids[m - 1]
        self.leaf_column = columns[:, m - 1]
        self.n_prefixes = int(ids[m - 1].max(initial=0)) + 1
        #: levels[k] for k = 1 .. m - 1: nodes of length-k prefixes.
        self.levels = [None] + [Level(ids[k - 1], ids[k], columns[:, k - 1]) for k in range(1, m)]
        self._steps = {}

    @property
    def cost(self):
        """Multiply-adds per state and pattern: the matrix ``C`` plus the tree nodes."""
        return self.n_prefixes * self.width + sum(level.n_nodes for level in self.levels[1:])

    def bind(self, coef):
        """The coefficient matrix ``C`` of ``coef``: ndarray of shape (n_prefixes * K, width).

        Row ``p * K + k`` holds target ``k``'s coefficients of the functions
        with prefix ``p``, by the column of their last variable.

        Parameters
        ----------
        coef : ndarray of shape (n_terms,) or (n_terms, K)
            Coefficients of the basis functions.
        """
        coef = np.asarray(coef, dtype=float).reshape(self.n_terms, -1)
        K = coef.shape[1]
        C = np.zeros((self.n_prefixes, K, self.width))
        C[self.leaf_parent, :, self.leaf_column] = coef
        return C.reshape(self.n_prefixes * K, self.width)

    def _step(self, order):
        """Per level (from the leaves up): which products to form, in which order.

        A level multiplies the carried patterns of order at most ``order - r``
        (a leading slice, since patterns are sorted by order) by the ``r``-th
        derivative of the level's factor, for ``r = 0 .. order``. Returns, per
        level, ``(k, counts, r_index, p_index, keep)``: ``counts[r]`` patterns
        take derivative ``r``; product ``i`` (in that r-major order) is
        pattern ``p_index[i]`` times derivative ``r_index[i]``; ``keep``
        sorts the products by order (None when they already are).
        """
        if order not in self._steps:
            m = self.n_states
            patterns = [(m - 1,) * r for r in range(order + 1)]
            steps = []
            for k in range(m - 1, 0, -1):
                counts = [sum(1 for p in patterns if len(p) + r <= order) for r in range(order + 1)]
                made = [(r, i) for r in range(order + 1) for i in range(counts[r])]
                new = [patterns[i] + (k - 1,) * r for r, i in made]
                keep = np.argsort([len(q) for q in new], kind="stable")
                r_index = np.array([r for r, _ in made], dtype=np.intp)[keep]
                p_index = np.array([i for _, i in made], dtype=np.intp)[keep]
                identity = np.array_equal(keep, np.arange(keep.size))
                steps.append((k, counts, r_index, p_index, None if identity else keep))
                patterns = [new[i] for i in keep]
            self._steps[order] = (steps, patterns)
        return self._steps[order]

    def rows(self, order, wanted):
        """Rows of :meth:`contract`'s results holding the patterns ``wanted`` (cached)."""
        key = ("rows", order, tuple(wanted))
        if key not in self._steps:
            patterns = self._step(order)[1]
            self._steps[key] = np.array([patterns.index(p) for p in wanted], dtype=np.intp)
        return self._steps[key]

    def _padded(self, k):
        """Children of every node of level ``k - 1`` by column, ``n_nodes(k)`` where none (cached)."""
        key = ("padded", k)
        if key not in self._steps:
            level = self.levels[k]
            n_parents = level.starts.size
            index = np.full((n_parents, self.width), level.n_nodes, dtype=np.intp)
            index[level.parent, level.key] = np.arange(level.n_nodes)
            self._steps[key] = index
        return self._steps[key]

    def _incidence(self, k):
        """Sparse 0/1 matrix summing the nodes of level ``k`` into their parents (cached)."""
        key = ("incidence", k)
        if key not in self._steps:
            level = self.levels[k]
            self._steps[key] = sparse.csr_array(
                (np.ones(level.n_nodes), (level.parent, np.arange(level.n_nodes))),
                shape=(level.starts.size, level.n_nodes),
            )
        return self._steps[key]

    def contract(self, tables, C, order):
        """Value and derivatives of ``sum_j coef[j] phi_j`` up to ``order``.

        Parameters
        ----------
        tables : ndarray of shape (n_orders, n_states + 1, width, n_samples)
            Factor tables (see :mod:`.tables`) with at least ``order + 1``
            derivative orders.
        C : ndarray
            From :meth:`bind`.
        order : {0, 1, 2}
            Highest derivative order.

        Returns
        -------
        results : ndarray of shape (n_patterns, K, n_samples)
        patterns : list of tuple
            The derivative of each row of ``results``: ``()`` the value,
            ``(i,)`` d/dx_i, ``(i, j)`` d2/dx_i dx_j (i <= j), sorted by order.
        """
        n_samples = tables.shape[-1]
        tables = tables[: order + 1]
        steps, patterns = self._step(order)
        if n_samples == 1 and C.shape[0] == self.n_prefixes:
            return self._contract_one(tables[..., 0], C, steps), patterns
        if n_samples <= FEW_SAMPLES:
            return self._contract_few(tables, C, steps), patterns
        K = C.shape[0] // self.n_prefixes
        # Samples in chunks whose largest temporary stays cache-sized.
        per_sample = self.n_prefixes * K * (order + 1) ** 2 * 8
        chunk = max(FEW_SAMPLES + 1, CHUNK_BYTES // per_sample)
        if n_samples <= chunk:
            return self._contract_many(np.ascontiguousarray(tables), C, steps), patterns
        out = np.empty((len(patterns), K, n_samples))
        for start in range(0, n_samples, chunk):
            part = slice(start, start + chunk)
            # A contiguous copy of the chunk's tables: every gather below then
            # copies whole rows.
            chunk_tables = np.ascontiguousarray(tables[..., part])
            out[:, :, part] = self._contract_many(chunk_tables, C, steps)
        return out, patterns

    def _contract_many(self, tables, C, steps):
        """:meth:`contract` for many samples: patterns first, one sparse sum per product.

        Every array is (pattern, node, K, sample) and every operation reads
        and writes whole contiguous (node, K * sample) blocks: numpy is many
        times slower on strided slices of the same size. The large
        temporaries live in the thread's workspace.
        """
        m = self.n_states
        n_orders, n_samples = tables.shape[0], tables.shape[-1]
        K = C.shape[0] // self.n_prefixes
        # Sum the last variable for every derivative order: (order, prefix * K, sample).
        current = scratch("contract.leaves", (n_orders, self.n_prefixes, K, n_samples))
        np.matmul(C, tables[:, m - 1], out=current.reshape(n_orders, -1, n_samples))
        for k, counts, _, _, keep in steps:
            level = self.levels[k]
            incidence = self._incidence(k)
            factors = scratch("contract.factors", (n_orders, level.n_nodes, n_samples))
            for r in range(n_orders):
                np.take(tables[r, k - 1], level.key, axis=0, out=factors[r], mode="clip")
            products = scratch("contract.products", (counts[0], level.n_nodes, K, n_samples))
            new = np.empty((sum(counts), level.starts.size, K, n_samples))
            made = 0
            for r, count in enumerate(counts):
                np.multiply(current[:count], factors[r][None, :, None, :], out=products[:count])
                for i in range(count):
                    flat = products[i].reshape(level.n_nodes, K * n_samples)
                    new[made] = (incidence @ flat).reshape(-1, K, n_samples)
                    made += 1
            current = new if keep is None else new[keep]
        # With one variable there is no level: copy the results out of the
        # workspace, which the next call reuses (the caller keeps them).
        return current[:, 0] if steps else current[:, 0].copy()

    def adjoint(self, tables, weights, order):
        """The transpose of :meth:`contract`: ``sum_s sum_q weights[q, :, s] d^q phi_j(x_s)``.

        For the design ``A`` whose rows are the derivatives (patterns ``q``)
        of the basis at the samples, :meth:`contract` computes ``A c`` and
        this computes ``A^T w``: reverse mode through the same tree, ending in
        one matrix product over the samples.

        Parameters
        ----------
        tables : ndarray of shape (n_orders, n_states + 1, width, n_samples)
            Factor tables with at least ``order + 1`` derivative orders.
        weights : ndarray of shape (n_patterns, K, n_samples)
            One weight per pattern of :meth:`contract` (same order), target and
            sample.
        order : {0, 1, 2}
            Highest derivative order.

        Returns
        -------
        coef : ndarray of shape (n_terms, K)
        """
        n_samples = tables.shape[-1]
        tables = tables[: order + 1]
        steps, patterns = self._step(order)
        K = weights.shape[1]
        per_sample = self.n_prefixes * K * (order + 1) ** 2 * 8
        chunk = max(FEW_SAMPLES + 1, CHUNK_BYTES // per_sample)
        C_bar = np.zeros((self.n_prefixes * K, self.width))
        for start in range(0, n_samples, chunk):
            part = slice(start, start + chunk)
            self._adjoint_chunk(
                np.ascontiguousarray(tables[..., part]), np.ascontiguousarray(weights[..., part]),
                steps, C_bar,
            )
        return C_bar.reshape(self.n_prefixes, K, self.width)[
            self.leaf_parent, :, self.leaf_column
        ]

    def _adjoint_chunk(self, tables, weights, steps, C_bar):
        """Add one chunk of samples to the adjoint's coefficient matrix ``C_bar``."""
        m = self.n_states
        n_orders, n_samples = tables.shape[0], tables.shape[-1]
        K = weights.shape[1]
        bar = weights[:, None]  # (pattern, node = root, K, sample)
        for k, counts, _, _, keep in reversed(steps):
            level = self.levels[k]
            factors = scratch("adjoint.factors", (n_orders, level.n_nodes, n_samples))
            for r in range(n_orders):
                np.take(tables[r, k - 1], level.key, axis=0, out=factors[r], mode="clip")
            if keep is not None:
                unsorted = np.empty_like(bar)
                unsorted[keep] = bar
                bar = unsorted
            previous = np.zeros((counts[0], level.n_nodes, K, n_samples))
            made = 0
            for r, count in enumerate(counts):
                for i in range(count):
                    # Each child receives its parent's weight times its own factor.
                    spread = np.take(bar[made], level.parent, axis=0)
                    spread *= factors[r][:, None, :]
                    previous[i] += spread
                    made += 1
            bar = previous
        # bar: (order, prefix, K, sample); C_bar[p K + k, c] += sum_s bar T[r, m-1, c, s].
        for r in range(n_orders):
            C_bar += bar[r].reshape(-1, n_samples) @ tables[r, m - 1].T

    def _contract_one(self, tables, C, steps):
        """:meth:`contract` for one state and one target (a simulation's step): 2-D arrays only."""
        m = self.n_states
        current = np.zeros((tables.shape[0], self.n_prefixes + 1))
        np.matmul(tables[:, m - 1], C.T, out=current[:, :-1])
        for k, _, r_index, p_index, _ in steps:
            sums = current.take(self._padded(k), axis=1) @ tables[:, k - 1].T  # (pat, parents, orders)
            current = np.zeros((r_index.size, sums.shape[1] + 1))
            current[:, :-1] = sums[p_index, :, r_index]
        return current[:, :1, None]

    def _contract_few(self, tables, C, steps):
        """:meth:`contract` for a few samples: padded children, one matrix product per level.

        With samples first, summing the children of every node against the
        level's table is a small matrix product per sample; the number of
        numpy calls per level is fixed, which is what a single state pays for.
        """
        m = self.n_states
        n_orders, n_samples = tables.shape[0], tables.shape[-1]
        K = C.shape[0] // self.n_prefixes
        leaves = np.matmul(C, tables[:, m - 1]).reshape(n_orders, self.n_prefixes, K, n_samples)
        current = np.zeros((n_samples, K, n_orders, self.n_prefixes + 1))
        current[..., :-1] = leaves.transpose(3, 2, 0, 1)
        for k, _, r_index, p_index, _ in steps:
            children = np.take(current, self._padded(k), axis=3)  # (S, K, pat, parents, width)
            # Contiguous, or matmul takes a slow path (2.5x on 8 states).
            factors = np.ascontiguousarray(tables[:, k - 1].transpose(2, 1, 0))[:, None, None]
            sums = np.matmul(children, factors)  # (S, K, pat, parents, orders)
            n_parents = sums.shape[3]
            current = np.zeros((n_samples, K, r_index.size, n_parents + 1))
            current[..., :-1] = sums[:, :, p_index, :, r_index].transpose(1, 2, 0, 3)
        return current[..., 0].transpose(2, 1, 0)
