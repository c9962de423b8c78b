"""Model selection: honest cross-validation of trajectory models, and the search over them.

A pipeline ``make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())``
can be searched directly with :class:`~sklearn.model_selection.GridSearchCV`
on the trajectory array: one sample is one trajectory, so the folds hold out
whole trajectories, and the default score already compares rollouts with the
held-out *observations* (see :meth:`~sk_hamiltonian.HamiltonianRegressor.score`).

:class:`HamiltonianSearchCV` searches what the package can do in one object:
model spaces (polynomial, periodic or mixed positions; mechanical and
separable Hamiltonians), fit targets, de-noising, degree and sparsity, sharing
one assembly of the normal equations per fold among the candidates of a space.

The helpers: :func:`candidate_table` shows each candidate's mean score with
its standard error and which candidates the data cannot tell from the best;
:func:`multistep_scorer` is a held-out score from short predictions started at
every observation; :func:`one_standard_error_rule` is a ``refit`` callable that
prefers the smallest model whose score is within one standard error of the
best; :func:`segment_trajectories` cuts long records into segments with group
labels, so that a few long records can be cross-validated like many short
trajectories; :func:`threshold_path` gives each sparsity threshold's model
size and cross-validated score, with the thresholds that tie with the best.
"""

from ._cv_tools import (
    candidate_table,
    count_terms,
    multistep_scorer,
    one_standard_error_rule,
    segment_trajectories,
)
from ._screen import angle_like
from ._search import HamiltonianSearchCV, auto_spaces
from ._threshold_path import threshold_path

__all__ = [
    "HamiltonianSearchCV",
    "angle_like",
    "auto_spaces",
    "candidate_table",
    "count_terms",
    "multistep_scorer",
    "one_standard_error_rule",
    "segment_trajectories",
    "threshold_path",
]
