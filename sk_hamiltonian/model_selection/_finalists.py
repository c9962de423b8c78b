"""Stage 3 of the search: the choice among the finalists.

The finalists (one per derivative layout and fit target) are compared by
their rollout scores against the held-out observations
(:func:`~._selection.pick_among`). Among those the data cannot tell from the
best score, several may keep different terms; each distinct set, with the
smallest untied finalist that keeps the choice's terms and more
(:func:`richer_finalist`), is then fitted to the raw trajectories and weighed
by an information criterion (:func:`~._judgement.judge_supports`). The
choice is last weighed against laws built from it (:mod:`._offers`): its
terms pruned, and ``cos q`` in place of a Taylor series.
"""

import numpy as np

from ._judgement import judge_supports, support_key
from ._offers import MAX_PRUNED, offer_cosine_law, prune_terms
from ._selection import pick_among

# At most this many distinct sets of terms are judged by their trajectory fits
# (the fewest terms first): each costs one fit on all the data.
MAX_JUDGED = 4


def smoothing(denoise):
    """Order of layouts from the smoothest: the de-noising degree, finite differences last."""
    return np.inf if denoise == "finite_difference" else float(denoise)


def decide(records, finalists, selection, spaces, layouts, folds, trajectories, dt, noise,
           **search):
    """Stage 3: :func:`choose`, then with ``"simplest"`` the laws of :mod:`._offers`.

    Where the trajectories chose among the tied finalists (and a richer one)
    a set of terms larger than another, :func:`~._offers.prune_terms` drops
    what they need not keep; then :func:`~._offers.offer_cosine_law`. Marks
    each finalist's record ``tied`` (the offered laws never are).

    Returns
    -------
    choice : int
        Index into ``finalists`` (extended by the pruned and offered laws).
    judgement : dict or None
        The last verdict among sets of terms, its ``kind`` ``"tied
        finalists"`` or ``"cosine law"``, with ``pruned`` (the names of the
        terms dropped) and ``richer`` (the terms of an untied finalist the
        trajectories preferred to the tied ones, :func:`richer_finalist`, or
        None); None when there was none.

    Raises
    ------
    ValueError
        When every finalist's score failed in some fold.
    """
    choice, tied, judgement, judged = choose(records, finalists, selection, trajectories, dt,
                                             noise)
    if choice is None:
        raise ValueError(
            "Every finalist's score failed in some fold: no candidate can be "
            "chosen. Inspect cv_results_ or give more data; error_score='raise' shows "
            "the first failure."
        )
    for i, flag in zip(finalists, tied):
        records[i]["tied"] = bool(flag)
    if selection == "simplest" and noise is not None:
        pruned = []
        if judgement is not None and judgement["best"] is not None:
            choice, pruned = prune_terms(records, finalists, choice, judged, spaces, layouts,
                                         folds, trajectories, dt, noise, **search)
            judgement["pruned"] = pruned
        choice, cosine = offer_cosine_law(records, finalists, choice, spaces, layouts, folds,
                                          trajectories, dt, noise, **search)
        if cosine is not None:
            richer = None if judgement is None else judgement.get("richer")
            judgement = {**cosine, "pruned": pruned, "richer": richer}
    return choice, judgement


def choose(records, finalists, selection, trajectories, dt, noise):
    """The chosen finalist: the rollout scores' choice, then the trajectories' verdict.

    Parameters
    ----------
    records : list of dict
        Every candidate's record; the finalists' hold ``scores`` and ``fitted``.
    finalists : list of int
        Rows of the finalists in ``records``.
    selection : {"simplest", "best_score"}
    trajectories : list of ndarray
        The raw trajectories (time stamps first when ``dt`` is None).
    dt : float or None
    noise : ndarray of shape (n_states, 2) or None
        The data's own noise model (:func:`~sk_hamiltonian._trajectory_fit.difference_noise_model`).

    Returns
    -------
    choice : int or None
        Index into ``finalists``.
    tied : ndarray of bool
        The finalists the rollout scores cannot tell from the best.
    judgement : dict or None
        :func:`~._judgement.judge_supports`' verdict, when the tied
        finalists, with :func:`richer_finalist`, keep different terms.
    judged : list of HamiltonianRegressor
        The sets of terms weighed (empty without a verdict).
    """
    scores = np.array([records[i]["scores"] for i in finalists])
    choice, tied = pick_among(
        scores, [records[i]["n_terms"] for i in finalists],
        [smoothing(records[i]["denoise"]) for i in finalists],
        [records[i]["fit_on"] for i in finalists], selection,
    )
    if choice is None or selection != "simplest" or noise is None:
        return choice, tied, None, []
    # The tied finalists in the rule's order of preference, the choice first.
    order = [choice] + [j for j in np.flatnonzero(tied) if j != choice]
    representatives = {}
    for j in order:
        key = support_key(records[finalists[j]]["fitted"])
        representatives.setdefault(key, j)
    richer = richer_finalist(records, finalists, choice, tied)
    if richer is not None:
        representatives.setdefault(support_key(records[finalists[richer]]["fitted"]), richer)
    if len(representatives) < 2:
        return choice, tied, None, []
    candidates = sorted(representatives.items(), key=lambda item: len(item[0]))[:MAX_JUDGED]
    models = [records[finalists[j]]["fitted"] for _, j in candidates]
    judgement = judge_supports(models, trajectories, dt, noise)
    if judgement["best"] is not None:
        choice = candidates[judgement["best"]][1]
    # "richer": the terms of an untied finalist the trajectories preferred.
    chose_richer = richer is not None and choice == richer
    judgement.update(terms=[sorted(key) for key, _ in candidates], kind="tied finalists",
                     richer=sorted(support_key(models[judgement["best"]])) if chose_richer
                     else None)
    return choice, tied, judgement, models


def richer_finalist(records, finalists, choice, tied):
    """The untied finalist with the fewest terms that keeps every term of the choice and more.

    The rollout scores cover a fraction of a second of held-out data; a term
    whose effect builds up over a whole orbit (``q**4`` of a pendulum at small
    angles, on one record) can leave its finalist untied behind a choice
    without it, by a fold split's luck. Such a finalist is judged with the
    tied ones, so that the trajectories decide whether the choice lacks
    something; :func:`~._offers.prune_terms` then drops what it need not
    keep. At most ``MAX_PRUNED`` terms more than the choice; None when there
    is none.
    """
    kept = support_key(records[finalists[choice]]["fitted"])
    found = None
    for j, flag in enumerate(tied):
        record = records[finalists[j]]
        if flag or not np.all(np.isfinite(record["scores"])):
            continue
        key = support_key(record["fitted"])
        if key > kept and len(key) - len(kept) <= MAX_PRUNED and (
                found is None or len(key) < found[0]):
            found = (len(key), j)
    return None if found is None else found[1]
