"""``HamiltonianRegressor(terms=...)``: a fit on named terms only, and the search's cosine offer."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import HamiltonianRegressor
from sk_hamiltonian.datasets import HamiltonianSystem, anharmonic_spring, coupled_pendula
from sk_hamiltonian.inspection import hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV
from sk_hamiltonian.model_selection._offers import (
    cosine_terms,
    harmonic_terms,
    inherited_terms,
)


def spring_states(n=400, seed=0):
    """States and exact derivatives of ``H = p^2/2 + q^2/2 + q^4/4``."""
    X = np.random.default_rng(seed).uniform(-1.5, 1.5, size=(n, 2))
    p, q = X.T
    return X, np.column_stack([-(q + q**3), p])


def coefficients(model):
    return {term.text: term.coefficient for term in hamiltonian_terms(model)}


def test_named_terms_are_the_only_terms_fitted():
    X, y = spring_states()
    model = HamiltonianRegressor(degree=6, terms=[[2, 0], [0, 2], [0, 4]]).fit(X, y)
    assert model.n_terms_ == 3
    assert coefficients(model) == pytest.approx({"p^2": 0.5, "q^2": 0.5, "q^4": 0.25})
    # A wrong form is fitted as given, by least squares on its own terms.
    wrong = HamiltonianRegressor(degree=4, mixed=[False, True],
                                 terms=[[2, 0], [0, 2], [0, -1]]).fit(X, y)
    assert sorted(coefficients(wrong)) == ["cos(q)", "p^2", "q^2"]
    assert wrong.score(X, y) < model.score(X, y)


def test_named_terms_match_the_dense_fit_restricted_by_hand():
    # The named fit is the least-squares fit on those columns of the readable
    # basis, whatever the solver.
    X, y = spring_states()
    y = y + 0.05 * np.random.default_rng(1).standard_normal(y.shape)
    named = [[2, 0], [0, 2], [0, 4], [1, 1]]
    fits = [HamiltonianRegressor(degree=4, terms=named, solver=solver).fit(X, y)
            for solver in ("lstsq", "normal")]
    # By hand: dH/dp and dH/dq of each named monomial against (dq/dt, -dp/dt).
    p, q = X.T
    columns = [(2 * p, 0 * q), (0 * p, 2 * q), (0 * p, 4 * q**3), (q, p)]
    A = np.vstack([np.concatenate(c) for c in columns]).T
    b = np.concatenate([y[:, 1], -y[:, 0]])
    expected = np.linalg.lstsq(A, b, rcond=None)[0]
    for model in fits:
        got = coefficients(model)
        np.testing.assert_allclose([got["p^2"], got["q^2"], got["q^4"], got["p*q"]], expected,
                                   rtol=1e-8)


def test_a_threshold_drops_among_the_named_terms_only():
    X, y = spring_states()
    model = HamiltonianRegressor(degree=4, threshold=0.01,
                                 terms=[[2, 0], [0, 2], [0, 4], [0, 3], [1, 1]]).fit(X, y)
    assert sorted(coefficients(model)) == ["p^2", "q^2", "q^4"]


def test_named_terms_read_in_the_models_order_with_columns_in_qp_order():
    X, y = spring_states()
    model = HamiltonianRegressor(degree=4, state_order="qp",
                                 terms=[[2, 0], [0, 2], [0, 4]]).fit(X[:, ::-1], y[:, ::-1])
    assert coefficients(model) == pytest.approx({"p^2": 0.5, "q^2": 0.5, "q^4": 0.25})


@pytest.mark.parametrize("terms, message", [
    ([[2, 0], [0, -1]], (r"terms holds 1 multi-index\(es\) that are not terms of the model "
                         r"space .* the first \(0, -1\)")),
    ([2, 0], r"terms must be a non-empty array of integer multi-indices of shape \(n_terms, 2\)"),
    ([[2.5, 0]], "terms must be a non-empty array of integer"),
    ([[0, 0]], r"not terms of the model space .* \(the constant is not a term\)"),
])
def test_terms_outside_the_space_are_refused_with_the_argument_named(terms, message):
    X, y = spring_states()
    with pytest.raises(ValueError, match=message):
        HamiltonianRegressor(degree=4, terms=terms).fit(X, y)


def test_the_cosine_offer_replaces_a_softening_series_of_a_position_alone():
    # States and derivatives of H = p^2/2 - cos q, noisy so that every term
    # of the fit below is kept.
    X = np.random.default_rng(0).uniform(-1.5, 1.5, size=(400, 2))
    p, q = X.T
    y = np.column_stack([-np.sin(q), p]) + 0.05 * np.random.default_rng(1).standard_normal((400, 2))
    model = HamiltonianRegressor(degree=6, terms=[[2, 0], [0, 2], [0, 4], [0, 6], [2, 2]]).fit(X, y)
    assert len(hamiltonian_terms(model)) == 5 and coefficients(model)["q^4"] < 0
    mixed, terms, springs, settled = cosine_terms(model, X)
    assert mixed == [False, True]
    # q^4 and q^6 alone become cos q; p^2 q^2 is not a power of q alone.
    assert sorted(map(tuple, terms)) == [(0, -1), (0, 2), (2, 0), (2, 2)]
    # q^2 is offered with and without; the offers settle it and cos q.
    assert springs == [[0, 2]] and sorted(settled) == [[0, -1], [0, 2]]
    # A hardening quartic (the spring's) and odd powers are not offered.
    X, y = spring_states()
    assert cosine_terms(HamiltonianRegressor(degree=4, terms=[[2, 0], [0, 2], [0, 4]]).fit(X, y),
                        X) is None
    odd = HamiltonianRegressor(degree=4, terms=[[2, 0], [0, 2], [0, 3]]).fit(X, y)
    assert cosine_terms(odd, X) is None


def test_an_offer_inherits_the_choices_terms_that_hold_a_position_but_those_it_put_in():
    X, y = spring_states()
    # Noisy, so that every named term keeps a coefficient.
    y = y + 0.05 * np.random.default_rng(1).standard_normal(y.shape)
    choice = HamiltonianRegressor(degree=4, terms=[[2, 0], [0, 1], [0, 2], [0, 3], [0, 4],
                                                   [2, 2]]).fit(X, y)
    offer = HamiltonianRegressor(degree=4, mixed=[False, True],
                                 terms=[[2, 0], [0, -1], [0, 1], [0, 2], [0, 3], [2, 2],
                                        [1, 1]]).fit(X, y)
    # p^2 is kinetic, cos q and p*q are the offer's own, q^2 is a term the
    # offer put in (offered with and without): none is inherited.
    assert sorted(inherited_terms(offer, choice, [[0, 2], [0, -1]])) == [(0, 1), (0, 3), (2, 2)]
    # Not put in, q^2 is inherited like any other power.
    assert sorted(inherited_terms(offer, choice, [[0, -1]])) == [(0, 1), (0, 2), (0, 3), (2, 2)]
    plain = HamiltonianRegressor(degree=4, terms=[[2, 0], [0, 2], [0, 3]]).fit(X, y)
    assert sorted(inherited_terms(plain, choice, [])) == [(0, 2), (0, 3)]


def test_the_harmonic_offer_replaces_an_angles_cosines_alone_by_cos_q():
    # States and derivatives of H = p^2/2 + 9.8 cos q about the top, noisy so
    # that every named term keeps a coefficient.
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-4, 4, 400), rng.uniform(np.pi - 1.3, np.pi + 1.3, 400)])
    p, q = X.T
    y = np.column_stack([9.8 * np.sin(q), p]) + 0.05 * rng.standard_normal((400, 2))
    periodic = [False, True]
    many = HamiltonianRegressor(degree=6, periodic=periodic,
                                terms=[[2, 0], [0, 2], [0, 3], [0, -1], [2, 1]]).fit(X, y)
    terms, substituted = harmonic_terms(many)
    # cos 2q and cos 3q become cos q; sin q and p^2 cos q stay.
    assert sorted(map(tuple, terms)) == [(0, -1), (0, 1), (2, 0), (2, 1)]
    assert substituted == [[0, 1]]
    # With cos q among them, the harmonics still become cos q alone.
    with_first = HamiltonianRegressor(degree=6, periodic=periodic,
                                      terms=[[2, 0], [0, 1], [0, 2]]).fit(X, y)
    assert sorted(map(tuple, harmonic_terms(with_first)[0])) == [(0, 1), (2, 0)]
    # One harmonic, or harmonics of a mixed (not periodic) position: no offer.
    assert harmonic_terms(HamiltonianRegressor(degree=6, periodic=periodic,
                                               terms=[[2, 0], [0, 2]]).fit(X, y)) is None
    mixed = HamiltonianRegressor(degree=6, mixed=periodic,
                                 terms=[[2, 0], [0, -1], [0, -3]]).fit(X, y)
    assert harmonic_terms(mixed) is None


def test_a_series_with_odd_powers_is_read_about_the_datas_centre():
    # A torsion pendulum about its top, H = p^2/2 + 2 cos q + (q - pi)^2/2:
    # in the data's chart its Taylor series holds q, q^2, q^3 and q^4.
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(-2, 2, 400), rng.uniform(np.pi - 1, np.pi + 1, 400)])
    p, q = X.T
    y = np.column_stack([2 * np.sin(q) - (q - np.pi), p])
    y = y + 0.05 * rng.standard_normal(y.shape)
    series = [[2, 0], [0, 1], [0, 2], [0, 3], [0, 4]]
    model = HamiltonianRegressor(degree=4, terms=series).fit(X, y)
    mixed, terms, springs, settled = cosine_terms(model, X)
    assert mixed == [False, True]
    # q^3 and q^4 become cos q; q^2 and q, a spring about pi, are offered
    # with and without, and left to the pruning of an offer taken.
    assert sorted(map(tuple, terms)) == [(0, -1), (0, 1), (0, 2), (2, 0)]
    assert sorted(springs) == [[0, 1], [0, 2]] and settled == [[0, -1]]
    # A hardening series with odd powers (p^2/4 + q^2 + q^3/2 + q^4/2) is not
    # offered a cosine: its quartic about the data's centre is positive.
    X = np.column_stack([rng.uniform(-2, 2, 400), rng.uniform(-1.2, 1.0, 400)])
    p, q = X.T
    y = np.column_stack([-(2 * q + 1.5 * q**2 + 2 * q**3), p / 2])
    hard = HamiltonianRegressor(degree=4, terms=series).fit(X, y)
    assert coefficients(hard)["q^4"] == pytest.approx(0.5)
    assert cosine_terms(hard, X) is None


def test_the_softening_is_read_from_the_series_over_the_data_not_the_sign_of_q4():
    # H = p^2/2 + q^2/2 + a q^4 + b q^6 with a > 0 > b: near q = 0 the
    # series hardens, over the states it softens on average where q is large.
    def fitted(a, b, scale):
        X = np.random.default_rng(2).uniform(-scale, scale, size=(400, 2))
        p, q = X.T
        y = np.column_stack([-(q + 4 * a * q**3 + 6 * b * q**5), p])
        return HamiltonianRegressor(degree=6, terms=[[2, 0], [0, 2], [0, 4], [0, 6]]).fit(X, y), X

    model, X = fitted(0.1, -0.1, 1.5)  # mean of 0.1 q^4 - 0.1 q^6 over |q| < 1.5: negative
    assert coefficients(model)["q^4"] > 0
    assert cosine_terms(model, X) is not None
    model, X = fitted(0.1, -0.1, 0.8)  # over |q| < 0.8: positive
    assert cosine_terms(model, X) is None


def test_the_rivals_are_the_smallest_richer_finalist_and_each_other_spaces_best():
    from sk_hamiltonian.model_selection._finalists import other_spaces, richer_finalist

    X, y = spring_states()
    # name: (terms, space, mean score)
    sets = {
        "choice": ([[2, 0], [0, 2]], 0, 1.0),
        "tied superset": ([[2, 0], [0, 2], [0, 4]], 0, 0.99),
        "superset": ([[2, 0], [0, 2], [0, 4], [0, 6]], 0, 0.9),
        "larger superset": ([[2, 0], [0, 2], [0, 4], [0, 6], [2, 2]], 0, 0.95),
        "not a superset": ([[2, 0], [0, 4]], 0, 0.97),
        "failed superset": ([[2, 0], [0, 2], [2, 2]], 0, np.nan),
        "other space": ([[2, 0], [0, 4]], 1, 0.8),
        "other space, best": ([[2, 0], [0, 3]], 1, 0.85),
        "third space": ([[2, 0], [0, 3], [0, 4]], 2, 0.7),
    }
    records = [dict(fitted=HamiltonianRegressor(degree=6, terms=terms).fit(X, y), space=space,
                    scores=np.full(5, score))
               for terms, space, score in sets.values()]
    tied = np.array([True, True] + [False] * 7)
    finalists = list(range(len(records)))
    names = list(sets)

    def rivals():
        richer = richer_finalist(records, finalists, 0, tied)
        return (None if richer is None else names[richer],
                [names[j] for j in other_spaces(records, finalists, 0, tied)])

    assert rivals() == ("superset", ["other space, best", "third space"])
    # A tied finalist is judged anyway, and a space with one in the tie has
    # no rival of its own.
    tied[2] = True
    assert rivals() == ("larger superset", ["other space, best", "third space"])
    tied[3] = tied[7] = True
    assert rivals() == (None, ["third space"])


def searched(X, dt=0.05, **params):
    """The default search on ``X``, its warnings silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return HamiltonianSearchCV(dt=dt, **params).fit(X)


def coupled_records(n_records, n_times, seed):
    """Records of the coupled pendula below the energy where a pendulum goes over the top, 2 % noise."""
    system = coupled_pendula(coupling=0.5, g=1.0)
    box = np.asarray(system.domain, dtype=float)
    rng = np.random.default_rng(seed)
    x0 = []
    while len(x0) < n_records:
        x = rng.uniform(box[:, 0], box[:, 1], size=(64, 4))
        x0.extend(x[system.hamiltonian(x) < 1.5])
    X = system.solve(np.array(x0[:n_records]), 0.05 * np.arange(n_times), max_step=0.005)
    return X + 0.02 * np.sqrt(np.mean(X.reshape(-1, 4) ** 2, axis=0)) * rng.standard_normal(X.shape)


@pytest.mark.slow
def test_few_long_records_of_coupled_pendula_give_their_cosine_law():
    # From five records of 801 samples at small angles, the screen (at degree
    # 4) keeps the polynomial space, whose thresholded fits keep the Taylor
    # series (q1^4, q2^4); the trajectories tell it from the cosine law.
    X = coupled_records(5, 801, seed=0)
    search = searched(X)
    model = search.best_estimator_[-1]
    assert sorted(coefficients(model)) == sorted(
        ["p1^2", "p2^2", "cos(q1)", "cos(q2)", "q1^2", "q1*q2", "q2^2"])
    assert search.judgement_["kind"] == "cosine law"
    assert search.judgement_["best"] == 1
    assert search.cv_results_["stage"][search.best_index_] == "cosine"
    assert coefficients(model)["cos(q1)"] == pytest.approx(-1.0, rel=0.05)
    # The chosen pipeline refits to the same terms from its parameters alone.
    refit = search.best_estimator_.__class__(search.best_estimator_.steps).fit(X)
    assert sorted(coefficients(refit[-1])) == sorted(coefficients(model))


def test_the_spring_keeps_its_quartic_against_the_cosine_offer():
    rng = np.random.default_rng(0)
    X = anharmonic_spring().solve(rng.uniform(-1.5, 1.5, size=(60, 2)), 0.05 * np.arange(41),
                                  max_step=0.005)
    X = X + 0.01 * np.sqrt(np.mean(X.reshape(-1, 2) ** 2, axis=0)) * rng.standard_normal(X.shape)
    search = searched(X, denoise_degrees=("finite_difference", 5), degrees=(4,))
    assert sorted(coefficients(search.best_estimator_[-1])) == ["p^2", "q^2", "q^4"]
    # Its quartic hardens: no cosine law is offered.
    assert "cosine" not in set(search.cv_results_["stage"])
    assert search.judgement_ is None or search.judgement_["kind"] != "cosine law"


@pytest.mark.slow
def test_an_offer_ahead_by_one_standard_error_is_taken():
    # One record of the coupled pendula (4 001 samples): on this draw the
    # cosine law's residual sum is lower than the Taylor series' by between
    # one and two standard errors of the difference over the fit's segments.
    # Under the former rule (two standard errors) the search kept the Taylor
    # series here, with q1^4 and q2^4.
    search = searched(coupled_records(1, 4001, seed=2))
    judgement = search.judgement_
    assert judgement["kind"] == "cosine law" and judgement["best"] > 0
    assert 1 < judgement["gain"] / judgement["gain_se"] < 2
    assert sorted(coefficients(search.best_estimator_[-1])) == sorted(
        ["p1^2", "p2^2", "cos(q1)", "cos(q2)", "q1^2", "q1*q2", "q2^2"])
    assert search.cv_results_["stage"][search.best_index_] == "cosine"


def pendulum_with_spring(n_records, seed):
    """200 x 41 records of ``H = p^2/2 - 2 cos q + q^2/2`` below ``H = 1.5``, 2 % relative noise."""
    return one_degree_records(lambda q: q**2 / 2 - 2 * np.cos(q), lambda q: q + 2 * np.sin(q),
                              [[-2.5, 2.5], [-2.5, 2.5]], 1.5, n_records, 41, 0.05, seed,
                              relative=True)


@pytest.mark.slow
def test_an_offer_taken_is_pruned_of_a_term_it_inherited():
    # The Taylor series the search chose kept a small p^2 q^2 beside q^2 and
    # q^4 (relative noise); the cosine law offered in their place inherits
    # it, and the trajectories need it no more than its price.
    search = searched(pendulum_with_spring(200, seed=32))
    judgement = search.judgement_
    assert judgement["kind"] == "cosine law" and judgement["best"] > 0
    assert "p^2*q^2" in judgement["terms"][judgement["best"]]
    assert judgement["pruned"] == ["p^2*q^2"]
    assert sorted(coefficients(search.best_estimator_[-1])) == ["cos(q)", "p^2", "q^2"]
    assert search.cv_results_["stage"][search.best_index_] == "pruned"


@pytest.mark.parametrize("bic, n_terms, gain, gain_se, taken", [
    ([100.0, 90.0], [3, 3], 10.0, 8.0, True),     # as many terms, ahead by 1.25 SE
    ([100.0, 95.0], [3, 3], 5.0, 8.0, False),     # within one SE: the choice stays
    ([100.0, 90.0], [3, 3], 10.0, np.nan, False),  # too few segments to tell
    ([100.0, 99.0], [3, 2], -3.0, 8.0, True),      # fewer terms: the criterion alone
    ([100.0, 101.0], [3, 2], 20.0, 1.0, False),    # the criterion prefers the choice
])
def test_an_offer_is_taken_by_the_criterion_and_one_standard_error(bic, n_terms, gain, gain_se,
                                                                   taken):
    from sk_hamiltonian.model_selection._offers import offer_taken

    assert offer_taken(np.array(bic), np.array(n_terms), gain, gain_se) is taken


def test_the_offers_gain_is_summed_over_segments_with_its_standard_error():
    from sk_hamiltonian.model_selection._judgement import offered_gain

    chosen, offered = np.array([3.0, 5.0, 4.0, 8.0]), np.array([2.0, 5.0, 3.0, 4.0])
    gain, se = offered_gain([chosen, offered])
    difference = chosen - offered
    assert gain == pytest.approx(6.0)
    assert se == pytest.approx(2 * np.std(difference, ddof=1))
    assert np.isnan(offered_gain([chosen, None])[0])


@pytest.mark.slow
def test_a_larger_set_the_trajectories_chose_is_pruned_then_offered_its_cosine_law(
        small_angle_record):
    # One record of a pendulum at small angles (conftest.py). The tied
    # finalists keep p^2, q^2 and a six-term series with p^2 q^2 and p^2 q^4,
    # which along one orbit are nearly collinear with powers of q; the
    # trajectories prefer the six to the two (whose law misses q^4), and
    # before pruning that choice was the answer, at an error of 1.16 at T = 20.
    X = small_angle_record
    search = searched(X, dt=0.02)
    judgement = search.judgement_
    assert sorted(judgement["pruned"]) == ["p^2*q^2", "p^2*q^4", "q^6"]
    assert "pruned" in set(search.cv_results_["stage"])
    # The pruned series keeps a softening q^4: its cosine law, offered with
    # and without q^2, is taken without q^2 (fewer terms, lower criterion).
    assert judgement["kind"] == "cosine law"
    assert judgement["terms"][0] == ["p^2", "q^2", "q^4"]
    assert judgement["bic"][2] == min(judgement["bic"])
    model = search.best_estimator_[-1]
    assert sorted(coefficients(model)) == ["cos(q)", "p^2"]
    assert coefficients(model)["cos(q)"] == pytest.approx(-9.8, rel=0.01)


@pytest.mark.slow
def test_a_richer_rival_the_folds_left_untied_is_judged_with_the_tied_ones(
        small_angle_record):
    # The same record with folds under which every tied finalist keeps
    # p^2, q^2 (the harmonic law, missing q^4) and the six-term series scores
    # just outside the tie: before the richer rival was judged, these folds
    # gave 0.5021 p^2 + 4.759 q^2 and the default folds the cosine law.
    from sklearn.model_selection import KFold

    search = searched(small_angle_record, dt=0.02, cv=KFold(5, shuffle=True, random_state=1))
    judgement = search.judgement_
    assert "q^4" in judgement["untied"] and {"p^2", "q^2"} < set(judgement["untied"])
    assert "q^6" in judgement["pruned"]
    model = search.best_estimator_[-1]
    assert sorted(coefficients(model)) == ["cos(q)", "p^2"]
    assert coefficients(model)["cos(q)"] == pytest.approx(-9.8, rel=0.01)


def one_degree_records(potential, force, box, energy, n_records, n_times, dt, seed,
                       relative=False):
    """Records of ``p^2/2 + V(q)`` from uniform states of ``box`` below ``energy``, 2 % noise.

    ``force`` is ``V'``. The noise is 2 % of each variable's root-mean-square
    (as in ``benchmarks/outside_scenes.py``, whose ``top`` and ``torsion_top``
    scenes these give), or with ``relative`` 2 % of each sample.
    """
    def hamiltonian(X):
        p, q = np.moveaxis(np.asarray(X, dtype=float), -1, 0)
        return p**2 / 2 + potential(q)

    def gradient(X):
        p, q = np.moveaxis(np.asarray(X, dtype=float), -1, 0)
        return np.stack([p, force(q)], axis=-1)

    box = np.asarray(box, dtype=float)
    system = HamiltonianSystem("one degree of freedom", hamiltonian, gradient, domain=box,
                               initial_state=[0.3, 0.5])
    rng = np.random.default_rng(seed)
    x0 = []
    while len(x0) < n_records:
        x = rng.uniform(box[:, 0], box[:, 1], size=(256, 2))
        x0.extend(x[system.hamiltonian(x) < energy])
    X = system.solve(np.array(x0[:n_records]), dt * np.arange(n_times), max_step=dt / 10)
    if relative:
        return X * (1 + 0.02 * rng.standard_normal(X.shape))
    scale = np.sqrt(np.mean(X.reshape(-1, 2) ** 2, axis=0))
    return X + 0.02 * scale * rng.standard_normal(X.shape)


def pendulum_about_the_top(n_records, seed):
    """1 001-sample records of ``p^2/2 + 9.8 cos q``, angles from the top, within 1.3 of ``pi``."""
    return one_degree_records(lambda q: 9.8 * np.cos(q), lambda q: -9.8 * np.sin(q),
                              [[-4, 4], [np.pi - 1.3, np.pi + 1.3]], -4.8, n_records, 1001, 0.02,
                              seed)


@pytest.mark.slow
def test_an_angle_about_its_top_gives_the_law_it_gives_about_the_bottom():
    # On this draw the periodic space's threshold keeps cos 2q, cos 3q and
    # cos 4q (about the top, no polynomial series is offered cos q); the
    # same records shifted by pi are fitted as a Taylor series, offered
    # cos q. The harmonic offer gives the law in both charts.
    X = pendulum_about_the_top(4, seed=11)
    top = searched(X, dt=0.02)
    assert top.judgement_["kind"] == "cosine law" and top.judgement_["best"] == 1
    assert sorted(top.judgement_["terms"][0]) == ["cos(2 q)", "cos(3 q)", "cos(4 q)", "p^2"]
    bottom = searched(X - [0, np.pi], dt=0.02)
    laws = [coefficients(search.best_estimator_[-1]) for search in (top, bottom)]
    assert sorted(laws[0]) == sorted(laws[1]) == ["cos(q)", "p^2"]
    assert laws[0]["cos(q)"] == pytest.approx(-laws[1]["cos(q)"], rel=1e-3)
    assert laws[0]["cos(q)"] == pytest.approx(9.8, rel=0.01)


@pytest.mark.slow
def test_a_torsion_pendulum_about_its_top_is_offered_its_law():
    # In the data's chart the choice keeps q, q^2, q^3 and q^4, the Taylor
    # series about pi; its powers from three up are offered cos q, with the
    # spring q^2, q about pi, which is the law.
    X = one_degree_records(lambda q: 2 * np.cos(q) + (q - np.pi) ** 2 / 2,
                           lambda q: (q - np.pi) - 2 * np.sin(q),
                           [[-2.5, 2.5], [np.pi - 2.5, np.pi + 2.5]], -0.5, 200, 41, 0.05,
                           seed=11)
    search = searched(X)
    judgement = search.judgement_
    assert judgement["kind"] == "cosine law" and judgement["best"] == 1
    assert {"q^3", "q^4"} <= set(judgement["terms"][0])
    law = coefficients(search.best_estimator_[-1])
    assert sorted(law) == ["cos(q)", "p^2", "q", "q^2"]
    # About pi, 2 cos q + (q - pi)^2 / 2 = 2 cos q + q^2 / 2 - pi q + const.
    assert law["cos(q)"] == pytest.approx(2.0, rel=0.05)
    assert law["q"] / law["q^2"] == pytest.approx(-2 * np.pi, rel=0.05)
