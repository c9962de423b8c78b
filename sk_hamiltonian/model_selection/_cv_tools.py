"""Cross-validation helpers: candidate tables, the one-standard-error rule, scorers, segments."""

import numbers

import numpy as np
from sklearn.base import clone
from sklearn.pipeline import Pipeline

from .._base import BaseTrajectoryRegressor
from .._scoring import multistep_errors
from .._trajectories import check_trajectories, is_trajectory_container
from .._vector_field import VectorFieldRegressor
from ._selection import ties


def _final_regressor(estimator):
    final = estimator[-1] if isinstance(estimator, Pipeline) else estimator
    if not isinstance(final, BaseTrajectoryRegressor):
        raise ValueError(
            f"estimator must be a HamiltonianRegressor or VectorFieldRegressor, or a "
            f"Pipeline ending in one; got {type(final).__name__}."
        )
    return final


def count_terms(estimator, n_states, params=None):
    """Number of coefficients an estimator fits, without fitting it.

    Parameters
    ----------
    estimator : HamiltonianRegressor, VectorFieldRegressor or Pipeline
        The regressor, or a pipeline ending in one (as passed to
        :class:`~sklearn.model_selection.GridSearchCV`).
    n_states : int
        Number of state variables ``2d`` of the data.
    params : dict, default=None
        Parameters to set first, e.g. an entry of ``cv_results_["params"]``.

    Returns
    -------
    n_terms : int
        The ``n_terms_`` the estimator would have after fitting:
        ``C(n + 2d, 2d) - 1`` for :class:`~sk_hamiltonian.HamiltonianRegressor` and
        ``2d * C(n + 2d, 2d)`` for :class:`~sk_hamiltonian.VectorFieldRegressor`.

    See Also
    --------
    one_standard_error_rule : Uses this count to prefer smaller models.

    Examples
    --------
    >>> from sklearn.pipeline import make_pipeline
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.model_selection import count_terms
    >>> pipe = make_pipeline(DerivativeTransformer(dt=0.1), HamiltonianRegressor())
    >>> count_terms(pipe, n_states=4, params={"hamiltonianregressor__degree": 3})
    34
    """
    if (
        isinstance(n_states, bool)
        or not isinstance(n_states, numbers.Integral)
        or n_states < 2
        or n_states % 2
    ):
        raise ValueError(
            f"n_states must be the number of state variables 2d, a positive even "
            f"integer (p_1..p_d, q_1..q_d); got {n_states!r}."
        )
    if params:
        estimator = clone(estimator).set_params(**params)
    final = _final_regressor(estimator)
    per_target = final._n_terms(n_states)
    # The baseline fits every component of the vector field separately.
    return int(per_target * (n_states if isinstance(final, VectorFieldRegressor) else 1))


def one_standard_error_rule(estimator, n_states, *, metric="score"):
    """A ``refit`` callable: the smallest model within one standard error of the best.

    For :class:`~sklearn.model_selection.GridSearchCV` (or any search passing
    ``cv_results_`` to ``refit``). Among the candidates whose mean test score
    is at least ``best_mean - best_std / sqrt(n_splits)`` (the best candidate's
    mean score minus its standard error), it returns the one with the fewest
    fitted coefficients; ties go to the higher mean score.

    Parameters
    ----------
    estimator : HamiltonianRegressor, VectorFieldRegressor or Pipeline
        The estimator given to the search. The rule only knows the candidates'
        parameters, so it counts each candidate's terms by setting them on a
        clone of this estimator (see :func:`count_terms`); parameters not in
        the grid keep the estimator's values.
    n_states : int
        Number of state variables ``2d`` of the data being searched.
    metric : str, default="score"
        Which score to use: ``"score"`` for single-metric searches, else the
        key of the ``scoring`` dict.

    Returns
    -------
    rule : callable
        ``rule(cv_results) -> int``, the index of the chosen candidate.

    Raises
    ------
    ValueError
        From ``rule``, if ``cv_results`` lacks the test scores of ``metric``
        or no candidate has a finite mean score.

    See Also
    --------
    count_terms : The complexity measure.
    multistep_scorer : A held-out score to use with this rule.

    Notes
    -----
    Candidates whose mean score is NaN or infinite (a fit or a rollout failed
    in some fold: scikit-learn's ``error_score``, or a rollout scorer's
    ``-inf``) are never chosen, and do not define the best score. With a
    callable ``refit``, the search sets ``best_index_`` and ``best_params_``
    but not ``best_score_``; read ``cv_results_["mean_test_score"]`` instead.
    The standard deviation in ``cv_results_`` is that of the fold scores,
    ``numpy.std`` (no degrees-of-freedom correction).

    Examples
    --------
    >>> from sklearn.model_selection import GridSearchCV
    >>> from sklearn.pipeline import make_pipeline
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories
    >>> from sk_hamiltonian.model_selection import one_standard_error_rule
    >>> X = make_trajectories("henon_heiles", 60, 2, dt=0.01, random_state=0)
    >>> pipe = make_pipeline(DerivativeTransformer(dt=0.01, method="finite_difference"),
    ...                      HamiltonianRegressor())
    >>> search = GridSearchCV(pipe, {"hamiltonianregressor__degree": [2, 3, 4, 5]},
    ...                       refit=one_standard_error_rule(pipe, n_states=4)).fit(X)
    >>> search.best_params_
    {'hamiltonianregressor__degree': 3}
    """
    count_terms(estimator, n_states)  # fail now on a wrong estimator or n_states
    if not isinstance(metric, str):
        raise ValueError(
            f"metric must be the name of a score in cv_results_ ('score', or a key "
            f"of the scoring dict); got {metric!r}."
        )

    def rule(cv_results):
        mean_key, std_key = f"mean_test_{metric}", f"std_test_{metric}"
        if mean_key not in cv_results or std_key not in cv_results:
            raise ValueError(
                f"cv_results_ has no {mean_key!r}: pass metric= the name of a score "
                f"of the search ('score' for single-metric searches)."
            )
        means = np.asarray(cv_results[mean_key], dtype=float)
        stds = np.asarray(cv_results[std_key], dtype=float)
        finite = np.isfinite(means) & np.isfinite(stds)
        if not finite.any():
            raise ValueError(
                f"No candidate has a finite mean {metric!r}: every candidate failed in "
                f"some fold. Rerun the search with error_score='raise' to see why."
            )
        n_splits = sum(
            1 for key in cv_results if key.startswith("split") and key.endswith(f"_test_{metric}")
        )
        best = int(np.flatnonzero(finite)[np.argmax(means[finite])])
        threshold = means[best] - stds[best] / np.sqrt(max(n_splits, 1))
        eligible = np.flatnonzero(finite & (means >= threshold))
        n_terms = np.array(
            [count_terms(estimator, n_states, cv_results["params"][i]) for i in eligible]
        )
        # Fewest terms first, then the higher mean score, then the first listed.
        order = np.lexsort((eligible, -means[eligible], n_terms))
        return int(eligible[order[0]])

    return rule


def candidate_table(search, *, metric="score"):
    """Each candidate's mean score, its standard error, and the ties with the best.

    A candidate *ties* with the best when its mean test score is at least the
    best mean minus the best candidate's standard error (the fold scores'
    standard deviation over ``sqrt(n_splits)``): the threshold of
    :func:`one_standard_error_rule`. Tied candidates are ones the
    cross-validation cannot tell apart from the best; which of them a search
    picks is partly chance. The paired columns compare every candidate with
    the best fold by fold, which removes what all candidates share on a fold
    (e.g. how noisy its held-out trajectories are).

    Parameters
    ----------
    search : fitted GridSearchCV or RandomizedSearchCV, or dict
        A fitted search, or its ``cv_results_``.
    metric : str, default="score"
        Which score: ``"score"`` for single-metric searches, else the key of
        the ``scoring`` dict.

    Returns
    -------
    table : dict of ndarray
        One entry per candidate, in the order of ``cv_results_``:

        - ``"params"``: the candidates' parameters (a list);
        - ``"mean"``: mean test score over the folds;
        - ``"se"``: its standard error, ``std / sqrt(n_splits)``;
        - ``"difference"``: mean of the fold-by-fold differences to the best
          candidate (0 for the best, negative for the others);
        - ``"difference_se"``: standard error of those differences;
        - ``"tied"``: whether the candidate ties with the best (the best
          included);
        - ``"best"``: whether it is the candidate with the best mean score.

        ``pandas.DataFrame(table)`` shows it as a table. Candidates with a
        non-finite mean score (a failed fit or rollout in some fold) have NaN
        differences and never tie.

    Raises
    ------
    ValueError
        If ``search`` is neither a fitted search nor a ``cv_results_`` dict
        with the test scores of ``metric`` per split, or no candidate has a
        finite mean score.

    See Also
    --------
    one_standard_error_rule : Picks the smallest of the tied candidates.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian.model_selection import candidate_table
    >>> results = {
    ...     "params": [{"degree": 2}, {"degree": 3}, {"degree": 4}],
    ...     "split0_test_score": np.array([0.80, 0.95, 0.96]),
    ...     "split1_test_score": np.array([0.82, 0.97, 0.96]),
    ...     "mean_test_score": np.array([0.81, 0.96, 0.96]),
    ... }
    >>> table = candidate_table(results)
    >>> table["tied"].tolist(), table["best"].tolist()
    ([False, True, True], [False, True, False])
    >>> np.round(table["se"], 4).tolist()
    [0.0071, 0.0071, 0.0]
    """
    results = getattr(search, "cv_results_", search)
    if not isinstance(results, dict) or "params" not in results:
        raise ValueError(
            f"search must be a fitted GridSearchCV (or RandomizedSearchCV) or its "
            f"cv_results_ dict; got {type(search).__name__}. Fit the search first."
        )
    if not isinstance(metric, str):
        raise ValueError(
            f"metric must be the name of a score in cv_results_ ('score', or a key "
            f"of the scoring dict); got {metric!r}."
        )
    keys = sorted(
        (key for key in results if key.startswith("split") and key.endswith(f"_test_{metric}")),
        key=lambda key: int(key[len("split"): key.index("_")]),
    )
    if not keys:
        raise ValueError(
            f"cv_results_ has no per-split test scores of {metric!r}: pass metric= the name "
            f"of a score of the search ('score' for single-metric searches)."
        )
    folds = np.column_stack([np.asarray(results[key], dtype=float) for key in keys])
    n_splits = folds.shape[1]
    means = folds.mean(axis=1)
    finite = np.isfinite(folds).all(axis=1)
    if not finite.any():
        raise ValueError(
            f"No candidate has a finite mean {metric!r}: every candidate failed in some "
            f"fold. Rerun the search with error_score='raise' to see why."
        )
    se = folds.std(axis=1) / np.sqrt(n_splits)
    best = int(np.flatnonzero(finite)[np.argmax(means[finite])])
    paired = folds - folds[best]
    difference = np.where(finite, paired.mean(axis=1), np.nan)
    difference_se = np.where(finite, paired.std(axis=1) / np.sqrt(n_splits), np.nan)
    tied = ties(folds, best, higher_is_better=True, paired=False)
    return {
        "params": list(results["params"]),
        "mean": means,
        "se": se,
        "difference": difference,
        "difference_se": difference_se,
        "tied": tied,
        "best": np.arange(means.shape[0]) == best,
    }


def multistep_scorer(n_steps=5, *, stride=1):
    """Held-out score from short predictions started at every observation.

    A scorer for ``scoring=`` of :class:`~sklearn.model_selection.GridSearchCV`
    and :func:`~sklearn.model_selection.cross_val_score`. Like the default
    ``score``, it compares predictions with the raw held-out *observations*
    and never with derivatives or smoothed states, so it cannot reward the
    derivative estimator being tuned; unlike it, it restarts from every
    observation, which averages out the noise of the starting states.

    Parameters
    ----------
    n_steps : int, default=5
        Prediction horizon, in sampling intervals.
    stride : int, default=1
        Distance between starts, in samples; ``stride=n_steps`` costs as much
        as the default score.

    Returns
    -------
    scorer : callable
        ``scorer(estimator, X, y=None) -> float``, where ``estimator`` is a
        fitted pipeline ending in a regressor and ``X`` held-out raw
        trajectories (or ``estimator`` a regressor and ``X`` the derivative
        layout). The score is ``1 - mean_k min(1, e_k)``, with ``e_k`` the
        relative error of trajectory ``k`` (see
        ``sk_hamiltonian._scoring.multistep_errors``); at most 1, and 0 for a
        model whose predictions fail.

    See Also
    --------
    one_standard_error_rule : Prefer smaller models among near-best scores.
    sk_hamiltonian.HamiltonianRegressor.score : The default rollout score.

    Examples
    --------
    >>> from sklearn.model_selection import cross_val_score
    >>> from sklearn.pipeline import make_pipeline
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import make_trajectories
    >>> from sk_hamiltonian.model_selection import multistep_scorer
    >>> X = make_trajectories("henon_heiles", 60, 20, dt=0.05, random_state=0)
    >>> pipe = make_pipeline(DerivativeTransformer(dt=0.05, method="finite_difference"),
    ...                      HamiltonianRegressor(degree=3))
    >>> scores = cross_val_score(pipe, X, cv=3, scoring=multistep_scorer(5))
    >>> bool(scores.min() > 0.999)
    True
    """
    for name, value in (("n_steps", n_steps), ("stride", stride)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
            raise ValueError(f"{name} must be a positive integer; got {value!r}.")

    def scorer(estimator, X, y=None):
        if isinstance(estimator, Pipeline):
            model = _final_regressor(estimator)
            Xt = estimator[:-1].transform(X)
        else:
            model, Xt = _final_regressor(estimator), X
        if not is_trajectory_container(Xt):
            raise ValueError(
                "multistep_scorer needs trajectories: raw trajectories for a pipeline, "
                "or the DerivativeTransformer layout for a bare regressor."
            )
        errors = multistep_errors(model, Xt, n_steps, stride=stride)
        return float(1.0 - np.mean(np.minimum(errors, 1.0)))

    return scorer


def segment_starts(n_times, segment_length, tail="merge"):
    """First samples of the segments :func:`segment_trajectories` cuts a trajectory into."""
    starts = list(range(0, n_times, segment_length))
    if tail == "merge" and len(starts) > 1 and n_times - starts[-1] < segment_length:
        starts.pop()
    return starts


def segment_trajectories(X, segment_length, *, n_groups=None, tail="merge"):
    """Cut trajectories into contiguous segments, with group labels for blocked CV.

    Cross-validation holds out whole trajectories, so one long record cannot
    be cross-validated as it is. Cut into segments, it becomes many short
    trajectories; the group labels keep neighbouring segments together, so
    that :class:`~sklearn.model_selection.GroupKFold` holds out contiguous
    stretches of the record (blocked cross-validation). Every sample lands in
    exactly one segment, in order.

    Parameters
    ----------
    X : array-like of shape (n_trajectories, n_times, n_columns) or list of 2-D arrays
        Trajectories, with or without a leading time column (the columns are
        not interpreted: segments keep them all, time stamps included).
    segment_length : int
        Samples per segment, at least 2. A trajectory with fewer samples
        stays one segment.
    n_groups : int, default=None
        Number of groups: the segments, in the order of ``X`` (the segments
        of ``X[0]`` in time order, then those of ``X[1]``, ...), are split into
        ``n_groups`` runs of consecutive segments of nearly equal counts.
        Use it as the number of folds of ``GroupKFold`` for blocked
        cross-validation. None gives every segment its own group.
    tail : {"merge", "keep"}, default="merge"
        What happens to the last ``n_times % segment_length`` samples of a
        trajectory: ``"merge"`` appends them to its last segment (which may
        then hold up to ``2 * segment_length - 1`` samples), ``"keep"`` makes
        them a shorter segment of their own (which may be too short for a
        derivative estimate).

    Returns
    -------
    segments : ndarray of shape (n_segments, segment_length, n_columns) or list of 2-D arrays
        The segments; a 3-D array when ``X`` is one and all segments have the
        same length, else a list.
    groups : ndarray of shape (n_segments,)
        Group label of each segment, for the ``groups`` argument of
        :class:`~sklearn.model_selection.GridSearchCV` and
        :func:`~sklearn.model_selection.cross_val_score`.

    See Also
    --------
    sklearn.model_selection.GroupKFold : Holds out whole groups.

    Notes
    -----
    Every segment is a trajectory of its own downstream: its derivatives are
    estimated from its own samples only, and the default score rolls it out
    from an initial state fitted to its own observations.

    Examples
    --------
    >>> import numpy as np
    >>> from sklearn.model_selection import GroupKFold, cross_val_score
    >>> from sklearn.pipeline import make_pipeline
    >>> from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
    >>> from sk_hamiltonian.datasets import single_pendulum
    >>> from sk_hamiltonian.model_selection import segment_trajectories
    >>> system = single_pendulum()
    >>> t = 0.01 * np.arange(1000)
    >>> record = system.solve(system.initial_state, t)           # one long record
    >>> segments, groups = segment_trajectories(record[None], 50, n_groups=5)
    >>> segments.shape, groups[:6].tolist()
    ((20, 50, 2), [0, 0, 0, 0, 1, 1])
    >>> pipe = make_pipeline(DerivativeTransformer(dt=0.01, method="finite_difference"),
    ...                      HamiltonianRegressor(degree=6))
    >>> scores = cross_val_score(pipe, segments, groups=groups, cv=GroupKFold(5))
    >>> bool(scores.min() > 0.99)
    True
    """
    if (
        isinstance(segment_length, bool)
        or not isinstance(segment_length, numbers.Integral)
        or segment_length < 2
    ):
        raise ValueError(
            f"segment_length must be an integer of at least 2 samples; got {segment_length!r}."
        )
    if tail not in ("merge", "keep"):
        raise ValueError(
            f"tail must be 'merge' (append a short tail to the last segment) or 'keep' "
            f"(make it a segment of its own); got {tail!r}."
        )
    trajectories, is_array = check_trajectories(X)
    segments = []
    for T in trajectories:
        segments.extend(np.split(T, segment_starts(T.shape[0], segment_length, tail)[1:]))
    n_segments = len(segments)
    if n_groups is None:
        groups = np.arange(n_segments)
    else:
        if (
            isinstance(n_groups, bool)
            or not isinstance(n_groups, numbers.Integral)
            or not 1 <= n_groups <= n_segments
        ):
            raise ValueError(
                f"n_groups must be None or an integer from 1 to the number of segments "
                f"({n_segments} of {segment_length} samples here); got {n_groups!r}. Use a "
                f"shorter segment_length or fewer groups."
            )
        runs = np.array_split(np.arange(n_segments), n_groups)
        groups = np.concatenate([np.full(run.size, g) for g, run in enumerate(runs)])
    if is_array and len({S.shape[0] for S in segments}) == 1:
        return np.stack(segments), groups
    return segments, groups
