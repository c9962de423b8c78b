"""Hamilton's equations as a map of gradients: ``J^{-1}``, and ``J^{-1} - Gamma`` with damping.

A leaf of plain numpy, shared by the learned models (their vector field and
Jacobian), the known systems of :mod:`.datasets`, the integrators and the
compiled path (which applies the same map to the gradients it contracts).
"""

import numpy as np


def apply_inverse_symplectic(g):
    """Return ``J^{-1} g`` for ``J = [[0, I], [-I, 0]]``, row by row.

    ``J^{-1} = [[0, -I], [I, 0]]``, so ``(p, q)``-gradients map to
    ``(-dH/dq, dH/dp)``: Hamilton's equations.
    """
    d = g.shape[-1] // 2
    # Two ufunc calls into one buffer: a simulation calls this at every stage,
    # where ``np.concatenate`` of a list costs more than the arithmetic.
    out = np.empty_like(g)
    np.negative(g[..., d:], out=out[..., :d])
    out[..., d:] = g[..., :d]
    return out


def apply_structure(g, damping=None):
    """``(J^{-1} - Gamma) g``: Hamilton's equations with linear damping, row by row.

    The momentum rows get ``-dH/dq - gamma * dH/dp``, the position rows
    ``dH/dp``. Without damping this is :func:`apply_inverse_symplectic`.
    """
    out = apply_inverse_symplectic(g)
    if damping is not None:
        d = g.shape[-1] // 2
        out[..., :d] -= damping * g[..., :d]
    return out
