"""Stage 3 of the search: the choice among the finalists.

The finalists (one per derivative layout and fit target) are compared by
their rollout scores against the held-out observations
(:func:`~._selection.pick_among`). Among those the data cannot tell from the
best score, several may keep different terms; each distinct set, with
rivals from outside the tie (:func:`rival_finalists`), is then fitted to the
raw trajectories and weighed by an information criterion (:func:`~._judgement.judge_supports`). The
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

    Where the trajectories chose among the tied finalists (and their rivals)
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
        terms dropped) and ``untied`` (the terms of an untied finalist the
        trajectories preferred to the tied ones, :func:`rival_finalists`, or
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
            untied = None if judgement is None else judgement.get("untied")
            judgement = {**cosine, "pruned": pruned, "untied": untied}
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
        finalists, with :func:`rival_finalists`, keep different terms.
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
    rivals = rival_finalists(records, finalists, choice, tied)
    for j in rivals:
        representatives.setdefault(support_key(records[finalists[j]]["fitted"]), j)
    if len(representatives) < 2:
        return choice, tied, None, []
    candidates = sorted(representatives.items(), key=lambda item: len(item[0]))[:MAX_JUDGED]
    models = [records[finalists[j]]["fitted"] for _, j in candidates]
    judgement = judge_supports(models, trajectories, dt, noise)
    if judgement["best"] is not None:
        choice = candidates[judgement["best"]][1]
    # "untied": the terms of an untied finalist the trajectories preferred.
    judgement.update(terms=[sorted(key) for key, _ in candidates], kind="tied finalists",
                     untied=sorted(support_key(models[judgement["best"]]))
                     if choice in rivals else None)
    return choice, tied, judgement, models


def rival_finalists(records, finalists, choice, tied):
    """Untied finalists judged with the tied ones: a richer set, and other spaces' best.

    The rollout scores cover a fraction of a second of held-out data, and
    their tie is one paired standard error: a fold split's luck can leave
    out of it a finalist that differs where the trajectories would tell.

    * The *richer* finalist, the untied one with the fewest terms that keeps
      every term of the choice and at most ``MAX_PRUNED`` more: a term whose
      effect builds up over a whole orbit (``q**4`` of a pendulum at small
      angles, on one record) can leave it behind a choice without it; then
      :func:`~._offers.prune_terms` drops what it need not keep.
    * For each model space no tied finalist is in, its best-scoring
      finalist: on one record of a softening spring, ``p^2, cos 2q``
      (periodic) was alone in the tie under one fold split, with the
      spring's exact polynomial law one standard error behind.

    Returns
    -------
    rivals : list of int
        Indices into ``finalists`` (finalists with a failed fold left out).
    """
    scored = [j for j, flag in enumerate(tied)
              if not flag and np.all(np.isfinite(records[finalists[j]]["scores"]))]
    kept = support_key(records[finalists[choice]]["fitted"])
    keys = {j: support_key(records[finalists[j]]["fitted"]) for j in scored}
    richer = [j for j in scored if kept < keys[j] and len(keys[j]) - len(kept) <= MAX_PRUNED]
    rivals = [min(richer, key=lambda j: len(keys[j]))] if richer else []
    tied_spaces = {records[finalists[j]]["space"] for j in np.flatnonzero(tied)}
    best = {}
    for j in scored:
        space, score = records[finalists[j]]["space"], np.mean(records[finalists[j]]["scores"])
        if space not in tied_spaces and (space not in best or score > best[space][0]):
            best[space] = (score, j)
    return rivals + [j for _, j in best.values() if j not in rivals]
