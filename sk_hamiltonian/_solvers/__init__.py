"""Least-squares solvers shared by the regressors, one module per way of solving.

Every solver equilibrates the columns of the design (divides each by its
norm), which removes most of the growth of the Legendre gradients with the
degree, and reports the condition number of the equilibrated design
(:mod:`.common`).

``"lstsq"`` (:mod:`.dense`)
    Factorizes the whole design with an SVD-based LAPACK driver: the most
    accurate choice, at the memory cost of the design itself and ``O(rows *
    n_terms**2)`` work with a large constant.
``"normal"`` (:mod:`.normal`)
    Streams the design in blocks into the normal equations (an in-place BLAS
    rank-k update per block), factorizes them by Cholesky and refines the
    solution against the design, so that the result matches ``"lstsq"`` while
    the design's condition number stays below about ``1e7``; where the
    factorization fails or rank is lost it falls back to an eigen
    pseudo-inverse with ``lstsq``'s cut-off. Memory is ``O(n_terms**2)``
    whatever the number of samples; the time is one Gram matrix, the bound of
    every dense method.
``"iterative"`` (:mod:`.iterative`)
    Never forms the Gram matrix: conjugate gradients on the normal equations
    (CGLS), with the design applied as an operator (:mod:`sk_hamiltonian._design_operator`,
    a few times cheaper per pass than the explicit design) and preconditioned
    by the *closed-form* Gram matrix of the basis under the uniform measure on
    the box, which the empirical one approaches when the samples cover the box
    evenly (the paper's setting). The cost is a Cholesky factorization of that
    ``n_terms x n_terms`` matrix plus two operator applications per iteration.
    Its condition number is an estimate (an upper bound, from the
    preconditioner and the iteration's Ritz values).
``"sketch"`` (:mod:`.iterative`)
    The same iteration, preconditioned by the Gram matrix of a random sketch
    of the design (:mod:`sk_hamiltonian._sketch`): a few dozen iterations whatever the
    samples' distribution, for one pass over the design and the sketch's
    ``n_terms x n_terms`` products.

:func:`choose_solver` (:mod:`.choice`) resolves ``"auto"`` by size; the
choices are measured in ``benchmarks/bench_scale.py`` and explained in the
documentation (Solvers and scaling).
"""

from .choice import choose_solver
from .common import solve_nonnegative_tail, warn_if_ill_conditioned
from .dense import solve_dense, stack_blocks
from .iterative import solve_iterative, warn_not_converged
from .normal import (
    MIRROR_TILE,
    NormalEquations,
    mirror_upper,
    normal_equations,
    resolve_condition,
    solve_normal,
    solve_streaming,
    symmetric_from_upper,
)

__all__ = [
    "MIRROR_TILE",
    "NormalEquations",
    "choose_solver",
    "mirror_upper",
    "normal_equations",
    "resolve_condition",
    "solve_dense",
    "solve_iterative",
    "solve_nonnegative_tail",
    "solve_normal",
    "solve_streaming",
    "stack_blocks",
    "symmetric_from_upper",
    "warn_if_ill_conditioned",
    "warn_not_converged",
]
