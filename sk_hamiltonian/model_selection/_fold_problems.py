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
  (:func:`~sk_hamiltonian._least_squares.fit_support`).

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

from .._hamiltonian import HamiltonianRegressor
from .._least_squares import accumulated_solver, fit_support
from .._space.mixed import factor_degrees
from .._space.readable import ReadableBasis
from .._trajectories import unpack_derivatives


def layout_domain(Xt, periodic):
    """Bounding box of a derivative layout's states, one period ``[-pi, pi)`` for angles."""
    states = np.concatenate(list(unpack_derivatives(Xt).states))
    domain = np.column_stack([states.min(axis=0), states.max(axis=0)])
    domain[np.asarray(periodic, dtype=bool)] = [-np.pi, np.pi]
    return domain


def take(X, indices):
    """The trajectories ``indices`` of a 3-D array or a list."""
    if isinstance(X, np.ndarray):
        return X[indices]
    return [X[i] for i in indices]


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

    Attributes
    ----------
    domain : ndarray of shape (n_states, 2)
        The box of every problem.
    powers : ndarray of shape (n_terms, n_states)
        Multi-indices of the largest degree.
    """

    def __init__(self, params, Xt, folds, degree):
        self.params = dict(params)
        self.Xt, self.folds = Xt, folds
        n_states = unpack_derivatives(Xt).states[0].shape[1]
        periodic = self.params.get("periodic")
        self.domain = layout_domain(Xt, [False] * n_states if periodic is None else periodic)
        model = self._regressor(degree, 0.0)
        with warnings.catch_warnings():
            # The box holds every state: nothing is outside it.
            warnings.simplefilter("ignore")
            data = model._training_data(Xt, None, None)
            model._set_up_space(data, size_data=_NoSizeCheck(data))
        self._model = model
        self.powers = model.powers_
        self.periodic, self.mixed = model.periodic_, _mixed(model)
        self.n_tail = model._n_nonnegative()
        self.n_rows = data.n_rows(model.fit_on) * n_states
        self.gram, self.rhs, self.norm2 = [], [], []
        for test in folds:
            part = model._training_data(take(Xt, test), None, None, reset=False)
            gram, rhs = model._accumulate(part).result()
            self.gram.append(gram)
            self.rhs.append(rhs)
            self.norm2.append(_squared_targets(model, part))
        self.total = (sum(self.gram), sum(self.rhs))
        self._readable = {}

    def _regressor(self, degree, threshold):
        return HamiltonianRegressor(
            **{**self.params, "degree": degree, "threshold": threshold, "domain": self.domain})

    def columns(self, degree):
        """Unknowns of the problem of ``degree``: its basis functions, then the friction ones."""
        basis = factor_degrees(self.powers, self.mixed).sum(axis=1) <= degree
        return np.concatenate([basis, np.ones(self.n_tail, dtype=bool)])

    def n_unknowns(self, degree):
        """Number of unknowns of the problem of ``degree``."""
        return int(self.columns(degree).sum())

    def solve(self, degree, threshold, fold=None):
        """The support rule's solution on every fold but ``fold`` (None: on all the data).

        Returns
        -------
        columns : ndarray of bool
            :meth:`columns` of ``degree``.
        solution : sk_hamiltonian._least_squares.Solution
        """
        columns = self.columns(degree)
        gram, rhs = self.total
        if fold is not None:
            gram, rhs = gram - self.gram[fold], rhs - self.rhs[fold]
        gram, rhs = gram[np.ix_(columns, columns)], rhs[columns]
        n_basis = int(columns.sum()) - self.n_tail
        readable = self.readable_basis(degree) if threshold else None
        solve, norms = accumulated_solver(gram, rhs)
        solution = fit_support(
            solve, norms, n_basis + self.n_tail, n_basis=n_basis, threshold=threshold,
            readable=readable, n_nonnegative=self.n_tail, name="HamiltonianSearchCV",
        )
        return columns, solution

    def readable_basis(self, degree):
        """The change to the readable basis of the space of ``degree`` (built once)."""
        if degree not in self._readable:
            columns = self.columns(degree)
            powers = self.powers[columns[: columns.size - self.n_tail]]
            self._readable[degree] = ReadableBasis(powers, self.domain, self.periodic, self.mixed)
        return self._readable[degree]

    def equation_error(self, columns, coef, fold):
        """Relative residual of fold ``fold``'s rows for ``coef`` (the unknowns of ``columns``)."""
        gram, rhs = self.gram[fold][np.ix_(columns, columns)], self.rhs[fold][columns]
        norm2 = self.norm2[fold]
        residual = coef @ gram @ coef - 2.0 * coef @ rhs + norm2
        return max(float(residual), 0.0) / norm2 if norm2 > 0 else float(residual)

    def fitted(self, degree, threshold, solution, fold=None):
        """A fitted :class:`~sk_hamiltonian.HamiltonianRegressor` from a solution.

        Its space and fitted attributes are those of a fit on fold ``fold``'s
        training trajectories (all the data for None) on :attr:`domain`.
        """
        model = self._regressor(degree, threshold)
        indices = (np.arange(_n_trajectories(self.Xt)) if fold is None
                   else np.setdiff1d(np.arange(_n_trajectories(self.Xt)), self.folds[fold]))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = model._training_data(take(self.Xt, indices), None, None)
            model._set_up_space(data, size_data=_NoSizeCheck(data))
            model._set_solution(solution)
            model.solver_ = "normal"
            model._finish_fit(data)
        return model


class _NoSizeCheck:
    """A fold's data seen by the size check only for its shapes (the total decides)."""

    def __init__(self, data):
        self.states, self.derivatives = data.states, data.derivatives

    def n_rows(self, fit_on):
        return np.inf


def _squared_targets(model, data):
    """``b^T b`` of the design of ``data``."""
    total = 0.0
    for _, b in model._design_blocks(data):
        total += float(np.einsum("i,i->", b, b) if b.ndim == 1 else np.sum(b * b))
    return total


def _mixed(model):
    mixed = getattr(model, "mixed_", None)
    return np.zeros(model.n_features_in_, dtype=bool) if mixed is None else mixed


def _n_trajectories(Xt):
    return len(Xt)
