"""A regressor's fit in four steps, each callable on its own.

``fit`` runs them in order; ``partial_fit`` (:mod:`._streaming`), the dask
fit (:mod:`._distributed`) and the threshold path (:mod:`.model_selection._threshold_path`)
share them; and a search over candidates can call them without ``fit``, to
share one model space, or the normal equations of a fold, between
candidates:

(a) :func:`build_space`: the model space of the estimator's parameters on
    the training data (:mod:`._space.builder`);
(b) :func:`normal_equations`: ``(A^T A, A^T b, b^T b)`` of the estimator's
    design on any training data, e.g. some of its trajectories
    (:meth:`~._training_data.TrainingData.take_trajectories`);
(c) :func:`solve_normal_equations`: the support rule (every term, or
    sequential thresholding, with a non-negative friction tail) solved from
    normal equations (:mod:`._least_squares`);
(d) :func:`set_fitted`: a solution and its training data made into the
    fitted estimator.

Each takes the estimator first, for its parameters and its hooks (the
subclass's ``_design``, ``_check_dimensions``, ``_check_size``,
``_set_coef`` and ``_after_fit``); only :func:`set_fitted` changes it.
"""

import numpy as np

from ._angle_steps import check_angle_steps
from ._integrate import simulation
from ._least_squares import SupportRule
from ._memory import check_solver_memory, check_space_memory
from ._solvers import choose_solver, warn_if_ill_conditioned
from ._space.builder import build_space as _build
from ._space.builder import space_size


def space_parameters(estimator):
    """The estimator's parameters of :func:`~._space.builder.build_space` but the domain."""
    return {
        "degree": estimator.degree, "periodic": estimator._state_parameter("periodic"),
        "mixed": estimator._state_parameter("mixed"),
        "momentum_degree": estimator.momentum_degree, "separable": estimator.separable,
        "max_interaction": estimator.max_interaction,
        "couplings": estimator._state_parameter("couplings"),
        "include_constant": estimator._include_constant,
    }


def build_space(estimator, data, *, domain=None, size_data=None):
    """(a) The model space of the estimator's parameters on ``data``; nothing is set.

    Every model-space parameter is checked against the data (the
    estimator's ``_check_dimensions`` and ``_check_size`` included), the
    memory of the least fit of that many unknowns against
    ``memory_limit`` (:func:`sk_hamiltonian.set_config`) before the space is
    built, the steps of periodic and mixed coordinates along the
    trajectories (:func:`~._angle_steps.check_angle_steps`), and training
    states outside an explicit domain are reported with a
    :class:`~sk_hamiltonian.DomainWarning`.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        Its parameters say which space.
    data : TrainingData
        From ``estimator._training_data`` (or some of its trajectories).
    domain : array-like of shape (n_states, 2), default=None
        A box to use instead of the ``domain`` parameter (e.g. one box
        shared by the candidates of a search); None: the parameter's.
    size_data : object, default=None
        What ``_check_size`` sees instead of ``data`` (``partial_fit``'s
        chunks and the dask fit count rows their own way).

    Returns
    -------
    space : ModelSpace
    """
    n_states = data.states.shape[1]
    estimator._check_dimensions(n_states)
    explicit = estimator._state_parameter("domain") if domain is None else domain

    def check_size(n_terms):
        # Before the index set is built: too few equations, or too many unknowns.
        estimator._check_size(data if size_data is None else size_data)
        extra = estimator._n_terms(n_states) - n_terms  # e.g. friction coefficients
        check_space_memory(
            estimator, n_terms + extra, n_states,
            lambda degree: extra + space_size(
                n_states, **{**space_parameters(estimator), "degree": degree}),
        )

    space = _build(
        data.states, domain=explicit, sample_weight=data.sample_weight,
        check_size=check_size, **space_parameters(estimator),
    )
    # Before any fitting: a periodic or mixed coordinate the samples cannot
    # resolve would give a finite but meaningless model.
    check_angle_steps(estimator, space, data)
    if explicit is not None:
        w = data.sample_weight
        # Frames: _warn_n_outside, _warn_outside, here, fit (or partial_fit's
        # helper), and fit's _fit_context wrapper (or partial_fit): the
        # caller of fit is the next.
        estimator._warn_outside(data.states if w is None else data.states[w > 0], space,
                                "the training states", stacklevel=5)
    return space


def normal_equations(estimator, space, data, progress=None):
    """(b) ``(A^T A, A^T b, b^T b)`` of the estimator's design on ``space`` for ``data``.

    By the cheapest route (grouped blocks, or factored on a value basis), as
    ``fit`` with ``solver="normal"``, ``partial_fit`` and the dask fit
    accumulate them. The normal equations of disjoint pieces of data add up.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        Its ``_design`` says which rows and columns.
    space : ModelSpace
        From :func:`build_space`.
    data : TrainingData
        Any training data, e.g. some trajectories of a fit's
        (:meth:`~._training_data.TrainingData.take_trajectories`).
    progress : callable, default=None
        ``progress(k, n_rows)`` after each block.

    Returns
    -------
    gram, rhs, btb : ndarray, ndarray, float or ndarray
        See :meth:`~._least_squares.Design.normal_equations`.
    """
    return estimator._design(space).normal_equations(data, progress)


def solve_normal_equations(estimator, space, equations, residual=None):
    """(c) The estimator's support rule solved from normal equations.

    Every term, or the terms sequential thresholding at ``threshold`` keeps,
    with the friction coefficients of a damped model ``>= 0``; each solve is
    the ``"normal"`` solver's (Cholesky, or an eigen pseudo-inverse where
    rank is lost).

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        Its ``threshold`` and design.
    space : ModelSpace
        The space the equations belong to.
    equations : tuple
        ``(gram, rhs)`` or ``(gram, rhs, btb)``, e.g. from
        :func:`normal_equations`, or summed over pieces of data.
    residual : callable, default=None
        ``residual(keep)``, refinement against the design:
        ``estimator._design(space).residual(data)`` gives ``fit``'s answer
        with ``solver="normal"`` (three refinement passes over the data);
        None, the Cholesky solution as it is (``partial_fit``, whose samples
        are gone).

    Returns
    -------
    solution : Solution
        What :func:`set_fitted` takes.
    """
    return support_rule(estimator, space).from_normal_equations(equations, residual)


def set_fitted(estimator, space, solution, data, *, solver="normal", statistics=None):
    """(d) Make ``estimator`` the fitted model of ``solution``; return it.

    Sets every attribute ``fit`` sets: the space's (``periodic_``,
    ``powers_``, ``domain_``), the solution's (``coef_``, ``support_``,
    ``n_terms_``, ``n_iter_``, ``cond_``, ``rank_``), ``solver_``, and those
    of the training data (``dt_``, ``state_scale_``, ``time_scale_``,
    ``n_features_in_``, and the subclass's own, such as the energy trend);
    warns where the solve lost rank or digits.

    Parameters
    ----------
    estimator : BaseTrajectoryRegressor
        The estimator to set (a copy, to keep the original).
    space : ModelSpace
        The space of the solution.
    solution : Solution
        From :func:`solve_normal_equations` (or ``fit``'s solve).
    data : TrainingData
        The training data of the solution.
    solver : str, default="normal"
        The solver that gave it.
    statistics : PartialFitState, default=None
        Running statistics over more data than ``data`` (``partial_fit``,
        the dask fit): the state scale, magnitudes, time-scale sample and
        training step come from them.

    Returns
    -------
    estimator : BaseTrajectoryRegressor
    """
    if not np.all(np.isfinite(solution.coef)):
        # check_magnitude keeps the data's scale in range; a non-finite
        # solution is still never set as a model.
        raise ValueError(
            f"{type(estimator).__name__}: the least-squares solution is not finite (the "
            f"states reach {np.max(np.abs(data.states)):.3g} and their time derivatives "
            f"{np.max(np.abs(data.derivatives)):.3g} in magnitude). Rescale the data to units "
            f"in which each variable spans about 1, or lower `degree`."
        )
    est = estimator
    est.periodic_, est.powers_, est.domain_ = space.periodic, space.powers, space.domain
    est.mixed_ = space.mixed
    est._space = space
    est.solver_ = solver
    est.n_features_in_ = data.states.shape[1]
    est.support_ = solution.support
    est.n_terms_ = int(solution.n_kept)
    est.n_iter_ = solution.n_iter
    est.cond_, est.rank_ = solution.cond, solution.rank
    est._set_coef(solution.coef)
    est._rebuild_fitted()
    warn_if_ill_conditioned(solution.cond, solution.rank, solution.n_solved, type(est).__name__)
    if statistics is None:
        est.dt_ = data.median_step()
        scale = np.std(data.states, axis=0)
        # A constant variable (possible with an explicit domain) keeps unit scale.
        est.state_scale_ = np.where(scale > 0, scale, 1.0)
        # Typical size of each variable, for ranking terms (inspection).
        est._state_magnitude = np.sqrt(np.mean(data.states**2, axis=0))
        sample = data.states
    else:
        est.dt_ = statistics.training_step()
        est.state_scale_ = statistics.scale()
        est._state_magnitude = statistics.magnitude()
        sample = statistics.reservoir
    est.time_scale_ = simulation.time_scale(est._jacobian, sample)
    est._after_fit(data)
    return est


def choose(estimator, design, data):
    """The estimator's ``solver``, with ``"auto"`` resolved by the size of ``design`` on ``data``.

    Raises a ``ValueError`` (naming a solver that fits, if one does) where
    that solver would need more memory than ``memory_limit``.
    """
    n_rows = design.n_rows(data)
    solver = choose_solver(estimator.solver, n_rows, design.space.n_terms,
                           factored=lambda: design.factored_maps() is not None)
    check_solver_memory(estimator, solver, design.n_columns, n_rows, data.states.shape[1])
    return solver


def support_rule(estimator, space, threshold=None):
    """The estimator's support rule on ``space``, at ``threshold`` (default: its parameter)."""
    design = estimator._design(space)
    return SupportRule(space, design.n_columns,
                       estimator.threshold if threshold is None else threshold,
                       design.n_nonnegative, type(estimator).__name__,
                       keep=named_terms(estimator, space))


def named_terms(estimator, space):
    """The mask of the estimator's ``terms`` over the readable terms of ``space`` (None: all).

    ``terms`` holds multi-indices in the code and order of ``powers_`` (the
    readable basis carries the fitting basis' multi-indices); a row that is
    not a term of ``space`` is refused with the space's parameters and where
    to find its terms.
    """
    value = getattr(estimator, "terms", None)
    if value is None:
        return None
    name = type(estimator).__name__
    try:
        terms = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        terms = None
    if (terms is None or terms.ndim != 2 or terms.shape[1] != space.n_states
            or terms.shape[0] == 0 or not np.all(np.isfinite(terms))
            or np.any(terms != np.round(terms))):
        raise ValueError(
            f"{name}: terms must be a non-empty array of integer multi-indices of shape "
            f"(n_terms, {space.n_states}), one row per term, as HamiltonianTerm.powers "
            f"gives them; got {value!r}.")
    terms = terms.astype(np.intp)
    index = {tuple(row): j for j, row in enumerate(space.powers.tolist())}
    missing = [tuple(row) for row in terms.tolist() if tuple(row) not in index]
    if missing:
        raise ValueError(
            f"{name}: terms holds {len(missing)} multi-index(es) that are not terms of the "
            f"model space (degree={estimator.degree}, mixed={estimator.mixed!r}, "
            f"periodic={estimator.periodic!r}, momentum_degree={estimator.momentum_degree!r}), "
            f"the first {missing[0]}. Take them from hamiltonian_terms(model)[i].powers of a "
            f"model fitted in the same space (the constant is not a term), or widen the space.")
    keep = np.zeros(len(space.powers), dtype=bool)
    keep[[index[tuple(row)] for row in terms.tolist()]] = True
    return keep
