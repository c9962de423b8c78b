"""The compiled path of a model space: its arrays for the kernels, and their calls.

:mod:`sk_hamiltonian._kernels` takes arrays and returns arrays; here a
:class:`~.space.ModelSpace` and its coefficients become those arrays (the
prefix tree of :mod:`.kernel_tree` and the coefficients bound to it, cached
on the space) and the kernels' results the shapes the space's numpy path
returns. Whether this path runs at all is decided by the callers
(:meth:`~.space.ModelSpace.value_dot` and its siblings, the learned
Hamiltonian's ``predict``) with :func:`sk_hamiltonian._config.use_numba`.

- :func:`contract`: value, gradient and Hessian of ``sum_j coef[j] phi_j``
  at many states;
- :func:`field`: a Hamiltonian's vector field at many states (what
  ``predict`` returns), the structure applied in the same compiled pass;
- both take batches of :data:`~sk_hamiltonian._kernels.LANE_ROWS` states or
  more (value and gradient of one scalar) through the tree together, fewer
  state by state;
- :func:`checked_field`: the field at a few states with ``predict``'s checks,
  in one compiled call.
"""

import numpy as np

from .. import _kernels
from .._kernels.packing import pack
from .._structure import apply_structure
from .._threads import in_threads

_CHECKED = None  # the module of checked_field's kernel, imported on first use


def bound_kernels(space, coef):
    """The compiled kernels' view of ``space`` with ``coef`` bound to it.

    Returns ``(tree, bound, flat)``, cached on the space while ``coef``
    keeps its values (one comparison of the values for both bindings:
    :func:`~sk_hamiltonian._space.space.cached_binding`, so that changing
    ``coef`` in place is seen):

    - ``tree``: the arrays of :func:`.kernel_tree.tree_arrays` (cached on the space);
    - ``bound``: the coefficients bound to the tree, a dense (width, K,
      n_prefixes) array: ``[c, k, p]`` is target ``k``'s coefficient of the
      function with prefix ``p`` and last column ``c``;
    - ``flat``: the flat contractions, ``(use, keys0, rows0, W0, keys1,
      rows1, W1, keys2, rows2, W2)``: for each derivative order, whether the
      space contracts it flat (:meth:`ModelSpace._flat`), the functions'
      keys into the compiled work table, the row of the root's results each
      adds to (0: the value; ``1 + i``: d/dx_i; ``1 + m + i m + j``: d2/dx_i
      dx_j) and its coefficients (n_functions, K). Orders contracted by the
      tree get empty arrays.
    """
    arrays, order, _ = _tree(space)

    def bind(coef):
        coef2 = np.asarray(coef, dtype=float).reshape(space.n_terms, -1)
        return _bind_tree(arrays, order, coef2), _bind_flat(space, coef2)

    bound, flat = space._binding("jit", coef, bind)
    return arrays, bound, flat


def _tree(space):
    """``(tree_arrays, leaf order, children_by_parent)`` of ``space``, built once (not pickled)."""
    tree = space.__dict__.get("_kernel_tree")
    if tree is None:
        from .kernel_tree import children_by_parent, tree_arrays

        arrays, order = tree_arrays(space)
        tree = space.__dict__["_kernel_tree"] = (arrays, order, children_by_parent(arrays))
    return tree


def in_lanes(space, coef, order, n):
    """Whether the lanes kernels contract these ``n`` states (see :data:`~sk_hamiltonian._kernels.LANE_ROWS`).

    For the value and gradient of one scalar, where the space takes the
    tree (not flat products).
    """
    return (n >= _kernels.LANE_ROWS and order <= 1 and space.n_terms > 0
            and (np.ndim(coef) == 1 or np.shape(coef)[1] == 1)
            and space._flat(order, kernels="numba") is None)


def lane_kernels(space, coef):
    """``(compiled module, tree, children, leaf_coef)``: the coefficients in leaf order, cached."""
    arrays, order, children = _tree(space)
    leaf_coef = space._binding(
        "lanes", coef, lambda coef: np.ascontiguousarray(np.asarray(coef, dtype=float).reshape(-1)[order]))
    from .._kernels import _lanes_jit

    return _lanes_jit, arrays, children, leaf_coef


def _bind_tree(arrays, order, coef2):
    leaf_start, leaf_column = arrays[4], arrays[5]
    n_prefixes = leaf_start.size - 1
    leaf_parent = np.repeat(np.arange(n_prefixes), np.diff(leaf_start))
    # Dense (width, K, n_prefixes): the leaves are then a few vectorized
    # passes over the prefixes, with no branch per prefix.
    bound = np.zeros((arrays[10], coef2.shape[1], n_prefixes))
    bound[leaf_column, :, leaf_parent] = coef2[order]
    return bound


def _bind_flat(space, coef2):
    m = space.n_states
    use = np.zeros(3, dtype=np.bool_)
    parts = []
    for order in range(3):
        flat = space._flat(order, kernels="numba")
        if flat is None:
            parts += [np.zeros((0, 1), np.int64), np.zeros(0, np.int64),
                      np.zeros((0, coef2.shape[1]))]
            continue
        use[order] = True
        q = flat.patterns
        row = [0] if order == 0 else (
            [1 + p[0] for p in q] if order == 1 else [1 + m + i * m + j for i, j in q])
        parts += [np.ascontiguousarray(flat.jit_keys),
                  np.asarray(row, dtype=np.int64)[flat.pattern],
                  np.ascontiguousarray(coef2[flat.terms])]
    return (use, *parts)


def contract(space, X, coef, order):
    """Value, gradient and Hessian of ``sum_j coef[j] phi_j`` at the rows of ``X``.

    Parameters
    ----------
    space : ModelSpace
        The basis.
    X : ndarray of shape (n_samples, n_states)
        States.
    coef : ndarray of shape (n_terms,) or (n_terms, K)
        Coefficients.
    order : {0, 1, 2}
        Highest derivative order.

    Returns
    -------
    value : ndarray of shape (n_samples, K)
    grad : ndarray of shape (n_samples, n_states, K) or None (order 0)
    hess : ndarray of shape (n_samples, n_states, n_states, K) or None (order < 2)
    """
    if in_lanes(space, coef, order, X.shape[0]):
        return _contract_in_lanes(space, X, coef, order)
    _jit, tree, bound, flat, X = _prepared(space, X, coef)
    n, m = X.shape
    K = bound.shape[1]
    value = np.empty((n, K))
    grad = np.empty((n, m, K)) if order >= 1 else np.empty((0, m, K))
    hess = np.empty((n, m, m, K)) if order >= 2 else np.empty((0, m, m, K))
    def part(rows):
        _jit.evaluate(X[rows], tree, bound, flat, order, value[rows], grad[rows] if order >= 1 else grad,
                      hess[rows] if order >= 2 else hess, *_kernels.work(tree, K, m))

    in_threads(part, n, _kernels.PARALLEL_ROWS)
    return value, (grad if order >= 1 else None), (hess if order >= 2 else None)


def field(space, X, coef, damping=None):
    """The vector field ``(J^{-1} - Gamma) grad H`` of a Hamiltonian at the rows of ``X``.

    The structure and damping are applied in the compiled pass that
    contracts the gradient.

    Parameters
    ----------
    space : ModelSpace
        The basis.
    X : ndarray of shape (n_samples, n_states)
        States.
    coef : ndarray of shape (n_terms,)
        Coefficients of ``H = sum_j coef[j] phi_j``.
    damping : ndarray of shape (n_states // 2,), default=None
        ``Gamma``'s diagonal.

    Returns
    -------
    dXdt : ndarray of shape (n_samples, n_states)
    """
    n, m = X.shape
    if in_lanes(space, coef, 1, n):
        # The structure applied in numpy, as the numpy path applies it (a few
        # operations per state, against thousands for the gradient; a
        # compiled copy would be one more contraction to compile).
        return apply_structure(_contract_in_lanes(space, X, coef, 1)[1][:, :, 0], damping)
    gamma = np.zeros(m // 2) if damping is None else np.ascontiguousarray(damping, dtype=float)
    out = np.empty((n, m))
    _jit, tree, bound, flat, X = _prepared(space, X, coef)

    def part(rows):
        _jit.fields(0, X[rows], tree, bound, flat, gamma, out[rows], *_kernels.work(tree, 1, m))

    in_threads(part, n, _kernels.PARALLEL_ROWS)
    return out


def checked_field(space, X, coef, damping, domain, periodic, slack):
    """:func:`field` at a few states, with ``predict``'s checks in the same compiled call.

    One compiled call of 14 arguments (:mod:`sk_hamiltonian._kernels._checked_jit`), for
    predictions of one state at a time (a user's own integrator, a
    callback): no comparison of the coefficients in Python, no numpy call
    per check.

    Parameters
    ----------
    space : ModelSpace
        The basis (contracted by its tree or flat, as :func:`field`).
    X : ndarray of shape (n_samples, n_states)
        States, C-ordered float64.
    coef : ndarray of shape (n_terms,)
        Coefficients of ``H``, C-ordered float64.
    damping : ndarray of shape (n_states // 2,)
        ``Gamma``'s diagonal, C-ordered float64 (zeros for none).
    domain : ndarray of shape (n_states, 2)
        The box of the domain check, C-ordered float64.
    periodic : ndarray of shape (n_states,) of bool
        Variables never outside the box.
    slack : float
        Tolerance of the domain check, relative to each interval's width
        (as :func:`sk_hamiltonian._space.space.count_outside`).

    Returns
    -------
    result : tuple or None
        ``(dXdt, n_outside)``: the field and the number of rows outside the
        box; None where ``X`` has a NaN or an infinity (nothing computed:
        the caller's validation says what is wrong).
    """
    global _CHECKED
    if _CHECKED is None:
        from .._kernels import _checked_jit

        _CHECKED = _checked_jit
    out = np.empty(X.shape)
    checks = (0, X, coef, domain, periodic, slack, damping)
    work = _kernels.work(_tree(space)[0], 1, X.shape[1])
    packed = space.__dict__.get("_checked_kernel")
    status = _CHECKED.STALE
    if packed is not None:
        status = _CHECKED.checked_fields(*checks, *packed, *work, out)
    if status == _CHECKED.STALE:
        # First call, or coefficients other than those packed: pack anew.
        tree, bound, flat = bound_kernels(space, coef)
        packed = space.__dict__["_checked_kernel"] = pack([*tree, bound, *flat, coef.copy()])
        status = _CHECKED.checked_fields(*checks, *packed, *work, out)
    if status == _CHECKED.NOT_FINITE:
        return None
    return out, status


def _contract_in_lanes(space, X, coef, order):
    """:func:`contract` by :mod:`sk_hamiltonian._kernels._lanes_jit` (see :func:`in_lanes`)."""
    _lanes_jit, tree, children, leaf_coef = lane_kernels(space, coef)
    X = np.ascontiguousarray(X, dtype=float)
    n, m = X.shape
    value = np.empty(n)
    grad = np.empty((n, m)) if order >= 1 else np.empty((0, m))

    def part(rows):
        _lanes_jit.evaluate(X[rows], tree, children, leaf_coef, order, _kernels.lanes(rows.stop - rows.start),
                            value[rows], grad[rows] if order >= 1 else grad)

    in_threads(part, n, _kernels.PARALLEL_ROWS)
    return value[:, None], (grad[:, :, None] if order >= 1 else None), None


def _prepared(space, X, coef):
    """The compiled kernels, ``bound_kernels(space, coef)`` and ``X`` as they take it (C-ordered floats)."""
    return (_kernels.jit(), *bound_kernels(space, coef), np.ascontiguousarray(X, dtype=float))
