"""HamiltonianSearchCV: model spaces, fit targets, de-noising, degree and sparsity, cross-validated."""

import itertools
import time
import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.model_selection import check_cv
from sklearn.pipeline import Pipeline
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.parallel import Parallel, delayed
from sklearn.utils.validation import check_is_fitted

from .._derivatives import DerivativeTransformer
from .._hamiltonian import HamiltonianRegressor
from .._trajectories import check_trajectories
from ._fold_problems import FoldProblems, take
from ._refine import refine_on_trajectories
from ._selection import SELECTIONS, pick_among, pick_within

FIT_TARGETS = ("derivatives", "steps", "simpson", "weak")
FAMILIES = ("polynomial", "periodic", "mixed")
# Position coordinates searched one by one up to this many degrees of
# freedom; beyond, all positions share one family (3**d spaces grow fast).
PER_COORDINATE_DOF = 2
# Spaces kept after the screen, at most.
MAX_SPACES = 3
# Training equations per unknown a candidate needs in every fold.
ROWS_PER_UNKNOWN = 2


def auto_spaces(n_states):
    """The model spaces ``spaces="auto"`` searches for data with ``n_states`` variables.

    Each position coordinate is polynomial, periodic (an angle of period
    ``2 pi``) or mixed (both families); each combination is offered as a
    general Hamiltonian and as a mechanical one (``momentum_degree=2``).

    Parameters
    ----------
    n_states : int
        Number of state variables ``2d``.

    Returns
    -------
    spaces : list of dict
        Parameters of :class:`~sk_hamiltonian.HamiltonianRegressor`.
    """
    d = n_states // 2
    if d <= PER_COORDINATE_DOF:
        choices = list(itertools.product(FAMILIES, repeat=d))
    else:
        choices = [(family,) * d for family in FAMILIES]
    spaces = []
    for families in choices:
        space = {}
        for name in ("periodic", "mixed"):
            flags = [False] * d + [family == name for family in families]
            if any(flags):
                space[name] = flags
        for structure in ({}, {"momentum_degree": 2}):
            spaces.append({**space, **structure})
    return spaces


def _pipeline_params(denoise, fit_on, space, degree, threshold, damping, domain=None):
    """Parameters of ``make_pipeline(DerivativeTransformer(), HamiltonianRegressor())``."""
    params = {f"derivativetransformer__{key}": value
              for key, value in _transformer_params(denoise).items()}
    for key, value in space.items():
        params[f"hamiltonianregressor__{key}"] = value
    params["hamiltonianregressor__degree"] = int(degree)
    params["hamiltonianregressor__threshold"] = float(threshold)
    params["hamiltonianregressor__fit_on"] = fit_on
    if damping:
        params["hamiltonianregressor__damping"] = True
    if domain is not None:
        params["hamiltonianregressor__domain"] = domain
    return params


class HamiltonianSearchCV(BaseEstimator):
    """Cross-validated search over model spaces, fit targets, de-noising, degree and sparsity.

    What a :class:`~sklearn.model_selection.GridSearchCV` over a pipeline
    ``make_pipeline(DerivativeTransformer(dt), HamiltonianRegressor())`` would
    search, in one object that shares the work among candidates: for each
    derivative layout (de-noising degree, or finite differences), fit target
    and model space, the normal equations of every fold come from one pass
    over the data, and every degree and threshold is a smaller solve on them.

    The search runs in three stages on the same folds of whole trajectories,
    and a fourth on all of them:

    1. **Screen** the model spaces (``spaces``) on one reference layout (the
       middle de-noising degree) and the derivative fit, at the smallest
       degree: each candidate's held-out *equation error* (the relative
       residual of the held-out trajectories' least-squares rows) ranks
       spaces, degrees and thresholds honestly, since they are all measured
       against the same targets. The spaces whose best candidate ties with
       the best one are kept (at most three: the smallest models first).
    2. **Search** every layout and fit target in the kept spaces, degree by
       degree from the smallest (a degree no better than the best below it,
       within one standard error, ends the space's search), at every
       threshold; within each layout and fit target the candidate with the
       fewest terms among those tied with the lowest mean equation error (one
       standard error) is that pair's *finalist*.
    3. **Score** the finalists by the regressors' default rollout score
       against the held-out raw observations (which never sees the
       derivatives or smoothed states being compared), and choose by
       ``selection``.
    4. **Refine** (``refine="trajectories"``) the chosen model, refitted on
       all the data: the coefficients of its kept terms are fitted to the
       raw trajectories themselves, each simulated from an initial state of
       its own, with weights from a noise model ``a_i + b_i x_i^2`` per
       variable estimated from the residuals (the output-error estimate).
       The terms stay those chosen; their coefficients no longer carry the
       bias and noise of the estimated derivatives.

    Parameters
    ----------
    dt : float, default=None
        Sampling step of the trajectories; None: time stamps in the first
        column, as for :class:`~sk_hamiltonian.DerivativeTransformer`.
    denoise_degrees : sequence of {"finite_difference"} or int, default=("finite_difference", 3, 5, 8)
        Derivative layouts: second-order finite differences, or de-noising
        polynomials of these degrees ``Q``.
    degrees : sequence of int, default=(4, 6, 8, 10)
        Degrees ``n`` of ``H~``, tried from the smallest until one is no
        better than those below it. Degrees with fewer than two training
        equations per unknown in some fold are left out.
    spaces : "auto" or list of dict, default="auto"
        Model spaces, as parameters of
        :class:`~sk_hamiltonian.HamiltonianRegressor` (``periodic``,
        ``mixed``, ``momentum_degree``, ``separable``, ``max_interaction``,
        ``couplings``, ``solver``). ``"auto"`` (:func:`auto_spaces`): each
        position coordinate polynomial, periodic or mixed, each as a general
        and as a mechanical Hamiltonian (``momentum_degree=2``).
    fit_on : sequence of {"derivatives", "steps", "simpson", "weak"}, default=("derivatives", "steps", "simpson", "weak")
        Fit targets (see :class:`~sk_hamiltonian.HamiltonianRegressor`). The
        steps, Simpson and weak fits use the layout's states: the de-noised
        states with a polynomial, the raw ones with finite differences.
    thresholds : sequence of float, default=(0.0, 0.001, 0.01, 0.03, 0.1)
        Sparsity thresholds (0: every term).
    damping : bool, default=False
        Fit linear friction with every candidate.
    domain : array-like of shape (n_states, 2), default=None
        The box of every candidate (for a periodic variable, its period);
        None: the bounding box of each derivative layout's states, and
        ``[-pi, pi)`` for periodic variables. Needed when a variable is
        constant in the data.
    refine : {"trajectories"} or None, default="trajectories"
        Refit the chosen model's kept coefficients to the raw trajectories
        (stage 4), with the friction of a model fitted with ``damping``.
        Skipped, with the reason in ``refinement_``, for a model of more than
        40 terms, or whose simulation of the training trajectories fails.
        None: the least-squares fit of the chosen candidate, as refitted.
    selection : {"simplest", "best_score"}, default="simplest"
        The final choice among the finalists' rollout scores.
        ``"best_score"``: the best mean score. ``"simplest"``: among the
        finalists within one paired standard error of the best mean score
        (which the data cannot tell from it), the fewest terms, then the
        smoothest derivative layout (the lowest de-noising degree; noise left
        in the states biases the coefficients toward zero), then the least
        biased fit target (weak, Simpson, steps, then derivatives), then the
        best mean score.
    cv : int, cross-validation generator or iterable, default=5
        Folds of whole trajectories, as in
        :class:`~sklearn.model_selection.GridSearchCV`.
    n_jobs : int, default=None
        Layouts, fit targets and spaces assembled in parallel (joblib).
    verbose : int, default=0
        Print the stages' progress when positive.

    Attributes
    ----------
    best_estimator_ : Pipeline
        ``make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())``
        with ``best_params_``, fitted on all the data.
    best_params_ : dict
        The chosen candidate's parameters, in the pipeline's names.
    best_index_ : int
        Its row in ``cv_results_``.
    best_score_ : float
        Its mean rollout score.
    cv_results_ : dict of ndarray
        One row per candidate, laid out as
        ``cv_results_`` of :class:`~sklearn.model_selection.GridSearchCV`
        (``params``, ``param_<name>``, ``split<k>_test_score``,
        ``mean_test_score``, ``std_test_score``, ``rank_test_score``), with
        the rollout scores of the finalists (NaN for the other candidates),
        and ``split<k>_equation_error``, ``mean_equation_error``,
        ``std_equation_error``, ``n_terms`` (on all the data), ``stage``
        (``"screen"``, ``"search"`` or ``"finalist"``) and ``tied`` (the
        finalists the data cannot tell from the best score).
    spaces_ : list of dict
        The model spaces screened.
    kept_spaces_ : list of dict
        The model spaces searched after the screen.
    n_splits_ : int
        Number of folds.
    refinement_ : dict
        Stage 4's outcome: ``status`` (``"refined"``, ``"not asked"``, or
        ``"kept: "`` and why the least-squares coefficients were kept), and
        when refined ``n_terms``, ``n_iter`` (Levenberg-Marquardt iterations),
        ``noise`` (the variance model's ``(a_i, b_i)`` per variable),
        ``rms`` (the root-mean-square residual per variable) and ``change``
        (the largest relative change of a kept coefficient).
    refit_time_ : float
        Seconds of the final fit on all the data, the refinement included.
    search_time_ : float
        Seconds of the whole search, the refit included.
    n_features_in_ : int
        Number of state variables.

    See Also
    --------
    sklearn.model_selection.GridSearchCV : The general search.
    sk_hamiltonian.model_selection.candidate_table : Ties among the finalists.

    Examples
    --------
    >>> from sk_hamiltonian.datasets import make_trajectories, single_pendulum
    >>> from sk_hamiltonian.inspection import hamiltonian_terms
    >>> from sk_hamiltonian.model_selection import HamiltonianSearchCV
    >>> X = make_trajectories(single_pendulum(), 100, 40, dt=0.01, noise=0.02, random_state=0)
    >>> search = HamiltonianSearchCV(dt=0.01, denoise_degrees=[3], degrees=[4],
    ...                              fit_on=["derivatives", "weak"]).fit(X)
    >>> sorted(term.text for term in hamiltonian_terms(search.best_estimator_[-1]))
    ['cos(q)', 'p^2']
    >>> search.best_params_["hamiltonianregressor__periodic"]
    [False, True]
    """

    _parameter_constraints = {
        "dt": [Interval(Real, 0, None, closed="neither"), None],
        "denoise_degrees": ["array-like"],
        "degrees": ["array-like"],
        "spaces": [StrOptions({"auto"}), list],
        "fit_on": ["array-like"],
        "thresholds": ["array-like"],
        "damping": ["boolean"],
        "domain": ["array-like", None],
        "refine": [StrOptions({"trajectories"}), None],
        "selection": [StrOptions(set(SELECTIONS))],
        "cv": ["cv_object"],
        "n_jobs": [Integral, None],
        "verbose": ["verbose"],
    }

    def __init__(
        self, dt=None, *, denoise_degrees=("finite_difference", 3, 5, 8), degrees=(4, 6, 8, 10),
        spaces="auto", fit_on=FIT_TARGETS, thresholds=(0.0, 0.001, 0.01, 0.03, 0.1),
        damping=False, domain=None, refine="trajectories", selection="simplest", cv=5,
        n_jobs=None, verbose=0,
    ):
        self.dt = dt
        self.denoise_degrees = denoise_degrees
        self.degrees = degrees
        self.spaces = spaces
        self.fit_on = fit_on
        self.thresholds = thresholds
        self.damping = damping
        self.domain = domain
        self.refine = refine
        self.selection = selection
        self.cv = cv
        self.n_jobs = n_jobs
        self.verbose = verbose

    def fit(self, X, y=None, groups=None):
        """Search the candidates on trajectories ``X`` and refit the chosen one on all of them.

        Parameters
        ----------
        X : array-like of shape (n_trajectories, n_times, n_columns) or list of 2-D arrays
            Raw trajectories, sampled every ``dt`` (``n_columns = 2d``) or
            with their time stamps in the first column (``dt=None``).
        y : None
            Ignored.
        groups : array-like of shape (n_trajectories,), default=None
            Group labels of the trajectories, for a ``cv`` such as
            :class:`~sklearn.model_selection.GroupKFold`.

        Returns
        -------
        self : HamiltonianSearchCV
            Fitted.
        """
        self._validate_params()
        start = time.perf_counter()
        trajectories, _ = check_trajectories(X, min_times=3)
        n_states = trajectories[0].shape[1] - (1 if self.dt is None else 0)
        denoise = self._check_denoise(min(T.shape[0] for T in trajectories))
        degrees = self._check_values("degrees", self.degrees, integer=True, low=1)
        thresholds = self._check_values("thresholds", self.thresholds, integer=False, low=0)
        fit_on = self._check_fit_on()
        spaces = auto_spaces(n_states) if self.spaces == "auto" else self._check_spaces()
        n_trajectories = len(trajectories)
        cv = check_cv(self.cv)
        folds = [test for _, test in cv.split(np.zeros((n_trajectories, 1)), groups=groups)]
        if len(folds) < 2:
            raise ValueError(f"cv must give at least 2 folds; got {len(folds)}.")
        layouts = {
            key: DerivativeTransformer(dt=self.dt, **_transformer_params(key)).fit_transform(X)
            for key in denoise
        }
        # Stage 1: the spaces, on the reference layout and fit target.
        reference = _reference(denoise)
        target = "derivatives" if "derivatives" in fit_on else fit_on[0]
        self._say(f"screen: {len(spaces)} spaces on {_describe_layout(reference)}, {target}, "
                  f"degree {degrees[0]}")
        screened = Parallel(n_jobs=self.n_jobs)(
            delayed(_unit)(layouts[reference], folds, [space], target, [degrees[0]], thresholds,
                           self.damping, self.domain, reference, rollout=False)
            for space in spaces
        )
        records, failures = [], []
        for k, (unit_records, _, unit_failures) in enumerate(screened):
            failures.extend(unit_failures)
            for record in unit_records:
                record.update(space=k, stage="screen")
            records.extend(unit_records)
        kept = _kept_spaces(records, failures, spaces)
        self._say(f"kept: {[spaces[k] for k in kept]}")
        # Stages 2 and 3: every layout and fit target in the kept spaces.
        pairs = list(itertools.product(denoise, fit_on))
        results = Parallel(n_jobs=self.n_jobs)(
            delayed(_unit)(layouts[key], folds, [spaces[k] for k in kept], target_, degrees,
                           thresholds, self.damping, self.domain, key, rollout=True)
            for key, target_ in pairs
        )
        finalists = []
        for (key, target_), (unit_records, finalist, unit_failures) in zip(pairs, results):
            failures.extend(unit_failures)
            for record in unit_records:
                record.update(space=kept[record["space"]], stage="search")
            if finalist is not None:
                unit_records[finalist]["stage"] = "finalist"
                finalists.append(len(records) + finalist)
            records.extend(unit_records)
        if not finalists:
            raise ValueError(
                "No candidate could be fitted and scored in every fold. Give more "
                "trajectories, lower degrees, or fewer folds." + _reason(failures)
            )
        scores = np.array([records[i]["scores"] for i in finalists])
        choice, tied = pick_among(
            scores, [records[i]["n_terms"] for i in finalists],
            [_smoothing(records[i]["denoise"]) for i in finalists],
            [records[i]["fit_on"] for i in finalists], self.selection,
        )
        if choice is None:
            raise ValueError(
                "Every finalist's rollout failed in some fold: no candidate can be "
                "chosen. Inspect cv_results_ or give more data."
            )
        for i, flag in zip(finalists, tied):
            records[i]["tied"] = bool(flag)
        self.spaces_ = spaces
        self.kept_spaces_ = [spaces[k] for k in kept]
        self.n_splits_ = len(folds)
        self.cv_results_ = _cv_results(records, spaces, len(folds), self.damping, self.domain)
        self.best_index_ = finalists[choice]
        self.best_params_ = self.cv_results_["params"][self.best_index_]
        self.best_score_ = float(self.cv_results_["mean_test_score"][self.best_index_])
        refit_start = time.perf_counter()
        self.best_estimator_ = Pipeline([
            ("derivativetransformer", DerivativeTransformer(dt=self.dt)),
            ("hamiltonianregressor", HamiltonianRegressor()),
        ]).set_params(**self.best_params_).fit(X)
        self.refinement_ = dict(status="not asked")
        if self.refine == "trajectories":
            self._say("refine: the chosen model's coefficients on the raw trajectories")
            self.refinement_ = refine_on_trajectories(
                self.best_estimator_[-1], trajectories, self.dt)
            self._say(f"refine: {self.refinement_['status']}")
        self.refit_time_ = time.perf_counter() - refit_start
        self.search_time_ = time.perf_counter() - start
        self.n_features_in_ = n_states
        return self

    # ------------------------------------------------------------ delegation
    def predict(self, X):
        """The chosen model's time derivatives at the states of trajectories ``X``.

        Parameters
        ----------
        X : array-like
            Raw trajectories, as for :meth:`fit`.

        Returns
        -------
        dXdt : ndarray or list of ndarray
            ``predict`` of
            ``best_estimator_``: the learned vector field at the
            trajectories' (de-noised) states, in their shape.
        """
        check_is_fitted(self)
        return self.best_estimator_.predict(X)

    def score(self, X, y=None):
        """The rollout score of ``best_estimator_`` on trajectories ``X``.

        Parameters
        ----------
        X : array-like
            Raw trajectories, as for :meth:`fit`.
        y : None
            Ignored.

        Returns
        -------
        score : float
            See :meth:`sk_hamiltonian.HamiltonianRegressor.score`.
        """
        check_is_fitted(self)
        return self.best_estimator_.score(X)

    def simulate(self, x0, t, **kwargs):
        """Integrate the chosen model from one or several initial states.

        Parameters
        ----------
        x0 : array-like of shape (n_states,) or (n_initial, n_states)
            Initial state(s), at time ``t[0]``.
        t : array-like of shape (n_times,)
            Strictly increasing output times.
        **kwargs
            ``method``, ``max_step`` and ``on_failure`` of
            :meth:`sk_hamiltonian.HamiltonianRegressor.simulate`.

        Returns
        -------
        X : ndarray of shape (n_times, n_states) or (n_initial, n_times, n_states)
            The trajectories, sampled at ``t``.
        """
        check_is_fitted(self)
        return self.best_estimator_[-1].simulate(x0, t, **kwargs)

    def hamiltonian(self, X):
        """The chosen model's learned Hamiltonian ``H~`` at states ``X``.

        Parameters
        ----------
        X : array-like of shape (n_samples, n_states) or (..., n_states)
            States.

        Returns
        -------
        H : ndarray of shape X.shape[:-1]
            See :meth:`sk_hamiltonian.HamiltonianRegressor.hamiltonian`.
        """
        check_is_fitted(self)
        return self.best_estimator_[-1].hamiltonian(X)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        # Raw trajectories, as DerivativeTransformer takes them.
        tags.input_tags.two_d_array = False
        tags.input_tags.three_d_array = True
        tags.target_tags.required = False
        tags.requires_fit = True
        return tags

    # ------------------------------------------------------------ checks
    def _say(self, message):
        if self.verbose:
            print(f"[HamiltonianSearchCV] {message}", flush=True)

    def _check_denoise(self, shortest):
        values = list(self.denoise_degrees)
        if not values:
            raise ValueError("denoise_degrees must name at least one derivative layout.")
        out = []
        for value in values:
            if isinstance(value, str) and value == "finite_difference":
                out.append(value)
            elif isinstance(value, Integral) and not isinstance(value, bool) and value >= 1:
                out.append(int(value))
            else:
                raise ValueError(
                    f"denoise_degrees entries must be 'finite_difference' or a de-noising "
                    f"degree Q >= 1; got {value!r}."
                )
        usable = [v for v in out if v == "finite_difference" or v <= shortest - 2]
        if not usable:
            raise ValueError(
                f"Every de-noising degree in denoise_degrees={values!r} is too large for the "
                f"shortest trajectory ({shortest} samples; Q must be at most samples - 2): give "
                f"lower degrees or 'finite_difference'."
            )
        if len(usable) < len(out):
            warnings.warn(
                f"HamiltonianSearchCV: de-noising degrees "
                f"{[v for v in out if v not in usable]} left out: the shortest trajectory has "
                f"{shortest} samples, and Q must be at most samples - 2.",
                UserWarning, stacklevel=3,
            )
        return list(dict.fromkeys(usable))

    @staticmethod
    def _check_values(name, values, integer, low):
        values = list(np.ravel(values))
        ok = bool(values) and all(
            not isinstance(v, bool) and isinstance(v, Integral if integer else Real)
            and np.isfinite(v) and v >= low for v in values
        )
        if not ok:
            kind = "integers" if integer else "finite numbers"
            raise ValueError(f"{name} must be a non-empty list of {kind} >= {low}; got {values!r}.")
        cast = int if integer else float
        return sorted({cast(v) for v in values})

    def _check_fit_on(self):
        values = list(self.fit_on) if not isinstance(self.fit_on, str) else [self.fit_on]
        if not values or any(v not in FIT_TARGETS for v in values):
            raise ValueError(f"fit_on must be a non-empty list of {FIT_TARGETS}; got {self.fit_on!r}.")
        return list(dict.fromkeys(values))

    def _check_spaces(self):
        allowed = {"periodic", "mixed", "momentum_degree", "separable", "max_interaction",
                   "couplings", "solver"}
        if not self.spaces:
            raise ValueError("spaces must be 'auto' or a non-empty list of dicts.")
        for space in self.spaces:
            if not isinstance(space, dict) or set(space) - allowed:
                raise ValueError(
                    f"spaces entries must be dicts of HamiltonianRegressor parameters among "
                    f"{sorted(allowed)}; got {space!r}."
                )
        return [dict(space) for space in self.spaces]


def _transformer_params(denoise):
    if denoise == "finite_difference":
        return {"method": "finite_difference"}
    return {"method": "polynomial", "degree": int(denoise)}


def _describe_layout(denoise):
    return "finite differences" if denoise == "finite_difference" else f"Q={denoise}"


def _smoothing(denoise):
    """Order of layouts from the smoothest: the de-noising degree, finite differences last."""
    return np.inf if denoise == "finite_difference" else float(denoise)


def _reference(denoise):
    """The layout the spaces are screened on: the middle de-noising degree."""
    polynomial = sorted(v for v in denoise if v != "finite_difference")
    return polynomial[len(polynomial) // 2] if polynomial else "finite_difference"


def _reason(failures):
    """The first failure's message, as the end of an error message."""
    return f" The first candidate's error: {failures[0]}" if failures else ""


def _unit(Xt, folds, spaces, fit_on, degrees, thresholds, damping, domain, denoise, rollout):
    """Every candidate of one layout and fit target in ``spaces``; with ``rollout``, its finalist scored.

    Returns the candidates' records (``space`` is the index into ``spaces``),
    the row of the finalist (None without ``rollout`` or without one), and
    the messages of the spaces that could not be set up.
    """
    records, problems, failures = [], [], []
    n_folds = len(folds)
    for k, space in enumerate(spaces):
        params = {**space, "fit_on": fit_on, "damping": damping}
        # Degrees from the smallest, each assembled on its own: a degree whose
        # best candidate is no better than the best below (within one standard
        # error) ends the space's search, as the larger ones, which cost the
        # most, would add terms the data do not need.
        best = None
        for degree in degrees:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    problem = FoldProblems(params, Xt, folds, degree, domain)
                except ValueError as error:  # e.g. a constant variable, or no Simpson pairs
                    failures.append(str(error))
                    break
            size = problem.n_unknowns(degree)
            if ROWS_PER_UNKNOWN * size > problem.n_rows * (n_folds - 1) / n_folds:
                break
            problems.append(problem)
            found = [_candidate(problem, degree, threshold, n_folds)
                     for threshold in thresholds]
            for record in found:
                record.update(denoise=denoise, fit_on=fit_on, space=k, size=size,
                              problem=len(problems) - 1)
            records.extend(found)
            errors = np.array([r["errors"] for r in found])
            here = int(np.nanargmin(errors.mean(axis=1))) if np.isfinite(errors).any() else None
            if here is None:
                break
            mean = errors[here].mean()
            if best is not None and mean >= best[0] - best[1]:
                break
            best = (mean, errors[here].std() / np.sqrt(n_folds))
    finalist = None
    if rollout and records:
        finalist, _ = pick_within(
            np.array([r["errors"] for r in records]), np.array([r["n_terms"] for r in records]),
            np.array([r["size"] for r in records]),
        )
    if finalist is not None:
        record = records[finalist]
        problem = problems[record["problem"]]
        started = time.perf_counter()
        for fold, test in enumerate(folds):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, solution = problem.solve(record["degree"], record["threshold"], fold)
                model = problem.fitted(record["degree"], record["threshold"], solution, fold)
                try:
                    record["scores"][fold] = model.score(take(Xt, test))
                except Exception:  # a rollout that cannot be scored counts as failed
                    record["scores"][fold] = np.nan
        record["score_time"] = (time.perf_counter() - started) / n_folds
    for record in records:
        del record["problem"]
    return records, finalist, failures


def _candidate(problem, degree, threshold, n_folds):
    """One candidate's record: its equation error in every fold, its terms on all the data."""
    started = time.perf_counter()
    errors = np.full(n_folds, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for fold in range(n_folds):
            columns, solution = problem.solve(degree, threshold, fold)
            errors[fold] = problem.equation_error(columns, solution.coef, fold)
        _, solution = problem.solve(degree, threshold)
    return dict(degree=degree, threshold=threshold, errors=errors,
                n_terms=int(solution.n_kept),
                fit_time=(time.perf_counter() - started) / (n_folds + 1),
                scores=np.full(n_folds, np.nan), score_time=np.nan, tied=False)


def _within(inner, outer):
    """Whether every function of model space ``inner`` is one of ``outer`` (same variables).

    A polynomial or periodic variable lies within a mixed one (the Fourier
    terms of an angle of period ``2 pi`` are a mixed variable's), a
    mechanical Hamiltonian within a general one, a separable one within a
    non-separable one; other parameters must agree.
    """
    keys = (set(inner) | set(outer)) - {"periodic", "mixed", "momentum_degree", "separable"}
    if any(inner.get(key) != outer.get(key) for key in keys):
        return False
    flags = {name: (np.asarray(space.get("periodic") or [], bool),
                    np.asarray(space.get("mixed") or [], bool))
             for name, space in (("inner", inner), ("outer", outer))}
    size = max(f.size for pair in flags.values() for f in pair)
    (p_in, m_in), (p_out, m_out) = [
        tuple(np.resize(f, size) if f.size else np.zeros(size, bool) for f in pair)
        for pair in flags.values()
    ]
    # Per variable: polynomial (neither), periodic, or mixed (both families).
    if np.any(p_out & ~p_in) or np.any(p_in & ~p_out & ~m_out) or np.any(m_in & ~m_out):
        return False
    if np.any(~p_in & ~m_in & p_out):  # a polynomial variable is no angle
        return False
    degree_in, degree_out = inner.get("momentum_degree"), outer.get("momentum_degree")
    if degree_out is not None and (degree_in is None or degree_in > degree_out):
        return False
    return bool(inner.get("separable", False) or not outer.get("separable", False))


def _kept_spaces(records, failures, spaces):
    """The spaces whose screened candidates tie with the best, the smallest of each nest.

    A tied space is dropped when a space within it (:func:`_within`) ties
    with as few terms: it adds only functions the data do not need. At most
    :data:`MAX_SPACES` are kept, the smallest models first.
    """
    if not records:
        raise ValueError(
            "No model space could be set up on the screening layout." + _reason(failures))
    errors = np.array([r["errors"] for r in records])
    best, tied = pick_within(errors, np.array([r["n_terms"] for r in records]),
                             np.array([r["size"] for r in records]))
    if best is None:
        raise ValueError(
            "No model space could be fitted in every fold on the screening layout: give more "
            "trajectories or lower degrees."
        )
    ranking = {}
    for record, flag in zip(records, tied):
        if flag:
            key = (record["n_terms"], record["size"], float(np.mean(record["errors"])))
            ranking[record["space"]] = min(ranking.get(record["space"], key), key)
    kept = [k for k in ranking
            if not any(j != k and _within(spaces[j], spaces[k]) and ranking[j][0] <= ranking[k][0]
                       for j in ranking)]
    return sorted(kept, key=ranking.get)[:MAX_SPACES]


def _cv_results(records, spaces, n_folds, damping, domain):
    """``cv_results_`` from the candidates' records."""
    params = [
        _pipeline_params(r["denoise"], r["fit_on"], spaces[r["space"]], r["degree"],
                         r["threshold"], damping, domain)
        for r in records
    ]
    results = {"params": params}
    for name in sorted({key for p in params for key in p}):
        column = np.ma.MaskedArray(np.empty(len(params), dtype=object), mask=True)
        for i, p in enumerate(params):
            if name in p:
                column[i] = p[name]
        results[f"param_{name}"] = column
    scores = np.array([r["scores"] for r in records])
    errors = np.array([r["errors"] for r in records])
    for k in range(n_folds):
        results[f"split{k}_test_score"] = scores[:, k]
    finite = np.isfinite(scores).all(axis=1)
    mean = np.where(finite, scores.mean(axis=1), np.nan)
    results["mean_test_score"] = mean
    results["std_test_score"] = np.where(finite, scores.std(axis=1), np.nan)
    order = np.argsort(-np.where(finite, mean, -np.inf), kind="stable")
    rank = np.empty(len(records), dtype=np.int32)
    rank[order] = np.arange(1, len(records) + 1)
    results["rank_test_score"] = rank
    for k in range(n_folds):
        results[f"split{k}_equation_error"] = errors[:, k]
    results["mean_equation_error"] = errors.mean(axis=1)
    results["std_equation_error"] = errors.std(axis=1)
    results["mean_fit_time"] = np.array([r["fit_time"] for r in records])
    results["mean_score_time"] = np.array([r["score_time"] for r in records])
    results["n_terms"] = np.array([r["n_terms"] for r in records])
    results["stage"] = np.array([r["stage"] for r in records])
    results["tied"] = np.array([r["tied"] for r in records])
    return results
