"""The kept terms of a fitted HamiltonianRegressor as the parameters of a trajectory fit.

The terms are those of the readable form (monomials, ``cos``, ``sin``), the
constant aside: the fit moves their coefficients, and the friction of a model
fitted with ``damping=True`` (kept non-negative), and nothing else. The
fitting-basis coefficients follow through ``to_fitting``, which touches only
the kept terms' lower-degree companions on the box.
"""

import numpy as np

from .._inspection.terms import term_scales
from .._space import tensor
from .._space.space import ModelSpace
from .solver import FlowModel

# Kept terms beyond which the trajectory fit is not run: its sensitivities
# cost (n_samples x n_states x n_terms) per step, and a model of that many
# terms is not the sparse law the fit is for. Up to two degrees of freedom
# the cap is MAX_TERMS; beyond, TERMS_PER_STATE per state variable, since a
# sparse law of a chain or network has a few terms per variable (the FPU
# chain of eight particles keeps 52, and its trajectory fit is ten times
# more accurate at T = 20 than least squares).
MAX_TERMS = 40
TERMS_PER_STATE = 10
# Relative size below which a readable coefficient is round-off of a zero.
ROUND_OFF = 1e-10


def max_terms(n_states):
    """The most kept terms the trajectory fit takes for states of ``n_states`` variables."""
    return max(MAX_TERMS, TERMS_PER_STATE * n_states)


class KeptTerms:
    """The readable kept terms of a fitted regressor: a :class:`~.solver.FlowModel` and its start.

    Parameters
    ----------
    regressor : HamiltonianRegressor
        Fitted.

    Attributes
    ----------
    reason : str or None
        Why the terms cannot be fitted to trajectories (no term, or more than
        :func:`max_terms` of the state variables); None when they can.
    n_terms : int
        Number of kept readable terms, the constant aside.
    model : FlowModel
        The flow of ``H = sum_j theta_j term_j`` (and the friction).
    start : ndarray
        The regressor's coefficients of the kept terms, then its friction.
    key : bytes
        Identifies the kept terms (the same for two regressors of one space
        and box that keep the same readable terms).
    """

    def __init__(self, regressor):
        space = regressor._space
        readable = space.readable_basis()
        values = readable.from_fitting @ regressor.coef_
        nonconstant = np.any(space.powers != 0, axis=1)
        # The fit keeps terms in the readable basis; mapped back from the
        # fitting basis, the others come out at round-off, not at zero. Sizes
        # in the data, not raw coefficients, tell them apart: with positions
        # in thousandths, the spring's q^4 reads 2.5e-10 beside p^2's 500.
        size = np.abs(values) * term_scales(space.powers, regressor._state_magnitude,
                                            space.periodic)
        kept = size > ROUND_OFF * np.max(size, initial=0.0)
        self.terms = np.flatnonzero(kept & nonconstant)
        self.n_terms = len(self.terms)
        self.reason = None
        limit = max_terms(space.n_states)
        if self.n_terms == 0:
            self.reason = "no term to refine"
        elif self.n_terms > limit:
            self.reason = (f"{self.n_terms} terms, more than {limit} "
                           f"for {space.n_states} state variables")
        self.key = np.sort(self.terms).tobytes()
        self.damped = bool(regressor.damping)
        self.theta0 = values[self.terms]
        self.start = (np.concatenate([self.theta0, regressor.damping_]) if self.damped
                      else self.theta0)
        if self.reason is not None:
            return
        self.to_fitting = readable.to_fitting[:, self.terms].toarray()
        self.rows = np.any(self.to_fitting != 0, axis=1)
        sub = ModelSpace(space.domain, space.powers[self.rows], space.periodic, space.mixed)
        columns = self.to_fitting[self.rows]
        self.model = FlowModel(
            gradients=lambda X: sub.gradients(X) @ columns,
            hessian=lambda X, theta: sub.hessian_dot(X, columns @ theta),
            wrap_difference=sub.wrap_difference,
            n_damped=len(regressor.damping_) if self.damped else 0,
            gradients_and_hessian=_from_one_table(sub, columns),
        )

    def fitting_covariance(self, covariance, n_basis):
        """A covariance of the parameters as that of ``coef_`` (then the friction).

        ``coef_`` moves by ``to_fitting @ theta``, so its covariance is
        ``to_fitting Sigma to_fitting^T``; the friction's block follows.
        Returns an array of shape (n_basis + n_friction,) * 2.
        """
        n_theta = len(self.theta0)
        n_friction = covariance.shape[0] - n_theta
        T = np.zeros((n_basis + n_friction, n_theta + n_friction))
        T[:n_basis, :n_theta] = self.to_fitting
        T[n_basis:, n_theta:] = np.eye(n_friction)
        return T @ covariance @ T.T

    def apply(self, regressor, params):
        """Set ``params`` (coefficients, then friction) as the regressor's, in place.

        Returns the largest relative change of a kept coefficient.
        """
        theta, friction = self.model.split(params)
        regressor.coef_ = regressor.coef_ + self.to_fitting @ (theta - self.theta0)
        if self.damped:
            regressor.damping_ = friction
        regressor.support_ = regressor.support_ | self.rows
        regressor._rebuild_fitted()
        change = float(np.max(np.abs(theta - self.theta0) / np.abs(self.theta0)))
        self.theta0 = theta
        return change


def _from_one_table(space, columns):
    """``both(X, theta)``: the terms' gradients and the Hessian of ``H``, from one table of ``X``.

    The sensitivities need both at every stage of every step; one evaluation
    of the factor tables serves them (it is most of their cost).
    """
    def both(X, theta):
        tables = space.factor_tables(X, 2)
        gradients = np.transpose(tensor.gradients(tables, space.layout), (2, 1, 0)) @ columns
        hessian = tensor.hessian_dot(tables, space.layout, columns @ theta)
        return gradients, np.moveaxis(hessian, -1, 0)

    return both
