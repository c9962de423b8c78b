"""Stage 3 of the search: the choice among the finalists.

The finalists (one per derivative layout and fit target) are compared by
their rollout scores against the held-out observations
(:func:`~._selection.pick_among`). Among those the data cannot tell from the
best score, several may keep different terms; each distinct set, with the
smallest richer finalist outside the tie (:func:`richer_finalist`), is then
fitted to the raw trajectories and weighed by an information criterion
(:func:`~._judgement.judge_supports`). The choice is then weighed against laws
built from it (:mod:`._offers`): its terms pruned, and ``cos q`` in place of a
Taylor series; last, against the best finalist of each other model space
(:func:`other_spaces`).
"""

import numpy as np

from ._judgement import judge_supports, support_key
from ._offers import (
    MAX_PRUNED,
    disputed_terms,
    inherited_terms,
    offer_cosine_law,
    prune_terms,
)
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

    Where the trajectories chose among the tied finalists (and the richer
    one) a set of terms larger than another, :func:`~._offers.prune_terms`
    drops what they need not keep; then :func:`~._offers.offer_cosine_law`
    (an offer taken is pruned of the terms it kept from the choice);
    then :func:`weigh_other_spaces`, and the offer again for another space's
    finalist the trajectories prefer. Marks each finalist's record ``tied`` (the offered
    laws never are).

    Returns
    -------
    choice : int
        Index into ``finalists`` (extended by the pruned and offered laws).
    judgement : dict or None
        The verdict among sets of terms that decided, its ``kind`` ``"tied
        finalists"``, ``"cosine law"`` or ``"other spaces"``, with ``pruned``
        (the names of the terms dropped) and ``untied`` (the terms of an
        untied finalist the trajectories preferred, :func:`richer_finalist`
        or :func:`other_spaces`, or None); None when there was none.

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
            disputed = disputed_terms(records[finalists[choice]]["fitted"], judged)
            choice, pruned = prune_terms(records, finalists, choice, disputed, spaces, layouts,
                                         folds, trajectories, dt, noise, **search)
            judgement["pruned"] = pruned
        untied = None if judgement is None else judgement.get("untied")
        offer = (spaces, layouts, folds, trajectories, dt, noise)
        choice, judgement = _offer_cosine(records, finalists, choice, judgement, pruned, untied,
                                          *offer, **search)
        choice, verdict = weigh_other_spaces(records, finalists, choice, tied, trajectories, dt,
                                             noise)
        if verdict is not None:
            choice, judgement = _offer_cosine(records, finalists, choice, verdict, [],
                                              verdict["untied"], *offer, **search)
    return choice, judgement


def _offer_cosine(records, finalists, choice, judgement, pruned, untied, spaces, layouts,
                  folds, trajectories, dt, noise, **search):
    """:func:`~._offers.offer_cosine_law`; its verdict, where it ran, replaces ``judgement``.

    An offer taken is pruned of the terms it kept from the choice
    (:func:`~._offers.inherited_terms`) while the criterion improves.
    """
    before = records[finalists[choice]]["fitted"]
    choice, cosine, substituted = offer_cosine_law(records, finalists, choice, spaces, layouts,
                                                   folds, trajectories, dt, noise, **search)
    if cosine is not None:
        if cosine["best"]:
            inherited = inherited_terms(records[finalists[choice]]["fitted"], before,
                                        substituted)
            choice, dropped = prune_terms(records, finalists, choice, inherited, spaces, layouts,
                                          folds, trajectories, dt, noise, **search)
            pruned = pruned + dropped
        judgement = {**cosine, "pruned": pruned, "untied": untied}
    return choice, judgement


def weigh_other_spaces(records, finalists, choice, tied, trajectories, dt, noise):
    """The choice against :func:`other_spaces`' finalists, on the trajectories.

    Returns
    -------
    choice : int
        The choice, or the other space's finalist the criterion prefers.
    verdict : dict or None
        :func:`~._judgement.judge_supports`' verdict (``kind`` ``"other
        spaces"``, ``untied`` the winner's terms) where another space won;
        None otherwise.
    """
    rivals = other_spaces(records, finalists, choice, tied)
    if not rivals:
        return choice, None
    models = [records[finalists[j]]["fitted"] for j in [choice] + rivals]
    verdict = judge_supports(models, trajectories, dt, noise)
    if not verdict["best"]:  # None, or the choice itself
        return choice, None
    terms = [sorted(support_key(model)) for model in models]
    verdict.update(terms=terms, kind="other spaces", pruned=[], untied=terms[verdict["best"]])
    return rivals[verdict["best"] - 1], verdict


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
    terms = [sorted(key) for key, _ in candidates]
    # "untied": the terms of an untied finalist the trajectories preferred.
    judgement.update(terms=terms, kind="tied finalists",
                     untied=terms[judgement["best"]] if choice == richer else None)
    return choice, tied, judgement, models


def _scored_untied(records, finalists, tied):
    """The untied finalists scored in every fold."""
    return [j for j, flag in enumerate(tied)
            if not flag and np.all(np.isfinite(records[finalists[j]]["scores"]))]


def richer_finalist(records, finalists, choice, tied):
    """The untied finalist with the fewest terms that keeps every term of the choice and more.

    The rollout scores cover a fraction of a second of held-out data, and
    their tie is one paired standard error: a term whose effect builds up
    over a whole orbit (``q**4`` of a pendulum at small angles, on one
    record) can leave its finalist behind a choice without it, by a fold
    split's luck. So it is judged with the tied ones (at most ``MAX_PRUNED``
    terms more than the choice), and :func:`~._offers.prune_terms` drops
    what it need not keep. None when there is none.
    """
    kept = support_key(records[finalists[choice]]["fitted"])
    keys = {j: support_key(records[finalists[j]]["fitted"])
            for j in _scored_untied(records, finalists, tied)}
    richer = [j for j, key in keys.items() if kept < key and len(key) - len(kept) <= MAX_PRUNED]
    return min(richer, key=lambda j: len(keys[j]), default=None)


def other_spaces(records, finalists, choice, tied):
    """The best-scoring untied finalist of each model space no tied finalist is in.

    Weighed by the trajectories against the final choice (the offers
    included, so that a Taylor series offered its cosine law is not beaten
    by another space's long series first): on one record of a softening
    spring, ``p^2, cos 2q`` (the periodic space) was alone in the tie under
    one fold split of four, with the exact polynomial law one standard error
    behind. At most ``MAX_JUDGED - 1``, the best scores first.
    """
    taken = {records[finalists[j]]["space"] for j in np.flatnonzero(tied)}
    taken.add(records[finalists[choice]]["space"])
    best = {}
    for j in _scored_untied(records, finalists, tied):
        space, score = records[finalists[j]]["space"], np.mean(records[finalists[j]]["scores"])
        if space not in taken and (space not in best or score > best[space][0]):
            best[space] = (score, j)
    return [j for _, j in sorted(best.values(), reverse=True)][:MAX_JUDGED - 1]
