"""Which solver ``solver="auto"`` means for a design of a given size."""

# Designs up to this many entries (400 MB in float64) are factorized whole by
# "auto" (today's answers on small problems, to round-off).
DENSE_MAX_ENTRIES = 50_000_000
# From this many unknowns on, "auto" solves by conjugate gradients. Measured
# on the double pendulum (benchmarks/bench_scale.py): one iteration costs
# 1/13 of the (grouped) Gram matrix at n = 14 (3 059 unknowns) and 1/100 at
# n = 18 (7 314), while the closed-form preconditioner needs 100-200
# iterations, so the Gram matrix wins below about 10 000 unknowns.
ITERATIVE_MIN_TERMS = 10_000
# From this many unknowns, and this many rows per unknown, "auto" solves by
# conjugate gradients preconditioned by a sketch of the design (see
# sk_hamiltonian._sketch): about 50 iterations, each a pass of the operator, plus
# the sketch's Gram matrix (SKETCH_ROWS_PER_COLUMN / 2 * n**3 multiply-adds,
# which the rows make small beside the design's). Measured on the double
# pendulum, M = 60 000 (720 000 rows), both cores: at n = 16 (4 844
# unknowns) 165 s against the normal equations' 172 s, at n = 18 (7 314)
# 240 s against 405 s. Factored normal equations (one Gram matrix of the
# value basis, see _factored) took 55 s and 119 s on the same fits, so the
# sketch is left to designs without them.
SKETCH_MIN_TERMS = 5_000
SKETCH_MIN_ROWS_PER_TERM = 50
def choose_solver(solver, n_rows, n_terms, factored=False):
    """Resolve ``solver="auto"`` from the size of the design.

    Parameters
    ----------
    solver : {"auto", "lstsq", "normal", "iterative", "sketch"}
        The requested solver.
    n_rows, n_terms : int
        Shape of the design.
    factored : bool or callable, default=False
        Whether the normal equations come from one Gram matrix of a value
        basis (:mod:`sk_hamiltonian._factored`), ``n_states`` times cheaper than the
        grouped ones the sketch's threshold was measured against; a callable
        returning it is called only where the choice depends on it.

    Returns
    -------
    solver : str
        ``"lstsq"`` up to ``DENSE_MAX_ENTRIES`` entries; beyond, ``"normal"``;
        unless ``factored``, ``"sketch"`` from ``SKETCH_MIN_TERMS`` unknowns
        and ``SKETCH_MIN_ROWS_PER_TERM`` rows per unknown on; ``"iterative"``
        from ``ITERATIVE_MIN_TERMS`` unknowns on, where the Gram matrix costs
        more than the iterations it saves (and more memory than is
        reasonable).
    """
    if solver != "auto":
        return solver
    if n_rows * n_terms <= DENSE_MAX_ENTRIES:
        return "lstsq"
    if n_terms >= ITERATIVE_MIN_TERMS:
        return "iterative"
    if n_terms >= SKETCH_MIN_TERMS and n_rows >= SKETCH_MIN_ROWS_PER_TERM * n_terms:
        return "normal" if (factored() if callable(factored) else factored) else "sketch"
    return "normal"


