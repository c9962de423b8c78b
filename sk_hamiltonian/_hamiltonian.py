"""Structure-preserving regression: learn the Hamiltonian, not the vector field."""

import numpy as np
from sklearn.utils.validation import check_is_fitted

from ._base import BaseTrajectoryRegressor
from ._basis import (
    gradient_dot,
    gradient_matrix,
    hessian_dot,
    n_basis_functions,
    total_degree_powers,
    value_matrix,
)
from ._integrate import METHODS, apply_inverse_symplectic
from ._solvers import solve_dense, solve_streaming
from ._trajectories import check_n_states


def _symplectic_targets(y):
    """``J dx/dt`` for ``J = [[0, I], [-I, 0]]``: the gradient the data ask for."""
    d = y.shape[1] // 2
    return np.concatenate([y[:, d:], -y[:, :d]], axis=1)


class HamiltonianRegressor(BaseTrajectoryRegressor):
    """Structure-preserving regression of an unknown Hamiltonian system.

    Fits a polynomial Hamiltonian ``H~`` of total degree ``degree`` so that
    ``J dx/dt ≈ grad H~(x)`` in the least-squares sense (Wu, Qin & Xiu, Section
    3), with ``x = (p_1..p_d, q_1..q_d)`` and ``J = [[0, I], [-I, 0]]``. The
    learned system ``dx/dt = J^{-1} grad H~(x)`` is Hamiltonian by construction,
    so it conserves ``H~`` exactly along its trajectories.

    Parameters
    ----------
    degree : int, default=3
        Total degree ``n`` of the polynomial Hamiltonian. The number of unknowns
        is ``C(n + 2d, 2d) - 1``.
    domain : array-like of shape (n_states, 2), default=None
        The box ``D`` carrying the Legendre basis, one ``(low, high)`` row per
        state variable. None uses the bounding box of the training states.
    solver : {"auto", "lstsq", "normal"}, default="auto"
        ``"lstsq"`` factorizes the whole (column-equilibrated) design with an
        SVD; ``"normal"`` streams it in blocks into the normal equations, with
        memory independent of the number of samples. ``"auto"`` picks
        ``"lstsq"`` while the design holds at most 5e7 entries.

    Attributes
    ----------
    coef_ : ndarray of shape (n_terms,)
        Coefficients of ``H~`` in the basis ``powers_``.
    powers_ : ndarray of shape (n_terms, n_states)
        Multi-indices of the tensor Legendre basis functions (constant excluded).
    domain_ : ndarray of shape (n_states, 2)
        The box the basis lives on.
    cond_ : float
        Condition number of the column-equilibrated least-squares design.
    rank_ : int
        Numerical rank of that design.
    n_terms_ : int
        Number of fitted coefficients.
    solver_ : str
        The solver used.
    n_features_in_ : int
        Number of state variables ``2d``.
    feature_names_in_ : ndarray of shape (`n_features_in_`,)
        Names of the state variables, when ``X`` had string column names.

    See Also
    --------
    VectorFieldRegressor : The non-structure-preserving baseline.
    DerivativeTransformer : Estimates time derivatives from trajectories.

    Notes
    -----
    The basis is the tensor product of Legendre polynomials on ``domain_``
    mapped to ``[-1, 1]^{2d}``, of total degree ``1..degree``. Every
    non-constant basis function has zero mean over the box under the uniform
    measure, so the free additive constant of ``H~`` is fixed by the rule
    *H~ has zero mean over the domain*, the constant of the paper's Theorem 3.5.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-1, 1, size=(200, 2))              # states (p, q)
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])           # H = (p^2 + q^2) / 2
    >>> model = HamiltonianRegressor(degree=2, domain=[[-1, 1], [-1, 1]]).fit(X, y)
    >>> np.round(model.hamiltonian([[1.0, 0.0]]) - model.hamiltonian([[0.0, 0.0]]), 6)
    array([0.5])
    """

    _parameter_constraints = {**BaseTrajectoryRegressor._parameter_constraints}

    def _check_dimensions(self, X):
        check_n_states(X.shape[1])

    def _check_targets(self, X, y):
        if y.ndim != 2 or y.shape != X.shape:
            raise ValueError(
                f"y must hold the time derivative of every state variable, with the "
                f"same shape as X {X.shape}; got shape {y.shape}."
            )

    def _design_shape(self, n_samples, n_states):
        return n_samples * n_states, n_basis_functions(n_states, self.degree)

    def _fit_coef(self, X, y):
        self.powers_ = total_degree_powers(X.shape[1], self.degree)
        targets = _symplectic_targets(y)
        n_terms = self.powers_.shape[0]
        if self.solver_ == "lstsq":
            A = gradient_matrix(X, self.domain_, self.powers_).reshape(-1, n_terms)
            self.coef_, self.cond_, self.rank_ = solve_dense(A, targets.ravel())
            return
        rows = max(1, 20_000_000 // (n_terms * X.shape[1]))
        blocks = (
            (
                gradient_matrix(X[i : i + rows], self.domain_, self.powers_).reshape(-1, n_terms),
                targets[i : i + rows].ravel(),
            )
            for i in range(0, X.shape[0], rows)
        )
        self.coef_, self.cond_, self.rank_ = solve_streaming(blocks, n_terms)

    def _gradient(self, X):
        width = self.powers_.shape[0] * X.shape[1]
        return self._in_blocks(
            X, lambda B: gradient_dot(B, self.domain_, self.powers_, self.coef_), width
        )

    def _vector_field(self, X):
        return apply_inverse_symplectic(self._gradient(X))

    def _hessian(self, X):
        return hessian_dot(X, self.domain_, self.powers_, self.coef_)

    def _integrator(self, method):
        if method not in METHODS:
            raise ValueError(f"method must be one of {sorted(METHODS)}; got {method!r}.")
        if method == "avf":
            return METHODS["avf"](self._gradient, self._hessian, self.degree)
        return METHODS[method](self._vector_field)

    def hamiltonian(self, X):
        """The learned Hamiltonian ``H~``, normalized to zero mean over the domain.

        Parameters
        ----------
        X : array-like of shape (..., n_states)
            States; any leading shape, e.g. the output of :meth:`simulate`.

        Returns
        -------
        H : ndarray of shape X.shape[:-1]
            Values of ``H~``.
        """
        check_is_fitted(self)
        flat, lead = self._check_states(X)
        values = self._in_blocks(
            flat, lambda B: value_matrix(B, self.domain_, self.powers_) @ self.coef_,
            self.powers_.shape[0],
        )
        return values.reshape(lead)

    def gradient(self, X):
        """Gradient of the learned Hamiltonian, ``grad H~``.

        Parameters
        ----------
        X : array-like of shape (..., n_states)
            States.

        Returns
        -------
        grad : ndarray of the same shape as X
            ``(dH~/dp, dH~/dq)`` at each state.
        """
        check_is_fitted(self)
        flat, lead = self._check_states(X)
        return self._gradient(flat).reshape(lead + (self.n_features_in_,))
