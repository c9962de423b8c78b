"""When and how a simulation runs as one compiled loop (plain numpy until called).

A model that can be simulated by the compiled path says so with a
:class:`KernelModel` in its :class:`~sk_hamiltonian._integrate.Dynamics`
(``Dynamics.compiled``); :func:`sk_hamiltonian._integrate.integrate` then
hands the whole run to :func:`integrate_compiled` when the kernels switch
allows numba and the integrator is one of the four known methods. The model
space becomes the kernels' arrays here (:mod:`sk_hamiltonian._space.compiled`);
the kernels themselves (:mod:`sk_hamiltonian._kernels`) only see arrays.
"""

import math

import numpy as np

from .. import _kernels
from .._space.compiled import bound_kernels, in_lanes, lane_kernels
from .._space.fourier import MIN_SEGMENT_NODES, PHASE_LIMITS
from .._threads import in_threads
from .avf import AveragedVectorField
from .rk4 import RK4
from .symplectic import Leapfrog, Yoshida4

# The methods the compiled loop knows, by class: a subclass (or someone
# else's method of the same name) takes its own steps.
METHOD_CODES = {RK4: 0, AveragedVectorField: 1, Leapfrog: 2, Yoshida4: 2}


class KernelModel:
    """What a compiled simulation needs from a fitted model.

    Parameters
    ----------
    kind : {"gradient", "value"}
        ``"gradient"``: a Hamiltonian, ``f = (J^{-1} - Gamma) grad H`` with
        ``H = sum_j coef[j] phi_j``; ``"value"``: a vector field, ``f_c =
        sum_j coef[j, c] phi_j``.
    space : ModelSpace
        The basis the field is evaluated in.
    coef : ndarray of shape (n_terms,) or (n_terms, n_states)
        Its coefficients.
    damping : ndarray of shape (n_states // 2,), default=None
        Linear damping of a Hamiltonian model.
    split : tuple, default=None
        ``((kinetic_space, kinetic_coef), (potential_space, potential_coef))``
        of a separable Hamiltonian, for the explicit symplectic methods.
    """

    def __init__(self, kind, space, coef, damping=None, split=None):
        self.kind = kind
        self.space = space
        self.coef = coef
        self.damping = damping
        self.split = split


def integrate_compiled(integrator, y0, t, max_step):
    """:func:`sk_hamiltonian._integrate.integrate` in one compiled call, or None where it does not apply."""
    model = integrator.dynamics.compiled
    code = METHOD_CODES.get(type(integrator))
    if code is None:
        return None  # a subclass, or a method of someone else's: its own steps
    if code == 2 and model.split is None:
        return None
    from .._kernels import _simulate_jit

    space = model.space
    m = space.n_states
    y0 = np.array(y0, dtype=float, order="C")
    t = np.asarray(t, dtype=float)
    n_times = t.shape[0]
    substeps = max_step is not None and math.isfinite(max_step)
    intervals = np.diff(t)
    n_sub = np.array(
        [max(1, math.ceil(dt / max_step - 1e-9)) if substeps else 1 for dt in intervals],
        dtype=np.int64,
    )
    h = intervals / np.maximum(n_sub, 1) if n_times > 1 else np.zeros(0)
    tree, C, flat = bound_kernels(space, model.coef)
    if code == 2:
        (kinetic, c_p), (potential, c_q) = model.split
        tree, C, flat = bound_kernels(potential, c_q)
        tree2, C2, flat2 = bound_kernels(kinetic, c_p)
        lf_weights = np.asarray(integrator.weights, dtype=float)
    else:
        tree2, C2, flat2, lf_weights = tree, C, flat, np.zeros(0)
    if code == 1:
        rules = avf_rules(integrator, m)
        rtol, max_iter = float(integrator.rtol), int(integrator.max_iter)
    else:
        rules = (np.zeros((1, 0)), np.zeros((1, 0)), np.zeros(1), np.zeros(m))
        rtol, max_iter = 0.0, 0
    gamma = np.zeros(m // 2) if model.damping is None else np.asarray(model.damping, dtype=float)
    wrap = integrator.dynamics.wrap is not None
    periodic = space.periodic.copy() if wrap else np.zeros(m, dtype=bool)
    low, high = space.domain[:, 0].copy(), space.domain[:, 1].copy()
    kind = 0 if model.kind == "gradient" else 1
    n_states = y0.shape[0]
    parts = {}
    if code == 0 and kind == 0 and in_lanes(space, model.coef, 1, n_states):
        # Many states of a Hamiltonian by RK4: in step, sharing each pass of
        # the field (_lanes_jit).
        _lanes_jit, lane_tree, children, leaf_coef = lane_kernels(space, model.coef)

        def run(rows, out, failed_at):
            _lanes_jit.rk4(lane_tree, children, leaf_coef, gamma, periodic, low, high,
                           np.ascontiguousarray(y0[rows]), n_sub, h, _kernels.lanes(rows.stop - rows.start),
                           out, failed_at)
    else:
        def run(rows, out, failed_at):
            _simulate_jit.integrate(
                code, kind, tree, C, flat, tree2, C2, flat2, gamma, lf_weights, rules, rtol, max_iter,
                periodic, low, high, np.ascontiguousarray(y0[rows]), n_sub, h, out, failed_at,
            )

    def part(rows):
        out = np.empty((n_times, rows.stop - rows.start, m))
        failed_at = np.empty(rows.stop - rows.start, dtype=np.int64)
        run(rows, out, failed_at)
        parts[rows.start] = (out, failed_at)

    # Long runs of many states: one chunk of states per core (about
    # PARALLEL_ROWS evaluations of the field per state and step make a chunk
    # worth a thread).
    n_steps = max(1, int(n_sub.sum()))
    in_threads(part, n_states, max(1, -(-_kernels.PARALLEL_ROWS * 64 // n_steps)))
    starts = sorted(parts)
    out = np.concatenate([parts[a][0] for a in starts], axis=1)
    failed_at = np.concatenate([parts[a][1] for a in starts])
    return out, failed_at.astype(np.intp)


def avf_rules(integrator, n_features):
    """Every quadrature rule a compiled AVF step may take, as arrays.

    Returns ``(nodes, weights, phase_limits, phase_rates)``. Row ``e`` of
    ``nodes`` and ``weights`` (zero-padded) is
    ``integrator.rule(phase)`` for the phases up to ``phase_limits[e]``:
    ``e`` nodes more than the rule of short segments. ``phase_rates`` gives a
    step's phase, ``phase_rates @ |y1 - y0|``. A polynomial model has one
    rule and zero rates.
    """
    nodes, weights = integrator.nodes, integrator.weights
    rates = integrator.dynamics.phase_rates
    if rates is None:
        return nodes[None].copy(), weights[None].copy(), np.zeros(1), np.zeros(n_features)
    phase_limits = PHASE_LIMITS[MIN_SEGMENT_NODES:]
    n_first, n_rules = nodes.size, phase_limits.size
    table = np.zeros((2, n_rules, n_first + n_rules - 1))
    for e, phase in enumerate(phase_limits):
        table[:, e, : n_first + e] = integrator.rule(phase)
    return table[0], table[1], phase_limits, np.array(rates, dtype=float)
