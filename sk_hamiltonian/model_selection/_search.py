"""HamiltonianSearchCV: model spaces, fit targets, de-noising, degree and sparsity, cross-validated.

The stages' modules, on one set of folds: :mod:`._prepare` (spikes,
duplicates, long records, the folds; :mod:`._units`), :mod:`._screen` (the spaces),
:mod:`._degrees` (one finalist per layout and fit target), :mod:`._finalists`
(the choice, with :mod:`._judgement` and :mod:`._offers`), :mod:`._refine`
(the trajectory fit), :mod:`._energy_levels`; :mod:`._search_checks`.
"""

import time
from numbers import Integral, Real

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.metrics import get_scorer_names
from sklearn.pipeline import Pipeline
from sklearn.utils._param_validation import Interval, StrOptions
from sklearn.utils.validation import check_is_fitted

from .._derivatives import DerivativeTransformer
from .._hamiltonian import HamiltonianRegressor
from .._inspection.terms import check_state_names
from .._state_order import ORDER_WORDS, STATE_ORDERS, swap_raw, swap_search_inputs, swap_space
from .._trajectories import check_trajectories
from ._degrees import failure_reason, score_fold, search_finalists
from ._energy_levels import warn_one_level
from ._finalists import decide
from ._prepare import prepare
from ._refine import refine_chosen
from ._results import cv_results, describe_layout
from ._screen import (
    PER_COORDINATE_DOF,
    angle_like,
    auto_spaces,
    derivative_layouts,
    screen,
    screen_layout,
    screen_target,
)
from ._search_checks import (
    CLEAN_FIT_TARGETS,
    FIT_TARGETS,
    check_denoise,
    check_fit_on,
    check_scorer,
    check_spaces,
    check_values,
)
from ._selection import SELECTIONS
from ._units import refit_in_user_units, scaled_domain


class HamiltonianSearchCV(BaseEstimator):
    """Cross-validated search over model spaces, fit targets, de-noising, degree and sparsity.

    What a :class:`~sklearn.model_selection.GridSearchCV` over a pipeline
    ``make_pipeline(DerivativeTransformer(dt), HamiltonianRegressor())`` would
    search, in one object that shares the work among candidates: for each
    derivative layout (de-noising degree, or finite differences), fit target
    and model space, the normal equations of every fold come from one pass
    over the data, and every degree and threshold is a smaller solve on them.

    The search prepares the data, then runs three stages on the same folds
    and a fourth on all the data:

    0. **Prepare** the data (``preparation_``): samples far from their
       neighbours (spikes) and missing ones (NaN) are left out and their
       trajectories cut there, repeated trajectories left out, both named in an
       :class:`~sk_hamiltonian.OutlierWarning` and in ``preparation_``; with
       fewer than two trajectories per fold, the records are cut into
       contiguous segments and each fold holds out a contiguous stretch of them
       (blocked cross-validation); exact data (noise below 0.001 % of every
       variable) are searched with finite differences and the fit targets exact
       to ``O(dt**4)`` only (Simpson's pairs, the weak form); momenta spread
       over ten times more or less than the positions are rescaled to them by a
       power of ten for stages 1 to 3, so both rows weigh alike (``momentum_scale``).
    1. **Screen** the model spaces (``spaces``) on one reference layout (the
       middle de-noising degree of those whose polynomials follow the data,
       residuals within 20 times the noise (beyond two degrees of freedom, no
       :class:`~sk_hamiltonian.SmoothingWarning`), else finite differences) and
       the derivative fit (Simpson's pairs for exact data), at the smallest
       degree: each candidate's held-out *equation error* (the relative
       residual of the held-out trajectories' least-squares rows) ranks spaces,
       degrees and thresholds against the same targets. The spaces the data
       cannot reject against the best are kept, the smallest models first (at
       most three): a candidate is rejected only when it is worse by one
       standard error, unpaired and paired over the folds, and by 10 % (twice
       the part of an equation error a richer model can take from the bias of
       the estimated derivatives), than the best of all and than the best at
       its own threshold (where that one is not rejected).
    2. **Search** every layout and fit target in the kept spaces (the layouts
       passed over by the screen are left out, unless all are), degree by
       degree from the smallest (a degree no
       better than the best below it ends the space's search), at every
       threshold; within each layout and fit target, the candidate with the
       fewest terms among those the data cannot reject against the lowest
       equation error is that pair's *finalist*.
    3. **Choose** among the finalists by the regressors' default rollout score
       against the held-out raw observations (blind to the derivatives and
       smoothed states compared), or by ``scoring``, by ``selection``. When the
       finalists the scores cannot tell apart (and the smallest finalist with
       the choice's terms and more) keep different terms, each set is fitted to
       all the raw trajectories (output error, one noise model at the same
       states for all) and the lowest Bayesian information criterion decides
       (``judgement_``): the exact law against its Taylor series, on no fold. A
       larger set chosen so is pruned term by term while the criterion improves
       (stage ``"pruned"``); up to two degrees of freedom, a choice that keeps a
       softening series of a polynomial position alone (``-cos q``'s), or
       several cosines of an angle, is weighed so against its terms with ``cos q``
       in their place (with and without ``q**2``; stage ``"cosine"``, taken at one
       standard error, then pruned); last, against each other space's best finalist.
    4. **Refine** (``refine="trajectories"``) the chosen model, refitted on
       all the data: the coefficients of its kept terms are fitted to the raw
       trajectories, each simulated from an initial state of its own (long
       records in segments of at most two periods of the model, shorter where
       it is unstable), weighted by a noise model ``a_i + b_i x_i^2`` per
       variable (output error); a sample alone far off the fitted trajectory
       is left out and named in an ``OutlierWarning``. The result is checked
       first on every other fold from the second: the least-squares pick and
       its trajectory fit, both fitted on the other folds, are compared on
       the held-out trajectories; the refinement is kept only where it
       explains them as well (within 0.5 %) and its fit on all the data
       converges, else the least-squares coefficients stay and
       ``refinement_`` says why.

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
        ``couplings``, ``solver``). ``"auto"`` (:func:`auto_spaces`): up to
        two degrees of freedom, each position coordinate polynomial, periodic
        or mixed, each as a general and as a mechanical Hamiltonian
        (``momentum_degree=2``); beyond, pairwise couplings
        (``max_interaction=2``) in a general, a mechanical and a separable
        mechanical Hamiltonian, with the positions whose observed span is
        nearly a full turn or more (:func:`angle_like`) also offered as
        periodic and as mixed.
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
        40 terms (10 per state variable beyond four), or whose simulation of
        the training trajectories fails.
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
        :class:`~sklearn.model_selection.GridSearchCV`; with too few
        trajectories for them (fewer than two per fold), the number of folds
        of contiguous segments of the records (stage 0).
    n_jobs : int, default=None
        Layouts, fit targets and spaces assembled in parallel (joblib).
    verbose : int, default=0
        Print the stages' progress when positive.
    state_names : list of str, default=None
        Names of the ``2d`` state variables, in the order of the columns
        (momenta first unless ``state_order="qp"``), given to the chosen
        model (:class:`~sk_hamiltonian.HamiltonianRegressor`'s
        ``state_names``) for its formulas, reports and model file. None:
        ``p, q`` or ``p1.., q1..``.
    state_order : {"pq", "qp"}, default="pq"
        The order of the state columns of ``X`` (after the time stamps):
        ``"pq"`` is ``(p_1..p_d, q_1..q_d)``, ``"qp"`` is ``(q_1..q_d,
        p_1..p_d)``. The search runs in ``(p, q)`` order; ``domain``,
        ``spaces``, ``spaces_``, ``kept_spaces_``, ``cv_results_`` and
        ``best_params_`` are in the columns' order, and the chosen model is
        given the same ``state_order`` (:class:`~sk_hamiltonian.HamiltonianRegressor`),
        so that :meth:`predict` and :meth:`simulate` read and answer in it.
        The per-variable entries of ``preparation_`` and ``refinement_``
        (noise models, residuals) are in ``(p, q)`` order.
    scoring : str, callable or None, default=None
        How stage 3 scores each finalist on the held-out folds (and what
        :meth:`score` returns). None: the regressor's rollout score against
        the held-out raw observations. A scorer name of
        ``sklearn.metrics.get_scorer_names()`` or a callable
        ``scorer(estimator, X, y)``: called with the finalist's regressor
        fitted on the other folds, the held-out trajectories' states ``X``
        and their estimated time derivatives ``y`` (both of shape
        ``(n_samples, n_states)``, from the finalist's own derivative
        layout), as :class:`~sklearn.model_selection.GridSearchCV` scores a
        regressor fitted on states and derivatives; e.g. ``"r2"`` scores the
        learned vector field against the held-out derivative estimates (which
        differ from layout to layout: the default compares all with the same
        raw observations). Stages 1 and 2 rank by equation error whatever it is.
    refit : bool, default=True
        Refit the chosen candidate on all the data (``best_estimator_``) and
        refine it (stage 4). False: the search stops after the choice
        (``best_params_``, ``best_index_``, ``best_score_``,
        ``cv_results_``); :meth:`predict`, :meth:`score`, :meth:`simulate`
        and :meth:`hamiltonian` then raise an ``AttributeError``.
    error_score : "raise" or float, default=np.nan
        The score of a finalist in a fold where scoring it raises (e.g. a
        rollout that cannot be simulated). ``"raise"``: the error is raised.
        A finalist with a NaN score in some fold is not chosen.

    Attributes
    ----------
    best_estimator_ : Pipeline
        ``make_pipeline(DerivativeTransformer(dt=dt), HamiltonianRegressor())``
        with ``best_params_``, fitted on all the data (with ``refit=True``); with
        rescaled momenta, their fit's terms as ``terms``, and no threshold.
    best_params_ : dict
        The chosen candidate's parameters, in the pipeline's names.
    best_index_ : int
        Its row in ``cv_results_``.
    best_score_ : float
        Its mean score over the folds (rollout, or ``scoring``'s).
    cv_results_ : dict of ndarray
        One row per candidate, laid out as
        ``cv_results_`` of :class:`~sklearn.model_selection.GridSearchCV`
        (``params``, ``param_<name>``, ``split<k>_test_score``,
        ``mean_test_score``, ``std_test_score``, ``rank_test_score``), with
        the scores of the finalists (rollout, or ``scoring``'s; NaN for the
        other candidates),
        and ``split<k>_equation_error``, ``mean_equation_error``,
        ``std_equation_error``, ``n_terms`` (on all the data), ``stage``
        (``"screen"``, ``"search"``, ``"finalist"``, or ``"pruned"`` and
        ``"cosine"`` for the laws stage 3 builds) and ``tied`` (the
        finalists the data cannot tell from the best score).
    spaces_ : list of dict
        The model spaces screened (not those of the laws stage 3 builds,
        whose parameters are in ``cv_results_``).
    kept_spaces_ : list of dict
        The model spaces searched after the screen.
    n_splits_ : int
        Number of folds.
    refinement_ : dict
        Stage 4's outcome: ``status`` (``"refined"``, ``"not asked"``, or
        ``"kept: "`` and why the least-squares coefficients were kept);
        ``check``, the held-out check's misfits (least squares, trajectory
        fit), their difference ``gain`` and its standard error ``gain_se``;
        when refined ``n_terms``, ``n_iter`` (Levenberg-Marquardt
        iterations), ``converged``, ``noise`` (the variance model's ``(a_i,
        b_i)`` per variable), ``noise_source`` (``"residuals"``, or ``"data"``
        where the residuals' own could not be trusted), ``rms`` (the RMS
        residual per variable), ``misfit`` (each trajectory's RMS residual in
        units of the noise model), ``n_segments``, ``change`` (the largest
        relative change of a kept coefficient) and ``outliers`` (the samples
        the fit left out, numbered as in ``X``; empty for none).
    preparation_ : dict
        Stage 0's outcome: ``left_out`` (each trajectory's samples left out,
        numbered as in ``X``), ``missing`` (those that were NaN or infinite),
        ``dropped`` (trajectories left out whole), ``duplicates`` (each repeat
        and what it repeats), ``segments`` (None, or how records were cut),
        ``noise`` (the data's own noise model, ``(a_i, b_i)`` per variable),
        ``clean`` (whether the data look exact), ``momentum_scale`` (the factor
        stages 1 to 3 multiplied the momenta by; 1.0 for none) and, after the refit,
        ``one_level`` (None, or ``span``, ``energy`` and ``message`` where
        every trajectory lies on one level of the chosen law's energy and so
        determines it only there: :class:`~sk_hamiltonian.IllConditionedWarning`).
    judgement_ : dict or None
        Stage 3's verdict among sets of terms that decided: ``kind`` (``"tied
        finalists"``, ``"other spaces"``, or ``"cosine law"``: the choice against its
        terms with ``cos q`` in place of a Taylor series or of an angle's harmonics,
        with ``gain`` and ``gain_se``), ``terms`` of each, their ``rss`` (weighted
        residual sums of squares; per segment ``segment_rss``), ``n_terms``, ``bic``,
        ``best``, ``pruned`` (the terms dropped from the choice) and ``untied`` (the
        terms of an untied finalist the trajectories preferred, else None). None when
        no two sets were weighed.
    refit_time_ : float
        Seconds of the final fit on all the data, refinement included (0 with
        ``refit=False``).
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
        "state_names": ["array-like", None],
        "state_order": [StrOptions(set(STATE_ORDERS))],
        "scoring": [StrOptions(set(get_scorer_names())), callable, None],
        "refit": ["boolean"],
        "error_score": [StrOptions({"raise"}), Real],
    }

    def __init__(
        self, dt=None, *, denoise_degrees=("finite_difference", 3, 5, 8), degrees=(4, 6, 8, 10),
        spaces="auto", fit_on=FIT_TARGETS, thresholds=(0.0, 0.001, 0.01, 0.03, 0.1),
        damping=False, domain=None, refine="trajectories", selection="simplest", cv=5,
        n_jobs=None, verbose=0, state_names=None, state_order="pq", scoring=None, refit=True,
        error_score=np.nan,
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
        self.state_names = state_names
        self.state_order = state_order
        self.scoring = scoring
        self.refit = refit
        self.error_score = error_score

    def fit(self, X, y=None, groups=None):
        """Search the candidates on trajectories ``X`` and refit the chosen one on all of them.

        Parameters
        ----------
        X : array-like of shape (n_trajectories, n_times, n_columns) or list of 2-D arrays
            Raw trajectories, sampled every ``dt`` (``n_columns = 2d``) or with
            time stamps in the first column (``dt=None``); NaN readings left out.
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
        trajectories, _ = check_trajectories(X, min_times=3, allow_missing=True)
        n_states = trajectories[0].shape[1] - (1 if self.dt is None else 0)
        check_state_names(self.state_names, n_states,
                          order=f"{ORDER_WORDS[self.state_order]} first")
        degrees = check_values("degrees", self.degrees, integer=True, low=1)
        thresholds = check_values("thresholds", self.thresholds, integer=False, low=0)
        fit_on = check_fit_on(self.fit_on)
        scorer = check_scorer(self.scoring)
        spaces = None if self.spaces == "auto" else check_spaces(self.spaces)
        # state_order="qp": the search runs on the states exchanged into (p, q) order,
        # the per-state parameters alike; its reports and model keep the columns' order.
        swapped = self.state_order == "qp" and n_states % 2 == 0
        domain = self.domain
        if swapped:
            trajectories, domain, spaces = swap_search_inputs(trajectories, domain, spaces,
                                                              self.dt)
        # Stage 0: the data as the folds will see them.
        prepared = prepare(trajectories, self.dt, self.cv, groups)
        X, trajectories, folds = prepared.X, prepared.trajectories, prepared.folds
        domain = scaled_domain(domain, prepared.momentum_scale)
        if spaces is None:  # which positions look like angles, once spikes are left out
            offset = 1 if self.dt is None else 0
            angles = angle_like([T[:, offset:] for T in trajectories])
            spaces = auto_spaces(n_states, angles=angles)
        if prepared.report["segments"] is not None:
            self._say(f"segments: {prepared.report['segments']['rule']}")
        denoise = check_denoise(self.denoise_degrees, min(T.shape[0] for T in trajectories))
        clean = prepared.report["clean"]
        if clean:
            # Exact data: de-noising only adds bias; O(dt**4) targets suffice.
            denoise = [v for v in denoise if v == "finite_difference"] or denoise[:1]
            fit_on = [v for v in fit_on if v in CLEAN_FIT_TARGETS] or fit_on
            self._say(f"clean data: layouts {denoise}, fit targets {fit_on}")
        # Layouts whose polynomials cannot follow the data are passed over; beyond
        # PER_COORDINATE_DOF, among nested pairwise spaces, any biased one (it keeps the larger).
        layouts, misfits = derivative_layouts(X, self.dt, denoise,
                                              strict=n_states // 2 > PER_COORDINATE_DOF)
        # Stage 1: the spaces, on the reference layout and fit target.
        reference = screen_layout(denoise, misfits)
        target = screen_target(fit_on, clean)
        self._say(f"screen: {len(spaces)} spaces on {describe_layout(reference)}, {target}, "
                  f"degree {degrees[0]}")
        records, failures, kept = screen(layouts[reference], folds, spaces, target, degrees[0],
                                         thresholds, self.damping, domain, reference,
                                         self.n_jobs)
        self._say(f"kept: {[spaces[k] for k in kept]}")
        # Stage 2: every layout and fit target in the kept spaces, a finalist each;
        # the biased layouts are left out, unless all are.
        searched = [key for key in denoise if key not in misfits] or denoise
        if len(searched) < len(denoise):
            self._say(f"biased layouts left out: "
                      f"{[describe_layout(key) for key in denoise if key in misfits]}")
        searched_records, finalists, searched_failures = search_finalists(
            {key: layouts[key] for key in searched}, fit_on, folds, spaces, kept, len(records),
            degrees=degrees, thresholds=thresholds, damping=self.damping, domain=domain,
            scorer=scorer, error_score=self.error_score, n_jobs=self.n_jobs)
        records.extend(searched_records)
        failures.extend(searched_failures)
        if not finalists:
            raise ValueError(
                "No candidate could be fitted and scored in every fold. Give more "
                "trajectories, lower degrees, or fewer folds." + failure_reason(failures)
            )
        # Stage 3: the choice among the finalists.
        n_screened = len(spaces)
        choice, judgement = decide(records, finalists, self.selection, spaces, layouts, folds,
                                   trajectories, self.dt, prepared.report["noise"],
                                   damping=self.damping, domain=domain, scorer=scorer,
                                   error_score=self.error_score)
        for record in records:
            record.pop("fitted", None)
        self.preparation_ = prepared.report
        self.judgement_ = judgement
        if swapped:  # back to the columns' order, for the report and the chosen model
            spaces = [swap_space(space, n_states) for space in spaces]
        self.spaces_ = spaces[:n_screened]
        self.kept_spaces_ = [spaces[k] for k in kept]
        self.n_splits_ = len(folds)
        self.cv_results_ = cv_results(records, spaces, len(folds), self.damping, self.domain)
        self.best_index_ = finalists[choice]
        self.best_params_ = self.cv_results_["params"][self.best_index_]
        self.best_score_ = float(self.cv_results_["mean_test_score"][self.best_index_])
        self.n_features_in_ = n_states
        self.refinement_ = dict(status="not asked")
        if not self.refit:
            self.refit_time_ = 0.0
            self.search_time_ = time.perf_counter() - start
            return self
        # Stage 4: the refit on all the data, and its coefficients on the trajectories.
        refit_start = time.perf_counter()
        # The chosen model reads the columns' order; the refinement's trajectories are (p, q).
        X_columns, balanced = (swap_raw(Z, 1 if self.dt is None else 0) if swapped else Z
                               for Z in (prepared.user_X, X))
        self.best_estimator_ = refit_in_user_units(Pipeline([
            ("derivativetransformer", DerivativeTransformer(dt=self.dt)),
            ("hamiltonianregressor", HamiltonianRegressor(state_names=self.state_names,
                                                          state_order=self.state_order)),
        ]).set_params(**self.best_params_), X_columns, balanced, prepared.momentum_scale)
        if self.refine == "trajectories":
            self.refinement_ = refine_chosen(self.best_estimator_, X_columns,
                                             prepared.user_trajectories, self.dt, folds,
                                             prepared.origin)
            self._say(f"refine: {self.refinement_['status']}")
        self.preparation_["one_level"] = warn_one_level(self.best_estimator_[-1], X_columns,
                                                        self.dt)
        self.refit_time_ = time.perf_counter() - refit_start
        self.search_time_ = time.perf_counter() - start
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
            ``best_estimator_.predict(X)``: the learned vector field at the
            trajectories' (de-noised) states, in their shape.
        """
        self._check_refitted("predict")
        return self.best_estimator_.predict(X)

    def score(self, X, y=None):
        """The score of ``best_estimator_`` on trajectories ``X``: ``scoring``'s, or the rollout score.

        Parameters
        ----------
        X : array-like
            Raw trajectories, as for :meth:`fit`.
        y : None
            Ignored.

        Returns
        -------
        score : float
            Without ``scoring``, the rollout score
            (:meth:`sk_hamiltonian.HamiltonianRegressor.score`); with it,
            ``scoring`` on the states and estimated derivatives of ``X``'s
            derivative layout, as in the search.
        """
        self._check_refitted("score")
        scorer = check_scorer(self.scoring)
        if scorer is None:
            return self.best_estimator_.score(X)
        Xt = self.best_estimator_[0].transform(X)
        return score_fold(self.best_estimator_[-1], Xt, scorer)

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
        self._check_refitted("simulate")
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
        self._check_refitted("hamiltonian")
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
    def _check_refitted(self, method):
        check_is_fitted(self)
        if not self.refit:
            raise AttributeError(
                f"This HamiltonianSearchCV was fitted with refit=False: {method} needs the "
                f"chosen model refitted on all the data. Fit again with refit=True, or fit "
                f"make_pipeline(DerivativeTransformer(dt), HamiltonianRegressor()) with "
                f"best_params_ yourself."
            )

    def _say(self, message):
        if self.verbose:
            print(f"[HamiltonianSearchCV] {message}", flush=True)
