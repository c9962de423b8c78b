"""The least-squares problem of a fit: its design, the terms kept, and their solve.

Every fit of the package is ``min_c ||A c - b||``, possibly over a subspace of
the coefficients. Four parts, each replaceable on its own (in the spirit of
skglm's datafit, penalty and solver):

- :mod:`.problem`: each regressor's :class:`Design` on a model space (which
  rows and columns; skglm's *datafit*), and bound to training data the
  :class:`LeastSquaresProblem` the solvers take (row blocks, grouped blocks
  for a sketch, an operator, and its normal equations ``(A^T A, A^T b, b^T
  b)`` by the estimator's cheapest route);
- :mod:`.column_solvers`: ``solve(keep, basis=None) -> (u, cond, rank)`` by
  one solver (:func:`column_solver`), or from normal equations
  (:func:`accumulated_solver`);
- :mod:`.support`: the support rule (:class:`SupportRule`, the *penalty*):
  every term (``threshold=0``, the paper's dense fit), or sequentially
  thresholded least squares (STLSQ) in the readable basis, with friction
  unknowns constrained to be non-negative and never dropped;
- :mod:`.fit`: a fit's solve with its fall-back (:func:`solve`), and a
  threshold path on one assembly (:func:`solve_path`).
"""

from .column_solvers import CGNotConverged, accumulated_solver, column_solver, design_residual
from .fit import solve, solve_path
from .problem import Design, HamiltonianDesign, LeastSquaresProblem, VectorFieldDesign
from .support import STLSQ_MAX_ITER, Solution, SupportRule, fit_support

__all__ = [
    "STLSQ_MAX_ITER",
    "CGNotConverged",
    "Design",
    "HamiltonianDesign",
    "LeastSquaresProblem",
    "Solution",
    "SupportRule",
    "VectorFieldDesign",
    "accumulated_solver",
    "column_solver",
    "design_residual",
    "fit_support",
    "solve",
    "solve_path",
]
