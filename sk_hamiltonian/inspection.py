"""Read a learned Hamiltonian: its terms in the user's own coordinates.

The regressors expand ``H~`` in Legendre polynomials on the box mapped to
``[-1, 1]`` and in Fourier series of angles measured from the start of their
period, which is good for fitting and opaque for reading. :func:`hamiltonian_terms`
re-expands ``H~`` in monomials ``x**k`` of the state variables as the user
gave them, times ``cos(k w x)`` and ``sin(k w x)`` for periodic variables
(``w = 2 pi / period``), and ranks the terms by their size over the domain;
:func:`format_hamiltonian` writes the leading ones as one line. A model fitted
with ``fit_on="trajectories"`` carries the covariance of its coefficients, and
one fitted with ``n_resamples > 0`` refits on resamples of its trajectories:
:func:`term_intervals` gives each term's interval (and inclusion frequency
over the refits), :func:`format_hamiltonian` prints them with
``intervals=True``, and :func:`resampled_models` and :func:`prediction_band`
turn them into predictions. :func:`to_sympy` gives ``H~`` as a sympy
expression.
"""

from ._inspection.formula import format_hamiltonian
from ._inspection.intervals import (
    TermInterval,
    prediction_band,
    resampled_models,
    term_intervals,
)
from ._inspection.symbolic import to_sympy
from ._inspection.terms import HamiltonianTerm, hamiltonian_terms

__all__ = [
    "HamiltonianTerm",
    "TermInterval",
    "format_hamiltonian",
    "hamiltonian_terms",
    "prediction_band",
    "resampled_models",
    "term_intervals",
    "to_sympy",
]
