"""The non-structure-preserving baseline: fit each component of the vector field."""

import numpy as np

from ._base import BaseTrajectoryRegressor
from ._design import quadrature_nodes
from ._integrate import Dynamics
from ._integrate.compiled import KernelModel
from ._least_squares import VectorFieldDesign
from ._space import ModelSpace


class VectorFieldRegressor(BaseTrajectoryRegressor):
    """Component-wise regression of the vector field (the non-SP baseline).

    Each component of ``dx/dt = f(x)`` is fitted separately by least squares in
    the same tensor-product space as :class:`HamiltonianRegressor` (constant
    included), as in Wu & Xiu (2018). The learned system is in general not
    Hamiltonian and conserves nothing; it is the baseline every comparison of
    the paper uses, and it takes the same model-space parameters so that
    comparisons stay fair.

    Unlike :class:`HamiltonianRegressor` it is a general regressor: the number
    of state variables need not be even (unless ``momentum_degree`` or
    ``separable`` is used) and, used on 2-D ``X``, the targets ``y`` may be any
    1-D or 2-D array. With fewer samples than basis functions it returns the
    minimum-norm least-squares solution, with an
    :class:`~sk_hamiltonian.IllConditionedWarning`. :meth:`simulate` requires
    ``y`` to have been the time derivatives of ``X``.

    Parameters
    ----------
    degree : int, default=3
        Largest total degree ``n`` of each component. Unknowns with the
        defaults: ``2d * C(n + 2d, 2d)``.
    domain : array-like of shape (n_states, 2), default=None
        The box carrying the basis (one period for periodic variables); None
        uses the bounding box of the training states, and ``[-pi, pi)`` for
        periodic variables.
    periodic : array-like of shape (n_states,) of bool, default=None
        Angles, with a trigonometric basis; as in :class:`HamiltonianRegressor`.
    mixed : array-like of shape (n_states,) of bool, default=None
        Variables with Fourier terms of period ``2 pi`` beside their
        polynomials; as in :class:`HamiltonianRegressor`.
    momentum_degree : int, default=None
        Largest total degree in the momenta (the first half of the variables)
        of each component; None: no limit.
    separable : bool, default=False
        No basis function mixes momenta and positions.
    max_interaction : int, default=None
        Most state variables one basis function depends on; None: no limit.
    couplings : list of sequences of int, default=None
        Groups of state variables that may share a basis function, as in
        :class:`HamiltonianRegressor`; None: any variables may.
    fit_on : {"derivatives", "steps", "simpson", "weak"}, default="derivatives"
        ``"steps"``: fit ``x1 - x0 = dt int_0^1 f(x0 + s (x1 - x0)) ds`` on the
        observed steps instead of estimated derivatives (derivative layout
        input only), the counterpart of the structure-preserving steps fit.
        ``"simpson"``: fit ``x2 - x0`` over each pair of consecutive steps
        with Simpson's rule for the integral of ``f`` (exact to
        ``O(dt**4)``; at least three samples per trajectory). ``"weak"``: the
        weak form over windows of samples, as in
        :class:`HamiltonianRegressor`.
    threshold : float, default=0.0
        Sparsity threshold, as in :class:`HamiltonianRegressor`, applied to
        each component separately (SINDy's sequentially thresholded least
        squares, in this library and the readable basis of monomials and
        angles). 0 fits every basis function.
    solver : {"auto", "lstsq", "normal", "iterative", "sketch"}, default="auto"
        As in :class:`HamiltonianRegressor`.
    verbose : int, default=0
        Print the progress of long fits when positive.
    n_resamples : int, default=0
        Refits on this many resamples of whole trajectories (derivative
        layout input only), each component with the same ``threshold``; as
        in :class:`HamiltonianRegressor`. 0: no resampling.
    resample : {"bootstrap", "subsample"}, default="bootstrap"
        Trajectories drawn with replacement, or half of them without.
    random_state : int, RandomState instance or None, default=None
        Seed of the resamples' draws.
    n_jobs : int, default=None
        Threads solving the resamples' refits; None means 1.

    Attributes
    ----------
    coef_ : ndarray of shape (n_basis, n_outputs) or (n_basis,)
        Column ``i`` holds the coefficients of output ``i`` (of component ``i``
        of the vector field); 1-D when ``y`` was 1-D.
    powers_ : ndarray of shape (n_basis, n_states)
        Multi-indices, the constant first (signed frequencies for periodic
        variables, as in :class:`HamiltonianRegressor`).
    periodic_ : ndarray of shape (n_states,) of bool
        Which variables are periodic.
    mixed_ : ndarray of shape (n_states,) of bool
        Which variables are mixed.
    domain_ : ndarray of shape (n_states, 2)
        The box the basis lives on.
    resampled_coef_ : ndarray of shape (n_resamples, n_basis, n_outputs) or (n_resamples, n_basis)
        With ``n_resamples > 0``: each refit's coefficients on a resample of
        the trajectories (zero off its support).
    cond_ : float
        Condition number of the column-equilibrated least-squares design
        (estimated with ``solver="iterative"`` or ``"sketch"`` and beyond
        1 500 unknowns with ``"normal"``).
    rank_ : int
        Numerical rank of that design.
    support_ : ndarray of the shape of ``coef_`` of bool
        Basis functions with a coefficient, per component; all True with
        ``threshold=0``.
    n_terms_ : int
        Number of fitted coefficients: ``coef_.size``, or with a threshold the
        kept readable terms summed over the components.
    n_iter_ : int
        Least-squares solves of the thresholded fit (the most over the
        components; 1 with ``threshold=0``).
    solver_ : str
        The solver used (``"normal"`` after :meth:`partial_fit` or a fit on
        dask arrays).
    dt_ : float
        Median time step of the training trajectories (NaN for 2-D input).
    time_scale_ : float
        ``1 / rho``, rho the 90th percentile of the spectral radius of the
        learned field's Jacobian over the training states (NaN when ``y`` was
        not the time derivative of ``X``); sets the default integration step.
    state_scale_ : ndarray of shape (n_states,)
        Standard deviation of each state variable over the training states.
    n_features_in_ : int
        Number of state variables.
    feature_names_in_ : ndarray of shape (`n_features_in_`,)
        Names of the state variables, when ``X`` had string column names.

    See Also
    --------
    HamiltonianRegressor : The structure-preserving method.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import VectorFieldRegressor
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-1, 1, size=(200, 2))
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])
    >>> model = VectorFieldRegressor(degree=1).fit(X, y)
    >>> np.round(model.predict([[0.5, 0.25]]), 6)
    array([[-0.25,  0.5 ]])
    """

    _include_constant = True

    def _design(self, space):
        return VectorFieldDesign(space, self.fit_on)

    def _set_coef(self, coef):
        self.coef_ = coef

    def _resampled_field(self):
        """``field(Y, models)``: the vector fields of the refits ``models`` at the rows of ``Y``."""
        self._dynamics()  # refuses a model that is no vector field
        coef = self.resampled_coef_
        rows = np.any(coef != 0, axis=(0, 2))
        space = ModelSpace(self.domain_, self.powers_[rows], self.periodic_, self._mixed())
        coef = coef[:, rows]

        def field(Y, models):
            return np.einsum("sj,sjc->sc", space.values(Y), coef[models])

        return field

    def _vector_field(self, X):
        space = self._eval_space
        return self._in_blocks(
            X, lambda B: space.value_dot(B, self._eval_coef), space.n_terms * space.layout.n_slots
        )

    def _is_vector_field(self):
        return self.coef_.ndim == 2 and self.coef_.shape[1] == self.n_features_in_

    def _jacobian(self, X):
        if not self._is_vector_field():
            return None
        # J[s, c, i] = d f_c / d x_i = sum_j coef[j, c] d_i phi_j.
        return np.einsum("sij,jc->sci", self._eval_space.gradients(X), self._eval_coef)

    def _dynamics(self):
        if not self._is_vector_field():
            raise ValueError(
                "simulate needs a vector field: fit with y the time derivatives of X "
                f"({self.n_features_in_} outputs); this model was fitted with "
                f"{1 if self.coef_.ndim == 1 else self.coef_.shape[1]} output(s)."
            )
        return Dynamics(
            self._vector_field, jacobian=self._jacobian,
            n_nodes=quadrature_nodes(self._eval_space, of_gradient=False),
            phase_rates=self._eval_space.phase_rates if self._eval_space.has_fourier else None,
            wrap=self._space.wrap if self.periodic_.any() else None,
            compiled=KernelModel("value", self._eval_space, self._eval_coef),
        )
