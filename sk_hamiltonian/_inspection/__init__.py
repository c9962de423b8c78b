"""The parts of :mod:`sk_hamiltonian.inspection`: terms, formula, intervals, sympy."""
