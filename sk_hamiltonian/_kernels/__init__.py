"""Compiled kernels (numba), behind the narrow interface of the model space.

numba is optional (``pip install sk_hamiltonian[fast]``). Nothing here
imports it until a kernel is first asked for, and every caller checks
:func:`sk_hamiltonian._config.use_numba` first, so without numba the numpy
path runs exactly as before.

- :func:`contract`: value, gradient and Hessian of ``sum_j coef[j] phi_j``
  at many states (what :class:`~sk_hamiltonian._space.ModelSpace`'s
  ``value_dot``, ``gradient_dot`` and ``hessian_dot`` return);
- :func:`field`: a Hamiltonian's vector field at many states (what
  ``predict`` returns), the structure applied in the same compiled pass;
- both take batches of :data:`LANE_ROWS` states or more (value and gradient
  of one scalar) through the tree together (:mod:`._lanes_jit`), fewer
  state by state (:mod:`._jit`);
- :func:`checked_field`: the field at a few states with ``predict``'s checks,
  in one compiled call (:mod:`._checked_jit`);
- :mod:`.simulate`: whole fixed-step integrations as compiled loops;
- :mod:`.threads`: BLAS threads chosen by problem size.
"""

import threading

import numpy as np

from .packing import pack
from .threads import thread_pool

_NUMBA = None
_local = threading.local()
# Rows of a batch per thread from which the evaluation runs on every core
# (below, handing the work to threads costs more than it saves).
PARALLEL_ROWS = 256
# States from which a batch goes through the tree in lanes (_lanes_jit), and
# the most states per pass. Measured on the degree-15 model of
# benchmarks/bench_scale.py (3 875 terms, the field of 1 024 states, one
# thread, best of 25 timings of _lanes_jit.fields and _jit.fields, a scratch
# script, 2026-11-25): per state 5.2 us state by state; in lanes 3.5 us at
# 16 states per pass, 2.2 at 32, 1.75 at 64, 1.5 at 128 and 1.4 at 256
# (1.6-1.7 at 192, 320 and 512).
LANE_ROWS = 16
MAX_LANES = 256


def numba_available():
    """Whether numba can be imported (checked once per process)."""
    global _NUMBA
    if _NUMBA is None:
        try:
            import numba  # noqa: F401
        except Exception:  # ImportError, or a numba broken against this numpy
            _NUMBA = False
        else:
            _NUMBA = True
    return _NUMBA


_JIT = None
_CHECKED = None  # the module of checked_field's kernel, imported on first use


def _compiled():
    """The module of compiled kernels (imported, and numba with it, on first use)."""
    global _JIT
    if _JIT is None:
        from . import _jit

        _JIT = _jit
    return _JIT


def bound_kernels(space, coef):
    """The compiled kernels' view of ``space`` with ``coef`` bound to it.

    Returns ``(tree, bound, flat)``, cached on the space while ``coef``
    keeps its values (one comparison of the values for both bindings:
    :func:`~sk_hamiltonian._space.space.cached_binding`, so that changing
    ``coef`` in place is seen):

    - ``tree``: the arrays of :func:`.tree.tree_arrays` (cached on the space);
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
        from .tree import children_by_parent, tree_arrays

        arrays, order = tree_arrays(space)
        tree = space.__dict__["_kernel_tree"] = (arrays, order, children_by_parent(arrays))
    return tree


def _in_lanes(space, coef, order, n):
    """Whether :mod:`._lanes_jit` contracts these ``n`` states (see :data:`LANE_ROWS`).

    For the value and gradient of one scalar, where the space takes the
    tree (not flat products).
    """
    return (n >= LANE_ROWS and order <= 1 and space.n_terms > 0
            and (np.ndim(coef) == 1 or np.shape(coef)[1] == 1)
            and space._flat(order, kernels="numba") is None)


def _lanes(n):
    """States per pass for ``n`` states: at most MAX_LANES, in passes of about equal size.

    A multiple of 8 (the last pass repeats a state where that is more than
    ``n`` needs): rows of any other length end in a scalar remainder and
    straddle cache lines (measured: 125 lanes ran 1.3 times slower than
    120 or 128).
    """
    n_passes = -(-n // MAX_LANES)
    return min(MAX_LANES, 8 * -(-n // (8 * n_passes)))


def _lane_kernels(space, coef):
    """``(compiled module, tree, children, leaf_coef)``: the coefficients in leaf order, cached."""
    arrays, order, children = _tree(space)
    leaf_coef = space._binding(
        "lanes", coef, lambda coef: np.ascontiguousarray(np.asarray(coef, dtype=float).reshape(-1)[order]))
    from . import _lanes_jit

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
    if _in_lanes(space, coef, order, X.shape[0]):
        return _contract_in_lanes(space, X, coef, order)
    _jit, tree, bound, flat, X = _prepared(space, X, coef)
    n, m = X.shape
    K = bound.shape[1]
    value = np.empty((n, K))
    grad = np.empty((n, m, K)) if order >= 1 else np.empty((0, m, K))
    hess = np.empty((n, m, m, K)) if order >= 2 else np.empty((0, m, m, K))
    def part(rows):
        _jit.evaluate(X[rows], tree, bound, flat, order, value[rows], grad[rows] if order >= 1 else grad,
                      hess[rows] if order >= 2 else hess, *_work(tree, K, m))

    in_threads(part, n, PARALLEL_ROWS)
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
    if _in_lanes(space, coef, 1, n):
        # The structure applied in numpy, as the numpy path applies it (a few
        # operations per state, against thousands for the gradient; a
        # compiled copy would be one more contraction to compile).
        from .._integrate.avf import apply_structure

        return apply_structure(_contract_in_lanes(space, X, coef, 1)[1][:, :, 0], damping)
    gamma = np.zeros(m // 2) if damping is None else np.ascontiguousarray(damping, dtype=float)
    out = np.empty((n, m))
    _jit, tree, bound, flat, X = _prepared(space, X, coef)

    def part(rows):
        _jit.fields(0, X[rows], tree, bound, flat, gamma, out[rows], *_work(tree, 1, m))

    in_threads(part, n, PARALLEL_ROWS)
    return out


def checked_field(space, X, coef, damping, domain, periodic, slack):
    """:func:`field` at a few states, with ``predict``'s checks in the same compiled call.

    One compiled call of 14 arguments (:mod:`._checked_jit`), for
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
        from . import _checked_jit

        _CHECKED = _checked_jit
    out = np.empty(X.shape)
    checks = (0, X, coef, domain, periodic, slack, damping)
    work = _work(_tree(space)[0], 1, X.shape[1])
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
    """:func:`contract` by :mod:`._lanes_jit` (see :func:`_in_lanes`)."""
    _lanes_jit, tree, children, leaf_coef = _lane_kernels(space, coef)
    X = np.ascontiguousarray(X, dtype=float)
    n, m = X.shape
    value = np.empty(n)
    grad = np.empty((n, m)) if order >= 1 else np.empty((0, m))

    def part(rows):
        _lanes_jit.evaluate(X[rows], tree, children, leaf_coef, order, _lanes(rows.stop - rows.start),
                            value[rows], grad[rows] if order >= 1 else grad)

    in_threads(part, n, PARALLEL_ROWS)
    return value[:, None], (grad[:, :, None] if order >= 1 else None), None


def _prepared(space, X, coef):
    """The compiled kernels, ``bound_kernels(space, coef)`` and ``X`` as they take it (C-ordered floats)."""
    return (_compiled(), *bound_kernels(space, coef), np.ascontiguousarray(X, dtype=float))


def _work(tree, K, m):
    """This thread's work arrays for ``tree`` and ``K`` targets (kept between calls)."""
    cache = getattr(_local, "work", None)
    if cache is None:
        cache = _local.work = {}
    key = (id(tree), K)
    entry = cache.get(key)
    if entry is None or entry[0] is not tree:
        if len(cache) >= 16:
            cache.clear()
        entry = cache[key] = (tree, _compiled().work(tree, K, m))
    return entry[1]


def in_threads(part, n, minimum):
    """``part(rows)`` over ``n`` rows: in one slice, or one slice per core from ``minimum`` rows.

    The compiled kernels release the GIL, so threads run them in parallel
    (no numba threading layer: nothing to go wrong in forked workers). At
    most ``numba.get_num_threads()`` threads.
    """
    if n < 2 * minimum:  # one slice, whatever the thread count
        part(slice(0, n))
        return
    import numba

    # numba's thread count (NUMBA_NUM_THREADS, numba.set_num_threads), all
    # cores by default, is the knob users of numba know.
    n_threads = min(numba.get_num_threads(), n // max(1, minimum))
    if n_threads <= 1:
        part(slice(0, n))
        return
    bounds = np.linspace(0, n, n_threads + 1).astype(int)
    futures = [thread_pool().submit(part, slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:])]
    for future in futures:
        future.result()
