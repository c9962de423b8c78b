"""A fitted regressor's kept coefficients fitted to raw trajectories, accepted only where held-out data agree.

:func:`refine` is the one implementation of the trajectory fit (output error)
behind :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV`'s last
stage. It runs the solver (:mod:`.solver`) on the kept readable terms
(:mod:`.terms`), over segments of the records no longer than a period of
the model (:mod:`.segments`), and, given a way to refit the least-squares
model on part of the data, checks the result first on data it was not
fitted on:

1. for each held-out set of trajectories, the least-squares model is
   refitted on the others, its terms fitted to their trajectories, and
   both are scored on the held-out trajectories: each held-out segment's
   initial state fitted with the coefficients fixed, its misfit weighed by
   the noise model of the training fit;
2. the trajectory fit is accepted unless its held-out misfit, summed over
   the held-out trajectories, exceeds the least-squares model's by more than
   :data:`CHECK_TOLERANCE` of it; otherwise the least-squares coefficients
   are kept, with the reason;
3. accepted, the kept terms are fitted to all the trajectories, starting
   from the least-squares coefficients; a fit that does not converge is not
   used either.

The training fits of both steps leave out the samples that stand alone far
off their fitted trajectories (:mod:`.outliers`); the result names those of
the last (``outliers``).
"""

import numpy as np

from .noise import difference_noise_model
from .segments import (
    SEGMENT_PERIODS,
    group_by_times,
    growth_rates,
    shooting_segments,
    split_times,
)
from .covariance import parameter_covariance
from .solver import TrajectoryFitError, fit_initial_states, fit_trajectories
from .terms import KeptTerms

# Scores are clustered by trajectory (the segments of one record share it)
# when there are at least this many, else by segment.
MIN_CLUSTERS = 10
# The trajectory fit is rejected when its held-out misfit exceeds the
# least-squares fit's by more than this fraction: a fit that fails does so by
# tens of percent or orders of magnitude, and one that ties should not lose to
# the noise of the comparison.
CHECK_TOLERANCE = 0.005


def segment_duration(regressor):
    """The longest segment the fit simulates for ``regressor``: a period of its model."""
    scale = getattr(regressor, "time_scale_", np.nan)
    return SEGMENT_PERIODS * 2 * np.pi * scale if np.isfinite(scale) else np.inf


def segmented(regressor, times, states, indices=None):
    """The trajectories ``indices`` cut for ``regressor`` (:func:`~.segments.shooting_segments`), grouped.

    Returns the groups of :func:`~.segments.group_by_times`, each group's
    owners (positions in ``indices``) and where each of its segments starts
    in its trajectory (a sample index).
    """
    indices = np.arange(len(times)) if indices is None else indices
    times, states = [times[k] for k in indices], [states[k] for k in indices]
    rates = growth_rates(regressor._jacobian, states)
    seg_times, seg_states, owner = shooting_segments(times, states, segment_duration(regressor),
                                                     rates)
    # Segments come in their trajectory's order, contiguous.
    lengths = np.array([len(t) for t in seg_times], dtype=np.intp)
    ends = np.cumsum(lengths)
    first = np.searchsorted(owner, owner)  # owner is sorted: each trajectory's first segment
    starts = ends - lengths - (ends - lengths)[first]
    groups, members = group_by_times(seg_times, seg_states, regressor._default_step("rk4"))
    return groups, [owner[m] for m in members], [starts[m] for m in members]


def _samples_left_out(outliers, owners, starts):
    """The samples the fit left out: trajectory (position) to sorted sample indices."""
    left = {}
    for far, owner, start in zip(outliers, owners, starts):
        for row, j in zip(*np.nonzero(far)):
            left.setdefault(int(owner[row]), []).append(int(start[row] + j))
    return {k: sorted(v) for k, v in sorted(left.items())}


def _per_trajectory(values, owners, n):
    """Sums of per-segment values over the segments of each trajectory."""
    total = np.zeros(n)
    for v, o in zip(values, owners):
        np.add.at(total, o, v)
    return total


def refine(regressor, trajectories, dt, *, least_squares=None, held_out=None):
    """Fit the kept coefficients of a fitted ``HamiltonianRegressor`` to raw trajectories.

    Parameters
    ----------
    regressor : HamiltonianRegressor
        Fitted by least squares; ``coef_``, ``support_`` and ``damping_`` are
        updated in place when the fit is accepted, and the fit's outcome set
        as its attributes ``trajectory_fit_status_`` and, when accepted,
        ``noise_``, ``trajectory_misfit_`` and ``coef_covariance_``.
    trajectories : list of ndarray of shape (n_times_k, n_columns)
        The raw trajectories the regressor was fitted on, with their time
        stamps in the first column when ``dt`` is None.
    dt : float or None
        Sampling step.
    least_squares : callable, default=None
        ``least_squares(indices)``: the regressor's least-squares fit on the
        trajectories ``indices`` alone (a new fitted regressor). None: no
        held-out check.
    held_out : list of ndarray of int, default=None
        The held-out sets of the check; each trajectory should be in one.

    Returns
    -------
    info : dict
        ``status``: ``"refined"``, or ``"kept: "`` and why the least-squares
        coefficients were kept. ``check``, when checked: ``misfit``, the
        held-out misfits (least squares, trajectory fit) summed over the
        held-out trajectories, ``n_trajectories``, ``gain`` (the first
        misfit less the second) and ``gain_se`` (its standard error from the
        spread of that difference over the held-out trajectories; NaN with
        one). When refined:
        ``n_terms``; ``n_iter`` (Levenberg-Marquardt iterations);
        ``converged``; ``noise`` (the variance model ``(a_i, b_i)`` of each
        variable, ``a_i + b_i x_i^2``) and ``noise_source`` (``"residuals"``:
        fitted to the residuals; ``"data"``: estimated from the data alone,
        where the residuals' own could not be trusted); ``rms`` (the
        root-mean-square residual per variable); ``misfit`` (each
        trajectory's root-mean-square residual in units of the noise model,
        about 1 where the model explains it); ``n_segments``; ``change``
        (the largest relative change of a kept coefficient); ``covariance``,
        that of ``coef_`` (then of ``damping_`` for a damped model), the
        :func:`~.covariance.parameter_covariance` with the scores clustered
        by trajectory (by segment with fewer than :data:`MIN_CLUSTERS`
        trajectories): the sandwich, each variance at least the
        model-based one; ``outliers``, the samples the fit left out
        (:mod:`.outliers`), each trajectory's index in ``trajectories`` to
        its sample indices (empty for none).
    """
    info = _refine(regressor, trajectories, dt, least_squares, held_out)
    _set_outcome(regressor, info)
    return info


def _set_outcome(regressor, info):
    """The fitted attributes of a trajectory fit: its status, and when refined its estimates."""
    for name in ("noise_", "trajectory_misfit_", "coef_covariance_"):
        regressor.__dict__.pop(name, None)
    regressor.trajectory_fit_status_ = info["status"]
    if info["status"] == "refined":
        regressor.noise_ = np.asarray(info["noise"], dtype=float)
        regressor.trajectory_misfit_ = np.asarray(info["misfit"], dtype=float)
        regressor.coef_covariance_ = np.asarray(info["covariance"], dtype=float)


def _refine(regressor, trajectories, dt, least_squares, held_out):
    terms = KeptTerms(regressor)
    if terms.reason is not None:
        return dict(status=f"kept: {terms.reason}")
    times, states = split_times(trajectories, dt)
    bound = difference_noise_model(states)
    if bound is None:
        return dict(status="kept: no trajectory has the 3 samples a noise estimate needs")
    check = None
    if least_squares is not None and held_out:
        check = _held_out_check(least_squares, held_out, times, states, bound)
        if check["verdict"] is not None:
            return dict(status=f"kept: {check.pop('verdict')}", check=check)
        check.pop("verdict")
    try:
        groups, owners, starts = segmented(regressor, times, states)
        with np.errstate(all="ignore"):
            result = fit_trajectories(terms.model, terms.start, groups, bound=bound,
                                      first_noise=bound, leave_out_outliers=True)
    except TrajectoryFitError as error:
        return dict(status=f"kept: {error}", check=check)
    if not np.all(np.isfinite(result["theta"])):
        return dict(status="kept: the refined coefficients are not finite", check=check)
    if not result["converged"]:
        return dict(status=f"kept: the trajectory fit did not converge in {result['n_iter']} "
                           f"iterations", check=check)
    change = terms.apply(regressor, result["theta"])
    n_obs = _per_trajectory([(mask.sum(axis=1) - far.sum(axis=1)) * Y.shape[2]
                             for (Y, _, mask), far in zip(groups, result["outliers"])], owners,
                            len(times))
    misfit = np.sqrt(_per_trajectory(result["misfit"], owners, len(times)) / n_obs)
    segment_owner = np.concatenate(owners)
    clusters = (segment_owner if np.unique(segment_owner).size >= MIN_CLUSTERS
                else np.arange(segment_owner.size))
    covariance = parameter_covariance(result["information"], np.concatenate(result["scores"]),
                                     clusters)
    info = dict(status="refined", n_terms=terms.n_terms, n_iter=result["n_iter"],
                converged=result["converged"], noise=result["noise"],
                noise_source=result["noise_source"], rms=result["rms"], misfit=misfit,
                n_segments=sum(len(Y) for Y, _, _ in groups), change=change,
                covariance=terms.fitting_covariance(covariance, len(regressor.coef_)),
                outliers=_samples_left_out(result["outliers"], owners, starts))
    if check is not None:
        info["check"] = check
    return info


def _held_out_check(least_squares, held_out, times, states, bound):
    """Held-out misfits of the least-squares fit and of its trajectory fit, and the verdict.

    ``verdict`` is None when the trajectory fit passes, else why it does not.
    """
    n = len(times)
    chunks = []
    for test in held_out:
        test = np.asarray(test, dtype=np.intp)
        if test.size == 0 or test.size == n:
            continue
        train = np.setdiff1d(np.arange(n), test)
        fitted = least_squares(train)
        terms = KeptTerms(fitted)
        if terms.reason is not None:
            continue  # nothing to refine on this part: both fits are the same
        try:
            groups, _, _ = segmented(fitted, times, states, train)
            with np.errstate(all="ignore"):
                # One fit weighted by the data's own noise model: the check
                # asks whether fitting these terms to trajectories generalises,
                # not for the last digits of the estimate.
                result = fit_trajectories(terms.model, terms.start, groups, bound=bound,
                                          n_reweights=0, first_noise=bound,
                                          leave_out_outliers=True)
        except TrajectoryFitError as error:
            return dict(verdict=f"on part of the data, {error}", misfit=None, n_trajectories=0)
        if not np.all(np.isfinite(result["theta"])):
            return dict(verdict="the trajectory fit's coefficients are not finite",
                        misfit=None, n_trajectories=0)
        noise = bound
        try:
            groups, owners, _ = segmented(fitted, times, states, test)
        except TrajectoryFitError as error:
            return dict(verdict=str(error), misfit=None, n_trajectories=0)
        with np.errstate(all="ignore"):
            pair = fit_initial_states(terms.model, [terms.start, result["theta"]], groups, noise)
        chunks.append(np.column_stack([_per_trajectory(m, owners, test.size) for m in pair]))
    if not chunks:
        return dict(verdict=None, misfit=None, n_trajectories=0)
    misfit = np.concatenate(chunks)
    totals = misfit.sum(axis=0)
    verdict = None
    if not np.all(np.isfinite(misfit[:, 1])):
        verdict = "the trajectory fit's simulation of held-out trajectories fails"
    elif np.all(np.isfinite(misfit[:, 0])) and totals[1] > (1 + CHECK_TOLERANCE) * totals[0]:
        verdict = (f"the trajectory fit explains held-out trajectories worse than the "
                   f"least-squares fit (weighted misfit {totals[1]:.4g} against "
                   f"{totals[0]:.4g})")
    gain = misfit[:, 0] - misfit[:, 1]
    with np.errstate(invalid="ignore"):
        gain_se = float(np.sqrt(len(gain)) * np.std(gain, ddof=1)) if len(gain) > 1 else np.nan
    return dict(verdict=verdict, misfit=tuple(float(v) for v in totals),
                n_trajectories=len(misfit), gain=float(gain.sum()), gain_se=gain_se)
