"""The threshold path: model size against cross-validated score, over sparsity thresholds."""

import copy
import warnings

import numpy as np
from scipy.stats import rankdata
from sklearn.base import clone
from sklearn.exceptions import FitFailedWarning
from sklearn.metrics import check_scoring
from sklearn.model_selection import check_cv
from sklearn.pipeline import Pipeline
from sklearn.utils import Bunch, _safe_indexing, indexable
from sklearn.utils.parallel import Parallel, delayed

from .. import _fit_steps as steps
from .._base import BaseTrajectoryRegressor
from .._least_squares import CGNotConverged, solve_path
from .._threads import gram_flops, limit_blas


def _threshold_parameter(estimator):
    """The ``set_params`` name of the final regressor's ``threshold``."""
    if isinstance(estimator, Pipeline):
        name, final = estimator.steps[-1]
        prefix = f"{name}__"
    else:
        final, prefix = estimator, ""
    if not isinstance(final, BaseTrajectoryRegressor):
        raise ValueError(
            f"estimator must be a HamiltonianRegressor or VectorFieldRegressor, or a "
            f"Pipeline ending in one; got {type(final).__name__}."
        )
    return prefix + "threshold"


def threshold_path(estimator, X, thresholds, *, cv=5, scoring=None, n_jobs=None):
    """Cross-validated score and model size for each sparsity threshold.

    For each threshold the estimator (a regressor, or a pipeline ending in
    one) is cross-validated with ``scoring`` and fitted once on all of ``X``
    for its number of terms. The result shows the trade-off between size and
    score, and which thresholds tie with the best: those whose mean score is
    within one standard error (of the best candidate's fold scores) of it.

    The scores are those of :class:`~sklearn.model_selection.GridSearchCV`
    over the threshold with the same folds, but each fold's design (and,
    with the normal equations, its Gram matrix) is assembled once for the
    whole path: a new support needs only a smaller solve, so the path costs
    little more than one dense fit per fold.

    Parameters
    ----------
    estimator : HamiltonianRegressor, VectorFieldRegressor or Pipeline
        The model, with every parameter but ``threshold`` set.
    X : array-like
        What the estimator's ``fit`` takes: trajectories for a pipeline
        starting with :class:`~sk_hamiltonian.DerivativeTransformer`, the
        derivative layout for a regressor.
    thresholds : array-like of float
        Non-negative thresholds, e.g. ``[0, 1e-3, 1e-2, 3e-2, 0.1]``.
    cv : int or cross-validation generator, default=5
        As in :class:`~sklearn.model_selection.GridSearchCV`: folds of whole
        trajectories.
    scoring : str or callable, default=None
        None: the estimator's own ``score`` (the honest rollout score).
    n_jobs : int, default=None
        Folds fitted in parallel (joblib), as in
        :class:`~sklearn.model_selection.GridSearchCV`.

    Returns
    -------
    path : sklearn.utils.Bunch
        With ``thresholds`` (sorted), ``n_terms`` (of the fit on all of
        ``X``), ``mean_score``, ``std_error`` (standard deviation of the fold
        scores over the square root of the number of folds), ``tied`` (bool:
        within one standard error of the best mean score), ``best_index``
        (the best mean score) and ``smallest_tied_index`` (the fewest terms
        among the tied), and ``cv_results``, laid out as ``cv_results_`` of
        the equivalent search (``params``, ``param_<name>``, the fold
        scores, their mean, standard deviation and rank).

    Raises
    ------
    ValueError
        If ``thresholds`` is empty or has a negative or non-finite entry, or
        the estimator is not a regressor of this package (or a pipeline
        ending in one).

    See Also
    --------
    sk_hamiltonian.plotting.plot_threshold_path : Draws the path.
    sk_hamiltonian.HamiltonianRegressor : Its ``threshold`` parameter.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.pipeline import make_pipeline
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories, single_pendulum
    >>> from sk_hamiltonian.model_selection import threshold_path
    >>> X = make_trajectories(single_pendulum(), 60, 40, dt=0.01, noise=0.02, random_state=0)
    >>> pipe = make_pipeline(
    ...     DerivativeTransformer(dt=0.01, degree=3),
    ...     HamiltonianRegressor(degree=6, periodic=[False, True], momentum_degree=2),
    ... )
    >>> path = threshold_path(pipe, X, [0.0, 0.03], cv=3)
    >>> path.n_terms.tolist()
    [32, 2]
    """
    name = _threshold_parameter(estimator)
    values = np.asarray(thresholds, dtype=float).ravel()
    if values.size == 0 or not np.all(np.isfinite(values)) or np.any(values < 0):
        raise ValueError(
            f"thresholds must be a non-empty list of finite numbers >= 0; got {thresholds!r}."
        )
    values = np.unique(values)
    X = X if isinstance(X, list) else indexable(X)[0]
    splitter = check_cv(cv)
    splits = list(splitter.split(X))
    scorer = check_scoring(estimator, scoring=scoring)
    fold_scores = Parallel(n_jobs=n_jobs)(
        delayed(_fold_scores)(clone(estimator), X, train, test, values, scorer)
        for train, test in splits
    )
    scores = np.array(fold_scores).T  # (threshold, fold)
    mean = scores.mean(axis=1)
    std = scores.std(axis=1)
    error = std / np.sqrt(len(splits))
    n_terms = np.array([_final(model).n_terms_ for model in _fit_path(clone(estimator), X, values)])
    finite = np.isfinite(mean)
    if not finite.any():
        raise ValueError(
            "No threshold gave a finite mean score: every candidate failed in some fold "
            "(see cv_results for the fold scores and the fit errors)."
        )
    best = int(np.flatnonzero(finite)[np.argmax(mean[finite])])
    tied = finite & (mean >= mean[best] - error[best])
    tied_indices = np.flatnonzero(tied)
    smallest = int(tied_indices[np.lexsort((-mean[tied], n_terms[tied]))[0]])
    results = {
        "params": [{name: float(v)} for v in values],
        f"param_{name}": np.ma.MaskedArray(values.copy()),
        **{f"split{k}_test_score": scores[:, k] for k in range(len(splits))},
        "mean_test_score": mean, "std_test_score": std,
        "rank_test_score": rankdata(-np.where(finite, mean, -np.inf), method="min").astype(
            np.int32),
    }
    return Bunch(
        thresholds=values, n_terms=n_terms, mean_score=mean, std_error=error, tied=tied,
        best_index=best, smallest_tied_index=smallest, cv_results=results,
    )


def _fit_path(estimator, X, values):
    """The estimator fitted at every threshold, sharing one assembly where possible."""
    steps = estimator.steps[:-1] if isinstance(estimator, Pipeline) else []
    final = _final(estimator)
    Xt = X
    for _, step in steps:
        if step is not None and step != "passthrough":
            Xt = step.fit_transform(Xt)
    try:
        models = fit_along_path(final, Xt, values)
    except (CGNotConverged, TypeError, ValueError):
        # Dask arrays, 2-D input without y, or an iterative solve that did
        # not converge: separate fits give the same models (or the error).
        models = [clone(final).set_params(threshold=float(v)).fit(Xt) for v in values]
    if not steps:
        return models
    return [Pipeline(steps + [(estimator.steps[-1][0], model)]) for model in models]


def fit_along_path(regressor, X, thresholds):
    """Fitted copies of ``regressor``, one per threshold, from one assembly.

    Each equals ``clone(regressor).set_params(threshold=t).fit(X)`` up to
    round-off, but the model space and the design (and with
    ``solver="normal"`` its Gram matrix) are built once: a new support needs
    only a smaller solve. In-memory data only; the caller falls back to
    separate fits for dask arrays and when conjugate gradients do not
    converge.

    Parameters
    ----------
    regressor : HamiltonianRegressor or VectorFieldRegressor
        The model; its ``threshold`` is ignored.
    X : derivative layout or array-like of shape (n_samples, n_states)
        What its ``fit`` takes (2-D states need ``y``, which this path does
        not take: pass the derivative layout).
    thresholds : sequence of float
        Non-negative thresholds.

    Returns
    -------
    models : list of estimators
        Fitted, in the order of ``thresholds``.
    """
    regressor._validate_params()
    regressor._check_integer_params()
    regressor._partial = None
    data = regressor._training_data(X, None, None)
    space = steps.build_space(regressor, data)
    design = regressor._design(space)
    solver = steps.choose(regressor, design, data)
    rules = [steps.support_rule(regressor, space, float(t)) for t in thresholds]
    models = []
    with limit_blas(gram_flops(design.n_rows(data), design.n_columns)):
        solutions = solve_path(design.problem(data), solver, rules,
                               fall_back=regressor.solver == "auto",
                               name=type(regressor).__name__)
        for threshold, solution in zip(thresholds, solutions):
            model = copy.copy(regressor)
            model.threshold = float(threshold)
            models.append(steps.set_fitted(model, space, solution, data, solver=solver))
    return models


def _fold_scores(estimator, X, train, test, values, scorer):
    """Scores of one fold at every threshold (NaN, with a warning, where a fit fails)."""
    try:
        models = _fit_path(estimator, _safe_indexing(X, train), values)
    except Exception as error:  # as GridSearchCV with error_score=np.nan
        warnings.warn(f"threshold_path: a fold failed to fit: {error!r}", FitFailedWarning)
        return [np.nan] * len(values)
    X_test = _safe_indexing(X, test)
    scores = []
    for model in models:
        try:
            scores.append(float(scorer(model, X_test, None)))
        except Exception as error:
            warnings.warn(f"threshold_path: scoring failed: {error!r}", FitFailedWarning)
            scores.append(np.nan)
    return scores


def _final(estimator):
    return estimator[-1] if isinstance(estimator, Pipeline) else estimator

