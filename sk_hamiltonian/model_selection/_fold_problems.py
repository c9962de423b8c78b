"""The least-squares problems of one model space, fold by fold, from one assembly.

A candidate of :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` is
a model space, a fit target, a de-noising setting, a degree and a threshold.
For one derivative layout, fit target and model space, every degree and every
threshold share their rows:

- the normal equations of the whole data are the sum of those of the folds'
  held-out trajectories, ``G = sum_k G_k``, so those of fold ``k``'s training
  set are ``G - G_k``: one pass over the data gives every fold;
- the index set of a smaller degree is a subset of the largest one's on the
  same box, so its normal equations are a sub-block;
- a threshold is a support rule on the same normal equations
  (:func:`~sk_hamiltonian._fit_steps.solve_normal_equations`).

The same quantities give each candidate's held-out *equation error*, the
relative residual ``||A_k c - b_k||**2 / ||b_k||**2`` of fold ``k``'s rows for
the coefficients ``c`` fitted without them, from ``G_k``, ``A_k^T b_k`` and
``b_k^T b_k`` alone. Within one derivative layout and fit target every
candidate is measured against the same targets, so the error ranks model
spaces, degrees and thresholds honestly; across layouts or fit targets the
targets differ, and only the rollout score compares them.

Every problem uses one box for all folds, the bounding box of the whole
layout's states (one period for periodic variables): the functions a space
spans do not depend on its box, only their conditioning does.
"""

import warnings

import numpy as np
from sklearn.base import clone

from .. import _fit_steps as steps
from .._hamiltonian import HamiltonianRegressor
from .._space import ModelSpace
from .._space.mixed import factor_degrees


def take(X, indices):
    """The trajectories ``indices`` of a 3-D array or a list."""
    if isinstance(X, np.ndarray):
        return X[indices]
    return [X[i] for i in indices]


class _NoSizeCheck:
    """Data seen by the size check only for its shapes: the folds' totals decide."""

    def __init__(self, data):
        self.states, self.derivatives = data.states, data.derivatives

    def n_rows(self, fit_on):
        return np.inf


class FoldProblems:
    """Normal equations of one model space and fit target on one layout, per fold.

    Parameters
    ----------
    params : dict
        Parameters of :class:`~sk_hamiltonian.HamiltonianRegressor` (model
        space, ``fit_on``, ``damping``, ``solver``), ``degree`` and
        ``threshold`` aside.
    Xt : derivative layout
        The whole data, from :class:`~sk_hamiltonian.DerivativeTransformer`.
    folds : list of ndarray of int
        Held-out trajectories of each fold.
    degree : int
        The largest degree to be solved.
    domain : array-like of shape (n_states, 2), default=None
        The box of every problem; None: the bounding box of the layout's
        states (one period ``[-pi, pi)`` for angles).

    Attributes
    ----------
    domain : ndarray of shape (n_states, 2)
        The box of every problem.
    space : ModelSpace
        The space of the largest degree.
    n_rows : int
        Least-squares rows of the whole data.
    """

    def __init__(self, params, Xt, folds, degree, domain=None):
        self.params = dict(params)
        self.folds = folds
        self._model = HamiltonianRegressor(**self.params, degree=degree)
        self._model._validate_params()
        self.data = self._model._training_data(Xt, None, None)
        # The whole layout's box (checked as a fit checks its own: a constant
        # variable needs an explicit domain), shared by every fold.
        self.space = steps.build_space(
            self._model, self.data, domain=domain, size_data=_NoSizeCheck(self.data))
        self.domain = self.space.domain
        self._design = self._model._design(self.space)
        self.n_tail = self._design.n_nonnegative
        self.n_rows = self._design.n_rows(self.data)
        self.parts = [steps.normal_equations(self._model, self.space,
                                             self.data.take_trajectories(test))
                      for test in folds]
        self.total = tuple(sum(part[i] for part in self.parts) for i in range(3))
        self._spaces = {}

    def columns(self, degree):
        """Unknowns of the problem of ``degree``: its basis functions, then the friction ones."""
        space = self.space
        basis = factor_degrees(space.powers, space.mixed).sum(axis=1) <= degree
        return np.concatenate([basis, np.ones(self.n_tail, dtype=bool)])

    def n_unknowns(self, degree):
        """Number of unknowns of the problem of ``degree``."""
        return int(self.columns(degree).sum())

    def space_of(self, degree):
        """The model space of ``degree`` on the shared box (built once)."""
        if degree not in self._spaces:
            rows = self.columns(degree)[: self.space.n_terms]
            space = self.space
            self._spaces[degree] = ModelSpace(space.domain, space.powers[rows], space.periodic,
                                              space.mixed)
        return self._spaces[degree]

    def estimator(self, degree, threshold):
        """The candidate's regressor, its parameters as a fit would have them."""
        return clone(self._model).set_params(degree=degree, threshold=threshold)

    def solve(self, degree, threshold, fold=None):
        """The support rule's solution on every fold but ``fold`` (None: on all the data).

        Returns
        -------
        columns : ndarray of bool
            :meth:`columns` of ``degree``.
        solution : sk_hamiltonian._least_squares.Solution
        """
        columns = self.columns(degree)
        gram, rhs, _ = self.total
        if fold is not None:
            gram, rhs = gram - self.parts[fold][0], rhs - self.parts[fold][1]
        equations = (gram[np.ix_(columns, columns)], rhs[columns])
        model = self.estimator(degree, threshold)
        return columns, steps.solve_normal_equations(model, self.space_of(degree), equations)

    def equation_error(self, columns, coef, fold):
        """Relative residual of fold ``fold``'s rows for ``coef`` (the unknowns of ``columns``)."""
        gram, rhs, btb = self.parts[fold]
        gram, rhs = gram[np.ix_(columns, columns)], rhs[columns]
        residual = float(coef @ gram @ coef - 2.0 * coef @ rhs + btb)
        return max(residual, 0.0) / btb if btb > 0 else residual

    def fitted(self, degree, threshold, solution, fold=None):
        """A fitted :class:`~sk_hamiltonian.HamiltonianRegressor` from a solution.

        Its fitted attributes are those of a fit on fold ``fold``'s training
        trajectories (all the data for None), on :attr:`domain`.
        """
        data = self.data
        if fold is not None:
            n_trajectories = len(data.trajectories)
            data = data.take_trajectories(np.setdiff1d(np.arange(n_trajectories),
                                                       self.folds[fold]))
        model = self.estimator(degree, threshold).set_params(domain=self.domain)
        with warnings.catch_warnings():
            # The fold models' own checks (energy trend, conditioning) are the
            # search's business, not the user's.
            warnings.simplefilter("ignore")
            return steps.set_fitted(model, self.space_of(degree), solution, data)
