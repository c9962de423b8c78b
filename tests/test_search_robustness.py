"""The default search on data its study scenes did not have: folds, exact data, long records, spikes.

The anharmonic spring ``H = p^2/2 + q^2/2 + q^4/4`` is not among the package's
datasets; it is built here as a user would, and so are an asymmetric well
(cubic and quartic terms) and a pendulum whose angle is read modulo one turn.
"""

import warnings

import numpy as np
import pytest
from sklearn.model_selection import KFold

from sk_hamiltonian import HamiltonianRegressor, DerivativeTransformer
from sk_hamiltonian.datasets import (
    HamiltonianSystem,
    anharmonic_spring,
    make_trajectories,
    single_pendulum,
)
from sk_hamiltonian.exceptions import OutlierWarning
from sk_hamiltonian.inspection import hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV
from sk_hamiltonian.model_selection._refine import refine_on_trajectories
from sk_hamiltonian.model_selection._screen import screen_ties

SPRING_TERMS = ["p^2", "q^2", "q^4"]


def spring_data(noise, n=120, seed=0):
    """Gaussian additive noise, ``noise`` times each variable's root-mean-square."""
    rng = np.random.default_rng(seed)
    X = anharmonic_spring().solve(rng.uniform(-1.5, 1.5, size=(n, 2)), 0.05 * np.arange(41),
                       max_step=0.005)
    rms = np.sqrt(np.mean(X.reshape(-1, 2) ** 2, axis=0))
    return X + noise * rms * rng.standard_normal(X.shape)


def terms(search):
    return sorted(term.text for term in hamiltonian_terms(search.best_estimator_[-1]))


def small_search(dt, **params):
    """The default search with fewer layouts and targets (the test's time)."""
    defaults = dict(denoise_degrees=("finite_difference", 5), degrees=(4, 6),
                    fit_on=("derivatives", "simpson", "weak"))
    return HamiltonianSearchCV(dt=dt, **{**defaults, **params})


@pytest.mark.parametrize("cv", [5, KFold(5, shuffle=True, random_state=3)],
                         ids=["default folds", "shuffled folds"])
def test_the_spring_law_does_not_depend_on_the_folds(cv):
    # At 3 % noise the periodic and mixed spaces once explained the
    # derivatives' bias 4 % better than the exact polynomial, and won on
    # some fold splits with a 4-term cosine series.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.05, cv=cv).fit(spring_data(0.03))
    assert terms(search) == SPRING_TERMS
    assert search.preparation_["momentum_scale"] == 1.0  # units within ten times: as they are


def test_exact_data_give_the_exact_law():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.05).fit(spring_data(0.0))
    assert search.preparation_["clean"]
    assert terms(search) == SPRING_TERMS
    # Only the fit targets exact to O(dt**4), on the raw states.
    assert set(search.cv_results_["param_hamiltonianregressor__fit_on"]) <= {"simpson", "weak"}
    coef = {t.text: t.coefficient for t in hamiltonian_terms(search.best_estimator_[-1])}
    np.testing.assert_allclose([coef["p^2"], coef["q^2"], coef["q^4"]], [0.5, 0.5, 0.25],
                               rtol=1e-4)


@pytest.mark.parametrize("units", [(1.0, 1000.0), (1000.0, 1.0)],
                         ids=["positions in thousandths", "momenta in thousandths"])
def test_the_spring_law_does_not_depend_on_the_units(units):
    # Positions in millimetres beside momenta in SI units: the position rows
    # of J dx/dt ~ grad H were a thousand times the momentum rows, and the
    # search kept p^2 alone. With momenta times b and positions times a, the
    # law in those units is a b H(q / a, p / b).
    b, a = units
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.05).fit(spring_data(0.01) * np.array([b, a]))
        natural = small_search(0.05).fit(spring_data(0.01))
    assert terms(search) == SPRING_TERMS
    # A power of ten: the momenta come back to the numbers of SI units, and
    # the search runs on the same numbers as there (to round-off).
    assert search.preparation_["momentum_scale"] == a / b
    coef = {t.text: t.coefficient for t in hamiltonian_terms(search.best_estimator_[-1])}
    expected = {t.text: t.coefficient for t in hamiltonian_terms(natural.best_estimator_[-1])}
    np.testing.assert_allclose([coef["p^2"], coef["q^2"], coef["q^4"]],
                               [expected["p^2"] * a / b, expected["q^2"] * b / a,
                                expected["q^4"] * b / a**3], rtol=1e-6)
    np.testing.assert_allclose([expected["p^2"], expected["q^2"], expected["q^4"]],
                               [0.5, 0.5, 0.25], rtol=0.01)


def test_the_trajectory_fit_keeps_terms_whose_coefficients_are_small_in_the_units():
    # With positions in thousandths the spring's q^4 reads 2.5e-10 beside
    # p^2's 500: taken for round-off of the change of basis, it was left out
    # of the trajectory fit, whose q^2 then took its place (+75 %).
    X = spring_data(0.01) * np.array([1.0, 1000.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        layout = DerivativeTransformer(dt=0.05, degree=5).fit_transform(X)
        model = HamiltonianRegressor(degree=4, momentum_degree=2,
                                     terms=[[2, 0], [0, 2], [0, 4]]).fit(layout)
        info = refine_on_trajectories(model, list(X), 0.05)
    assert info["status"] == "refined"
    coef = {t.text: t.coefficient for t in hamiltonian_terms(model)}
    np.testing.assert_allclose([coef["p^2"], coef["q^2"], coef["q^4"]], [500, 5e-4, 2.5e-10],
                               rtol=0.01)


def test_records_sampled_ten_times_a_period_give_the_spring_law():
    # dt = 0.5: the de-noising polynomials over a record of five periods leave
    # residuals 40 times the noise, and their finalists, scored in units of
    # their own flattened states, won with a law of q alone. Such layouts are
    # now left out; finite differences and the steps fit remain.
    rng = np.random.default_rng(0)
    X = anharmonic_spring().solve(rng.uniform(-1.5, 1.5, size=(120, 2)), 0.5 * np.arange(41),
                                  max_step=0.05)
    X = X + 0.02 * X.std(axis=(0, 1)) * rng.standard_normal(X.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.5).fit(X)
    assert search.best_params_["derivativetransformer__method"] == "finite_difference"
    # The law's terms, right to 0.5 %; at this step the search may keep a
    # small term more (here p^2 q^2, 0.0003 beside the law's 0.25 to 0.5).
    coef = {t.text: t.coefficient for t in hamiltonian_terms(search.best_estimator_[-1])}
    assert set(SPRING_TERMS) <= set(coef)
    np.testing.assert_allclose([coef["p^2"], coef["q^2"], coef["q^4"]], [0.5, 0.5, 0.25],
                               rtol=0.005)
    assert all(abs(c) < 0.01 for text, c in coef.items() if text not in SPRING_TERMS)


def test_one_long_record_is_cut_into_blocked_segments_and_fitted():
    system = single_pendulum()
    rng = np.random.default_rng(0)
    record = system.solve(system.initial_state, 0.01 * np.arange(2001))
    record = record + 0.02 * record.std(axis=0) * rng.standard_normal(record.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.01, denoise_degrees=(5,), degrees=(4,),
                              fit_on=("derivatives", "weak")).fit(record[np.newaxis])
    segments = search.preparation_["segments"]
    assert segments["n_records"] == 1 and segments["n_segments"] == 20
    assert search.n_splits_ == 5
    assert terms(search) == ["cos(q)", "p^2"]
    # One record is one energy level: the search says the law is pinned only there.
    one_level = search.preparation_["one_level"]
    assert one_level is not None and one_level["n_trajectories"] == 20
    assert "one level of the learned energy" in one_level["message"]


def test_spikes_are_named_left_out_and_the_law_found():
    X = make_trajectories(single_pendulum(), 150, 40, dt=0.01, noise=0.02, random_state=0)
    X[3, 17] = X[40, 0] = X[41, 40] = 1e6
    with pytest.warns(OutlierWarning, match=r"trajectories \[3, 40, 41\]"):
        search = small_search(0.01, denoise_degrees=(5,), degrees=(4,),
                              fit_on=("derivatives", "weak")).fit(X)
    assert search.preparation_["left_out"] == {3: [17], 40: [0], 41: [40]}
    assert terms(search) == ["cos(q)", "p^2"]


def test_missing_readings_are_left_out_like_spikes_and_named():
    X = make_trajectories(single_pendulum(), 150, 40, dt=0.01, noise=0.02, random_state=0)
    X[3, 10] = np.nan
    X[7, 0, 1] = np.inf
    X[9, 40, 0] = np.nan
    X[11, 17] = 1e6  # and a spike
    with pytest.warns(OutlierWarning, match=r"left out 4 samples of trajectories "
                                            r"\[3, 7, 9, 11\] as spikes or missing readings "
                                            r"\(3 NaN or infinite\)"):
        search = small_search(0.01, denoise_degrees=(5,), degrees=(4,),
                              fit_on=("derivatives", "weak")).fit(X)
    assert search.preparation_["missing"] == {3: [10], 7: [0], 9: [40]}
    assert search.preparation_["left_out"] == {3: [10], 7: [0], 9: [40], 11: [17]}
    assert terms(search) == ["cos(q)", "p^2"]
    assert np.isfinite(search.best_estimator_[-1].coef_).all()


def test_time_stamps_that_are_not_finite_are_refused():
    X = make_trajectories(single_pendulum(), 20, 40, dt=0.01, noise=0.02, random_state=0)
    t = 0.01 * np.arange(41)
    T = np.concatenate([np.broadcast_to(t[None, :, None], (20, 41, 1)), X], axis=2).copy()
    T[4, 6, 0] = np.nan
    with pytest.raises(ValueError, match=r"X\[4\]: the time stamps .* must be finite; sample 6"):
        HamiltonianSearchCV().fit(T)


def test_readings_moved_off_at_the_ends_of_records_are_left_out_by_the_trajectory_fit():
    # At a record's first or last sample the spike screen extrapolates from
    # one side, where 0.4 rad (about 30 noise levels) passes for noise; the
    # fitted trajectories pass by the neighbours, and the sample stands out.
    X = make_trajectories(single_pendulum(), 150, 40, dt=0.01, noise=0.02, random_state=0)
    X[5, 10] = 1e6  # a spike: trajectory 5 is cut there, its second piece starts at 11
    X[5, 40, 1] += 0.4
    X[70, 0, 1] -= 0.4
    X[90, 40, 1] += 0.4
    with pytest.warns(OutlierWarning, match=r"trajectory fit left out 3 samples of "
                                            r"trajectories \[5, 70, 90\]"):
        search = small_search(0.01, denoise_degrees=(5,), degrees=(4,),
                              fit_on=("derivatives", "weak")).fit(X)
    assert search.preparation_["left_out"] == {5: [10]}
    assert search.refinement_["status"] == "refined"
    assert search.refinement_["outliers"] == {5: [40], 70: [0], 90: [40]}
    assert terms(search) == ["cos(q)", "p^2"]


def test_time_stamps_that_do_not_increase_are_refused_before_anything_reads_them():
    X = make_trajectories(single_pendulum(), 20, 40, dt=0.01, noise=0.02, random_state=0)
    t = 0.01 * np.arange(41)
    t[10] = t[9]
    T = np.concatenate([np.broadcast_to(t[None, :, None], (20, 41, 1)), X], axis=2)
    # The spike screen once divided by the repeated step first, with a
    # RuntimeWarning before the error.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"X\[0\]: the time stamps .* strictly "
                                             r"increasing; sample 10"):
            HamiltonianSearchCV().fit(T)


def test_a_refinement_that_explains_held_out_data_worse_is_rejected_with_its_reason():
    # The held-out trajectories are of the pendulum, the training ones of a
    # pendulum under half the gravity, and the least-squares start knows the
    # first: fitting the terms to the training trajectories moves them away
    # from what the held-out ones show, and the check keeps the start.
    pendulum = make_trajectories(single_pendulum(), 40, 40, dt=0.01, noise=0.02,
                                 random_state=0)
    lighter = make_trajectories(single_pendulum(g=4.9), 40, 40, dt=0.01, noise=0.02,
                                random_state=1)
    params = dict(degree=4, periodic=[False, True], momentum_degree=2, threshold=0.03)

    def least_squares(indices):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            layout = DerivativeTransformer(dt=0.01, degree=3).fit_transform(pendulum)
            return HamiltonianRegressor(**params).fit(layout)

    model = least_squares(None)
    start = model.coef_.copy()
    info = refine_on_trajectories(model, list(lighter) + list(pendulum), 0.01,
                                  least_squares=least_squares, held_out=[np.arange(40, 80)])
    assert info["status"].startswith(
        "kept: the trajectory fit explains held-out trajectories worse")
    least, refined = info["check"]["misfit"]
    assert refined > 2 * least
    # ... by far more than the spread of the held-out trajectories' misfits.
    assert info["check"]["gain"] < -2 * info["check"]["gain_se"]
    np.testing.assert_array_equal(model.coef_, start)


def test_the_trajectories_judge_a_law_against_its_taylor_series():
    from sk_hamiltonian._trajectory_fit import difference_noise_model
    from sk_hamiltonian.model_selection._judgement import judge_supports

    X = make_trajectories(single_pendulum(), 100, 40, dt=0.01, noise=0.02, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, degree=5).fit_transform(X)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        taylor = HamiltonianRegressor(6, momentum_degree=2, threshold=0.001).fit(Xt)
        law = HamiltonianRegressor(4, periodic=[False, True], momentum_degree=2,
                                   threshold=0.03).fit(Xt)
    assert len(hamiltonian_terms(taylor)) > 2
    judgement = judge_supports([taylor, law], list(X), 0.01,
                               difference_noise_model(list(X)))
    assert judgement["best"] == 1
    assert judgement["rss"][1] < judgement["rss"][0]


def test_no_space_fits_the_data_says_why():
    # One record of 170 samples in 2 folds cannot hold the 495 unknowns of
    # degree 30 at any space: the error names the degree and the rows short.
    X = make_trajectories(single_pendulum(), 1, 170, dt=0.01, noise=0.02, random_state=0)
    with pytest.raises(ValueError, match="No model space could be set up") as info:
        small_search(0.01, cv=2, degrees=(30,), fit_on=("derivatives",)).fit(X)
    assert "degree 30 has 495 unknowns" in str(info.value)
    assert "lower degrees (degrees)" in str(info.value)


@pytest.mark.slow
def test_an_angle_read_modulo_one_turn_gives_the_pendulum_law():
    # Rotating and librating orbits, the angle reported in [-pi, pi) as an
    # encoder gives it: every rotation jumps by 2 pi between two samples.
    rng = np.random.default_rng(0)
    pendulum = single_pendulum()
    x0 = np.column_stack([rng.uniform(-8, 8, 150), rng.uniform(-np.pi, np.pi, 150)])
    X = pendulum.solve(x0, 0.02 * np.arange(41), max_step=0.002)
    X = X + 0.01 * np.sqrt(np.mean(X.reshape(-1, 2) ** 2, axis=0)) * rng.standard_normal(X.shape)
    wrapped = X.copy()
    wrapped[..., 1] = (X[..., 1] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(np.diff(wrapped[..., 1], axis=1)).max() > np.pi
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.02).fit(wrapped)
    assert terms(search) == ["cos(q)", "p^2"]
    coef = {t.text: t.coefficient for t in hamiltonian_terms(search.best_estimator_[-1])}
    np.testing.assert_allclose([coef["p^2"], coef["cos(q)"]], [0.5, -9.8], rtol=0.01)


@pytest.mark.slow
def test_an_asymmetric_anharmonic_well_from_few_long_records():
    # H = p^2/2 + q^2/2 + 0.3 q^3 + 0.1 q^4, not among the datasets: five
    # records of 801 samples, cut into segments by the search itself.
    def hamiltonian(X):
        p, q = X[..., 0], X[..., 1]
        return p**2 / 2 + q**2 / 2 + 0.3 * q**3 + 0.1 * q**4

    def gradient(X):
        p, q = X[..., 0], X[..., 1]
        return np.stack([p, q + 0.9 * q**2 + 0.4 * q**3], axis=-1)

    well = HamiltonianSystem("asymmetric well", hamiltonian, gradient,
                             [[-1.2, 1.2], [-1.2, 1.2]], [0.5, 0.5])
    rng = np.random.default_rng(3)
    X = well.solve(rng.uniform(-1.2, 1.2, size=(5, 2)), 0.05 * np.arange(801), max_step=0.005)
    X = X + 0.01 * np.sqrt(np.mean(X.reshape(-1, 2) ** 2, axis=0)) * rng.standard_normal(X.shape)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = small_search(0.05).fit(X)
    assert search.preparation_["segments"]["n_records"] == 5
    assert search.preparation_["one_level"] is None  # five records, five energies
    assert terms(search) == ["p^2", "q^2", "q^3", "q^4"]
    coef = {t.text: t.coefficient for t in hamiltonian_terms(search.best_estimator_[-1])}
    np.testing.assert_allclose([coef[k] for k in ("p^2", "q^2", "q^3", "q^4")],
                               [0.5, 0.5, 0.3, 0.1], rtol=0.02)


def test_the_screen_keeps_a_sparse_space_tied_at_its_own_threshold():
    # Made-up screen: a mixed space's dense fit (threshold 0) has the lowest
    # error of all; the polynomial space's three terms are 10 % above it in
    # every fold, but tie with the periodic space's five at threshold 0.03.
    folds = np.array([1.0, 1.2, 1.1, 1.15, 1.05]) * 1e-3
    rows = [(2, 0.0, 1.00, 34), (1, 0.0, 1.03, 24), (0, 0.0, 1.12, 14),
            (2, 0.03, 50.0, 3), (1, 0.03, 1.07, 5), (0, 0.03, 1.12, 3)]
    records = [dict(space=space, threshold=threshold, errors=scale * folds, n_terms=n,
                    size=100) for space, threshold, scale, n in rows]
    best, tied = screen_ties(records)
    assert best == 4  # the fewest terms among the overall ties
    assert tied.tolist() == [True, True, False, False, True, True]
    # Only the overall ties when the threshold's best is itself rejected.
    records[4]["errors"] = 1.2 * folds
    _, tied = screen_ties(records)
    assert tied.tolist() == [True, True, False, False, False, False]


@pytest.mark.slow
def test_relative_noise_does_not_screen_out_the_spring_law():
    # 200 records of 41 samples at 2 % multiplicative noise (one draw of the
    # robustness study's): a mixed space's 34 terms absorbed the derivatives'
    # state-dependent error 10 % better than the exact three, the polynomial
    # space was screened out and a five-term cosine series chosen.
    rng = np.random.default_rng(19)
    X = anharmonic_spring().solve(rng.uniform(-1.5, 1.5, size=(200, 2)), 0.05 * np.arange(41),
                                  max_step=0.005)
    X = X * (1 + 0.02 * rng.standard_normal(X.shape))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = HamiltonianSearchCV(dt=0.05).fit(X)
    assert any(not space.get("periodic") and not space.get("mixed")
               for space in search.kept_spaces_)
    assert terms(search) == SPRING_TERMS
