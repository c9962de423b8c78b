"""A fit's solve: the chosen solver under the support rule, with its fall-back; and a whole threshold path.

What ``fit`` runs between building the design and setting the fitted
attributes: :func:`solve` for one support rule, :func:`solve_path` for
several thresholds on one assembly of the design. Conjugate gradients that
stop at their cap fall back to the normal equations where ``solver="auto"``
allowed it.
"""

from .column_solvers import CGNotConverged, column_solver


def solve(problem, solver, rule, *, fall_back=False, progress=None, name="estimator"):
    """The :class:`~.support.Solution` of ``problem`` under ``rule``, by ``solver``.

    Parameters
    ----------
    problem : LeastSquaresProblem
        The design bound to the training data.
    solver : {"lstsq", "normal", "iterative", "sketch"}
        The solver (``"auto"`` resolved already).
    rule : SupportRule
        Every term, or the terms a threshold keeps.
    fall_back : bool, default=False
        Whether conjugate gradients that reach their cap fall back to the
        normal equations (``solver="auto"``) instead of warning.
    progress : callable, default=None
        ``progress(message)``: a callback ``report(*values)`` that shows the
        ``message`` template with the values (the blocks accumulated, the
        iterations and their residual), or None for silence.
    name : str, default="estimator"
        Named in messages and warnings.

    Returns
    -------
    solution : Solution
    solver : str
        The solver that gave it (``"normal"`` after a fall-back).
    """
    if progress is None:
        progress = _silent
    block_progress = progress("block {0}: {1} equations accumulated")
    # Named terms are a solve on some columns: the design must stay whole.
    single_solve = rule.threshold == 0 and not problem.n_nonnegative and rule.keep is None
    try:
        solve_, norms = column_solver(
            problem, solver, single_solve=single_solve, many_supports=rule.threshold > 0,
            fall_back=fall_back,
            progress=progress("iteration {0}: relative normal residual {1:.2e}"),
            block_progress=block_progress, name=name,
        )
        return rule(solve_, norms), solver
    except CGNotConverged:
        # The closed-form preconditioner assumes samples spread over the
        # box, a sketch a design well enough conditioned for its Gram
        # matrix; where that fails, fall back to the normal equations.
        report = progress("conjugate gradients did not converge; normal equations")
        if report is not None:
            report()
        solution = rule(*column_solver(problem, "normal", block_progress=block_progress, name=name))
        return solution, "normal"


def _silent(message):
    return None


def solve_path(problem, solver, rules, *, fall_back=False, name="estimator"):
    """The solutions of ``problem`` under several support rules, from one assembly of the design.

    Each equals :func:`solve` under its rule up to round-off, but the design
    (and with ``solver="normal"`` its Gram matrix) is built once: a new
    support needs only a smaller solve.

    Parameters
    ----------
    problem : LeastSquaresProblem
        The design bound to the training data.
    solver : {"lstsq", "normal", "iterative", "sketch"}
        The solver.
    rules : sequence of SupportRule
        One per threshold.
    fall_back : bool, default=False
        Raise :class:`~.column_solvers.CGNotConverged` where conjugate
        gradients reach their cap (the caller then fits separately), instead
        of warning.
    name : str, default="estimator"
        Named in warnings.

    Returns
    -------
    solutions : iterator of Solution
        In the order of ``rules``, each solved when it is asked for (the
        design is assembled by this call).
    """
    solve_, norms = column_solver(
        problem, solver, many_supports=True, fall_back=fall_back, name=name
    )
    return (rule(solve_, norms) for rule in rules)
