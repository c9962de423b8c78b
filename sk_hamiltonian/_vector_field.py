"""The non-structure-preserving baseline: fit each component of the vector field."""


from ._base import BaseTrajectoryRegressor
from ._basis import n_basis_functions, total_degree_powers, value_matrix
from ._integrate import METHODS
from ._solvers import solve_dense, solve_streaming


class VectorFieldRegressor(BaseTrajectoryRegressor):
    """Component-wise polynomial regression of the vector field (non-SP baseline).

    Each component of ``dx/dt = f(x)`` is fitted separately by least squares in
    the same total-degree tensor Legendre space as :class:`HamiltonianRegressor`
    (constant included), as in Wu & Xiu (2018). The learned system is in
    general not Hamiltonian and conserves nothing; it is the baseline every
    comparison of the paper uses.

    Unlike :class:`HamiltonianRegressor` it is a general polynomial regressor:
    the number of state variables need not be even and, used on 2-D ``X``, the
    targets ``y`` may be any 1-D or 2-D array. :meth:`simulate` requires ``y``
    to have been the time derivatives of ``X``.

    Parameters
    ----------
    degree : int, default=3
        Total degree ``n`` of each component. Unknowns:
        ``2d * C(n + 2d, 2d)``.
    domain : array-like of shape (n_states, 2), default=None
        The box carrying the Legendre basis; None uses the bounding box of the
        training states.
    solver : {"auto", "lstsq", "normal"}, default="auto"
        As in :class:`HamiltonianRegressor`.

    Attributes
    ----------
    coef_ : ndarray of shape (n_basis, n_outputs) or (n_basis,)
        Column ``i`` holds the coefficients of output ``i`` (of component ``i``
        of the vector field); 1-D when ``y`` was 1-D.
    powers_ : ndarray of shape (n_basis, n_states)
        Multi-indices, the constant first.
    domain_ : ndarray of shape (n_states, 2)
        The box the basis lives on.
    cond_ : float
        Condition number of the column-equilibrated design.
    rank_ : int
        Numerical rank of that design.
    n_terms_ : int
        Number of fitted coefficients, ``coef_.size``.
    solver_ : str
        The solver used.
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

    _parameter_constraints = {**BaseTrajectoryRegressor._parameter_constraints}

    def _design_shape(self, n_samples, n_states):
        return n_samples, n_basis_functions(n_states, self.degree, include_constant=True)

    def _fit_coef(self, X, y):
        self.powers_ = total_degree_powers(X.shape[1], self.degree, include_constant=True)
        if self.solver_ == "lstsq":
            A = value_matrix(X, self.domain_, self.powers_)
            self.coef_, self.cond_, self.rank_ = solve_dense(A, y)
            return
        rows = max(1, 20_000_000 // self.powers_.shape[0])
        blocks = (
            (value_matrix(X[i : i + rows], self.domain_, self.powers_), y[i : i + rows])
            for i in range(0, X.shape[0], rows)
        )
        self.coef_, self.cond_, self.rank_ = solve_streaming(blocks, self.powers_.shape[0])

    def _vector_field(self, X):
        return self._in_blocks(
            X, lambda B: value_matrix(B, self.domain_, self.powers_) @ self.coef_,
            self.powers_.shape[0],
        )

    def _integrator(self, method):
        if self.coef_.ndim != 2 or self.coef_.shape[1] != self.n_features_in_:
            raise ValueError(
                "simulate needs a vector field: fit with y the time derivatives of X "
                f"({self.n_features_in_} outputs); this model was fitted with "
                f"{1 if self.coef_.ndim == 1 else self.coef_.shape[1]} output(s)."
            )
        if method == "avf":
            raise ValueError(
                "method='avf' needs a Hamiltonian, which VectorFieldRegressor does not "
                "learn; use method='rk4', or HamiltonianRegressor."
            )
        if method not in METHODS:
            raise ValueError(f"method must be one of ['rk4']; got {method!r}.")
        return METHODS[method](self._vector_field)
