"""The averaged-vector-field method, which conserves a polynomial Hamiltonian exactly."""

import math

import numpy as np

from .base import FixedStepIntegrator


def apply_inverse_symplectic(g):
    """Return ``J^{-1} g`` for ``J = [[0, I], [-I, 0]]``, row by row.

    ``J^{-1} = [[0, -I], [I, 0]]``, so ``(p, q)``-gradients map to
    ``(-dH/dq, dH/dp)``: Hamilton's equations.
    """
    d = g.shape[-1] // 2
    return np.concatenate([-g[..., d:], g[..., :d]], axis=-1)


class AveragedVectorField(FixedStepIntegrator):
    """Averaged-vector-field (AVF) method for ``du/dt = J^{-1} grad H(u)``.

    One step solves ``y1 = y0 + h J^{-1} int_0^1 grad H(y0 + xi (y1 - y0)) dxi``.
    Because ``J^{-1}`` is skew, ``H(y1) = H(y0)`` exactly when the integral is
    exact. For a polynomial ``H`` of degree ``n`` the integrand has degree
    ``n - 1`` in ``xi``, so ``ceil(n / 2)`` Gauss-Legendre nodes make the
    quadrature exact, and the conservation holds to round-off at any step size.
    The implicit equation is solved by simplified Newton iterations with the
    matrix ``I - (h / 2) J^{-1} hess H(y0)`` until the update is at round-off.

    Parameters
    ----------
    grad : callable
        ``grad H``, mapping ``(n, n_features)`` to ``(n, n_features)``.
    hess : callable
        Hessian of ``H``, mapping ``(n, n_features)`` to
        ``(n, n_features, n_features)``.
    degree : int
        Polynomial degree of ``H``; sets the number of quadrature nodes.
    rtol : float, default=1e-14
        Newton stops when the update is below ``rtol`` times the state's size.
    max_iter : int, default=100
        Newton iterations before a step is declared failed.
    """

    conserves_energy = True

    def __init__(self, grad, hess, degree, rtol=1e-14, max_iter=100):
        self.grad = grad
        self.hess = hess
        self.rtol = rtol
        self.max_iter = max_iter
        nodes, weights = np.polynomial.legendre.leggauss(max(1, math.ceil(degree / 2)))
        self.nodes = 0.5 * (nodes + 1.0)
        self.weights = 0.5 * weights
        super().__init__(lambda y: apply_inverse_symplectic(grad(y)))

    def _averaged_gradient(self, y0, y1):
        n = y0.shape[0]
        diff = y1 - y0
        points = y0[None] + self.nodes[:, None, None] * diff[None]
        grads = self.grad(points.reshape(-1, y0.shape[1])).reshape(points.shape)
        return np.tensordot(self.weights, grads, axes=1).reshape(n, -1)

    def _step_impl(self, y, h):
        n_features = y.shape[1]
        jacobian = np.eye(n_features) - (0.5 * h) * apply_inverse_symplectic(
            np.swapaxes(self.hess(y), 1, 2)
        ).swapaxes(1, 2)
        with np.errstate(all="ignore"):
            newton_matrix = np.linalg.inv(jacobian)
        y1 = y + h * self.fun(y)
        scale = np.maximum(np.abs(y).max(axis=1), 1.0)
        converged = np.zeros(y.shape[0], dtype=bool)
        previous = np.full(y.shape[0], np.inf)
        for _ in range(self.max_iter):
            todo = ~converged
            residual = (
                y1[todo] - y[todo] - h * apply_inverse_symplectic(
                    self._averaged_gradient(y[todo], y1[todo])
                )
            )
            delta = np.einsum("bij,bj->bi", newton_matrix[todo], residual)
            y1[todo] -= delta
            size = np.abs(delta).max(axis=1)
            # Converged at the tolerance, or stalled at the round-off floor
            # (the update no longer shrinks and is already tiny).
            done = (size <= self.rtol * scale[todo]) | (
                (size >= 0.5 * previous[todo]) & (size <= 1e3 * self.rtol * scale[todo])
            )
            previous[todo] = size
            converged[np.flatnonzero(todo)[done]] = True
            if converged.all():
                break
        y1[~converged] = np.nan
        return y1
