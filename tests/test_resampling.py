"""Refits on resamples of whole trajectories: the parameters, the one-pass route, the intervals."""

import re

import numpy as np
import pytest
from sklearn.utils._param_validation import InvalidParameterError

import sk_hamiltonian
from sk_hamiltonian import (
    DerivativeTransformer,
    HamiltonianRegressor,
    VectorFieldRegressor,
    _design,
    _resampling,
)
from sk_hamiltonian._cli import main
from sk_hamiltonian._resampling import resample_weights
from sk_hamiltonian._trajectories import pack_derivatives
from sk_hamiltonian.datasets import double_well, make_trajectories, single_pendulum
from sk_hamiltonian._inspection.formula import _rounded
from sk_hamiltonian.inspection import (
    format_hamiltonian,
    prediction_band,
    resampled_models,
    term_intervals,
)

PENDULUM = dict(periodic=[False, True], momentum_degree=2, threshold=0.03, fit_on="simpson")


@pytest.fixture(scope="module")
def pendulum():
    X = make_trajectories(single_pendulum(), 40, 20, 0.05, noise=0.01, random_state=0)
    return DerivativeTransformer(dt=0.05).fit_transform(X)


@pytest.fixture(scope="module")
def exact_double_well():
    """Trajectories of H = p^2/2 - q^2/2 + q^4/4 with their exact derivatives."""
    system = double_well()
    X = make_trajectories(system, 30, 20, 0.05, noise=0.0, random_state=1)
    t = 0.05 * np.arange(X.shape[1])
    derivatives = system.vector_field(X.reshape(-1, 2)).reshape(X.shape)
    times = np.broadcast_to(t, X.shape[:2])
    return pack_derivatives(times, X, derivatives, X, True)


def resampled(Xt, n_resamples=20, **params):
    params = {"degree": 4, **PENDULUM, "random_state": 0, **params}
    return HamiltonianRegressor(n_resamples=n_resamples, **params).fit(Xt)


def test_default_is_no_resampling_and_a_refit_without_clears_it(pendulum):
    model = HamiltonianRegressor(4, **PENDULUM).fit(pendulum)
    assert not hasattr(model, "resampled_coef_")
    model.set_params(n_resamples=5, random_state=0).fit(pendulum)
    assert model.resampled_coef_.shape == (5, model.coef_.size)
    model.set_params(n_resamples=0).fit(pendulum)
    assert not hasattr(model, "resampled_coef_")


def test_fixed_random_state_gives_identical_refits(pendulum):
    a, b = resampled(pendulum), resampled(pendulum)
    assert np.array_equal(a.resampled_coef_, b.resampled_coef_)
    other = resampled(pendulum, random_state=1)
    assert not np.array_equal(a.resampled_coef_, other.resampled_coef_)
    # The main fit does not depend on the resampling.
    assert np.array_equal(a.coef_, HamiltonianRegressor(4, **PENDULUM).fit(pendulum).coef_)


def test_two_jobs_give_the_refits_of_one(pendulum):
    one = resampled(pendulum, n_jobs=1)
    two = resampled(pendulum, n_jobs=2)
    assert np.array_equal(one.resampled_coef_, two.resampled_coef_)


def test_weights_bootstrap_and_half_subsamples():
    boot = resample_weights(30, 200, "bootstrap", 0)
    assert boot.shape == (200, 30) and np.all(boot.sum(axis=1) == 30)
    assert np.all(boot == np.round(boot)) and boot.max() > 1  # with replacement
    half = resample_weights(31, 50, "subsample", 0)
    assert np.all(half.sum(axis=1) == 15) and set(np.unique(half)) == {0.0, 1.0}
    assert len({row.tobytes() for row in half}) == 50


def _separate_fit(model, Xt, weights, **params):
    """The model's estimator fitted on the resample itself: its trajectories, repeated."""
    taken = np.repeat(np.arange(weights.size), weights.astype(int))
    separate = type(model)(**{**model.get_params(), "n_resamples": 0, **params})
    return separate.set_params(domain=model.domain_).fit(Xt[taken])


@pytest.mark.parametrize("kind", ["bootstrap", "subsample"])
@pytest.mark.parametrize("params", [
    dict(degree=4, **PENDULUM),
    dict(degree=4, threshold=0.01, fit_on="derivatives"),
    dict(degree=3, damping=True, fit_on="steps"),
])
def test_weighted_sums_equal_fits_on_the_resampled_trajectories(pendulum, kind, params):
    model = HamiltonianRegressor(**params, n_resamples=3, resample=kind, random_state=2)
    model.fit(pendulum)
    weights = resample_weights(len(pendulum), 3, kind, 2)
    for r in (0, 2):
        separate = _separate_fit(model, pendulum, weights[r])
        scale = np.abs(separate.coef_).max()
        np.testing.assert_allclose(model.resampled_coef_[r], separate.coef_, rtol=0,
                                   atol=1e-9 * scale)
        if params.get("damping"):
            np.testing.assert_allclose(model.resampled_damping_[r], separate.damping_,
                                       rtol=0, atol=1e-9 * scale)


def test_vector_field_refits_equal_fits_on_the_resampled_trajectories(pendulum):
    model = VectorFieldRegressor(3, threshold=0.01, n_resamples=2, random_state=3).fit(pendulum)
    assert model.resampled_coef_.shape == (2,) + model.coef_.shape
    weights = resample_weights(len(pendulum), 2, "bootstrap", 3)
    separate = _separate_fit(model, pendulum, weights[1])
    np.testing.assert_allclose(model.resampled_coef_[1], separate.coef_, rtol=0,
                               atol=1e-9 * np.abs(separate.coef_).max())


def test_trajectory_equations_across_blocks_and_groups(pendulum, monkeypatch):
    model = resampled(pendulum, n_resamples=4, fit_on="simpson")
    data = model._training_data(pendulum, None, None)
    design = model._design(model._space)
    whole = design.trajectory_normal_equations(data)
    # Blocks of 7 pairs of steps: every trajectory (18 pairs) straddles blocks.
    monkeypatch.setattr(_design, "BLOCK_ENTRIES", 7 * design.n_columns * 2)
    split = design.trajectory_normal_equations(data)
    for k in (0, 13, 39):
        alone = design.normal_equations(data.take_trajectories([k]))
        for a, b, c in zip(whole, split, alone):
            np.testing.assert_allclose(a[k], c, rtol=1e-12, atol=1e-12 * np.abs(c).max())
            np.testing.assert_allclose(b[k], c, rtol=1e-12, atol=1e-12 * np.abs(c).max())
    # Trajectories taken 3 at a time and resamples 2 at a time: the same refits.
    monkeypatch.setattr(_resampling, "RESAMPLE_ENTRIES", 3 * design.n_columns**2)
    grouped = resampled(pendulum, n_resamples=4, fit_on="simpson")
    np.testing.assert_allclose(grouped.resampled_coef_, model.resampled_coef_, rtol=0,
                               atol=1e-10 * np.abs(model.coef_).max())


def test_noise_free_polynomial_gives_zero_width_intervals(exact_double_well):
    model = HamiltonianRegressor(4, threshold=0.01, n_resamples=20, random_state=0)
    model.fit(exact_double_well)
    intervals = term_intervals(model)
    truth = {"p^2": 0.5, "q^2": -0.5, "q^4": 0.25}
    assert {t.text for t in intervals} == set(truth)
    for t in intervals:
        assert t.n_kept == 20
        assert abs(t.coefficient - truth[t.text]) < 1e-9
        # Round-off of the refits and the change of basis, nothing else.
        assert t.high - t.low < 1e-11 and t.low <= t.median <= t.high
    low, median, high = prediction_band(model, [0.0, 1.2], np.linspace(0, 3, 31))
    assert np.max(high - low) < 1e-9


def test_pendulum_intervals_cover_the_fit_and_print(pendulum):
    model = resampled(pendulum, n_resamples=30)
    intervals = term_intervals(model)
    assert [t.text for t in intervals[:2]] == ["cos(q)", "p^2"]
    for t in intervals[:2]:
        assert t.n_kept == 30 and t.n_resamples == 30
        assert t.low < t.coefficient < t.high and t.low < t.median < t.high
    wider = term_intervals(model, level=0.99)[0]
    assert wider.low <= intervals[0].low and wider.high >= intervals[0].high
    text = format_hamiltonian(model, intervals=True)
    assert re.fullmatch(
        r"H~ = -\d\.\d+ \(±0\.\d+\) cos\(q\) \+ 0\.\d+ \(±0\.\d+\) p\^2 \+ const; every term "
        r"kept in 30/30 resamples(; not in H~ but kept in some resamples: .*)? \(90% intervals\)",
        text,
    ), text
    half = float(re.search(r"\(±([\d.]+)\) cos", text).group(1))
    assert half == pytest.approx((intervals[0].high - intervals[0].low) / 2, rel=0.5)
    assert format_hamiltonian(model) == format_hamiltonian(
        HamiltonianRegressor(4, **PENDULUM).fit(pendulum))


def test_terms_dropped_by_the_model_but_kept_by_refits_are_listed(pendulum):
    model = resampled(pendulum, n_resamples=30, threshold=0.002)
    intervals = term_intervals(model)
    shown = {t.text for t in intervals if t.coefficient != 0}
    others = [t for t in intervals if t.coefficient == 0]
    text = format_hamiltonian(model, intervals=True, max_terms=20)
    for t in others[:3]:
        assert t.text not in shown and t.n_kept > 0
        assert f"{t.text} ({t.n_kept}/30)" in text


def test_rounding_follows_the_interval():
    assert _rounded(9.7963, 0.036) == ("9.80", "0.04")
    assert _rounded(0.49949, 0.0016) == ("0.4995", "0.0016")
    assert _rounded(0.5, 0.0) == ("0.5", "0")
    assert _rounded(0.5, 3e-16) == ("0.500000", "3e-16")
    assert _rounded(1234.5, 31.0) == ("1234", "30")


def test_resampled_models_are_fitted_models(pendulum):
    model = resampled(pendulum, n_resamples=3)
    models = resampled_models(model)
    X = np.array([[0.3, 0.2], [-1.0, 1.5]])
    for r, refit in enumerate(models):
        assert np.array_equal(refit.coef_, model.resampled_coef_[r])
        assert not hasattr(refit, "resampled_coef_")
        reference = HamiltonianRegressor(4, **PENDULUM).fit(pendulum)
        reference.coef_ = model.resampled_coef_[r].copy()
        reference.support_ = np.ones_like(reference.support_)
        reference._rebuild_fitted()
        np.testing.assert_allclose(refit.predict(X), reference.predict(X), rtol=1e-12)
    assert np.array_equal(model.coef_, resampled(pendulum, n_resamples=3).coef_)


def test_prediction_band_holds_the_refits(pendulum):
    model = resampled(pendulum, n_resamples=10)
    t = np.linspace(0, 4, 41)
    low, median, high = prediction_band(model, [0.5, 1.0], t, level=0.8)
    runs = np.array([m.simulate([0.5, 1.0], t, method="rk4") for m in resampled_models(model)])
    assert low.shape == (41, 2)
    np.testing.assert_allclose(median, np.median(runs, axis=0), atol=1e-6)
    np.testing.assert_allclose(low, np.percentile(runs, 10, axis=0), atol=1e-6)
    assert np.all(high[1:] - low[1:] > 0) and np.all(high[0] == low[0])


def test_prediction_band_of_an_angle_is_in_the_chart_of_x0(pendulum):
    # The same state with its angle a turn further: the same band, a turn
    # further (the models wrap an angle into [-pi, pi); the band does not).
    model = resampled(pendulum, n_resamples=10)
    t = np.linspace(0, 4, 41)
    bands = [prediction_band(model, x0, t) for x0 in ([0.5, 1.0], [0.5, 1.0 + 2 * np.pi])]
    for edge, turned in zip(*bands):
        np.testing.assert_allclose(turned, edge + [0.0, 2 * np.pi], atol=1e-9)
    assert np.abs(np.diff(bands[1][1][:, 1])).max() < 1.0  # no jump of 2 pi


def test_model_file_keeps_the_resampling(pendulum, tmp_path):
    for params in (dict(), dict(damping=True, threshold=0.0, fit_on="steps")):
        model = resampled(pendulum, n_resamples=7, **params)
        path = tmp_path / "model.skh"
        sk_hamiltonian.save(model, path)
        loaded = sk_hamiltonian.load(path)
        assert loaded.n_resamples == 7 and loaded.random_state == 0
        assert np.array_equal(loaded.resampled_coef_, model.resampled_coef_)
        if params:
            assert np.array_equal(loaded.resampled_damping_, model.resampled_damping_)
        assert format_hamiltonian(loaded, intervals=True) == format_hamiltonian(
            model, intervals=True)


def test_bad_input_says_what_to_do(pendulum):
    for value in (-1, 2.5, True, "10"):
        with pytest.raises(InvalidParameterError, match="n_resamples"):
            HamiltonianRegressor(n_resamples=value).fit(pendulum)
    with pytest.raises(InvalidParameterError, match="resample"):
        HamiltonianRegressor(n_resamples=3, resample="jackknife").fit(pendulum)
    X = np.random.default_rng(0).uniform(-1, 1, (50, 2))
    with pytest.raises(ValueError, match="n_resamples=5 resamples whole trajectories.*2-D"):
        HamiltonianRegressor(2, n_resamples=5).fit(X, X[:, ::-1])
    with pytest.raises(ValueError, match="hold 1 trajectory.*at least 2"):
        HamiltonianRegressor(2, n_resamples=5).fit(pendulum[:1])
    with pytest.raises(ValueError, match="hold 3 trajectories.*subsample.*at least 4"):
        HamiltonianRegressor(2, n_resamples=5, resample="subsample").fit(pendulum[:3])
    with pytest.raises(ValueError, match="partial_fit does not keep.*n_resamples=0"):
        HamiltonianRegressor(2, n_resamples=5, domain=[[-8, 8], [-4, 4]]).partial_fit(pendulum)
    plain = HamiltonianRegressor(4, **PENDULUM).fit(pendulum)
    for call in (lambda: term_intervals(plain), lambda: format_hamiltonian(plain, intervals=True),
                 lambda: prediction_band(plain, [0.0, 1.0], [0.0, 1.0])):
        with pytest.raises(ValueError, match="without resampling.*n_resamples=100"):
            call()
    model = resampled(pendulum, n_resamples=3)
    for level in (0, 1, 1.5, True):
        with pytest.raises(ValueError, match="level must be a number in"):
            term_intervals(model, level=level)
    with pytest.raises(ValueError, match="intervals must be True .* got 'yes'"):
        format_hamiltonian(model, intervals="yes")


def test_too_many_resamples_are_refused_before_any_work(pendulum, monkeypatch):
    def never(*args, **kwargs):
        raise AssertionError("the fit ran")

    monkeypatch.setattr(sk_hamiltonian._base, "solve", never)
    monkeypatch.setattr(_resampling, "resample_weights", never)
    for Regressor in (HamiltonianRegressor, VectorFieldRegressor):
        with pytest.raises(ValueError, match=r"n_resamples=1,000,000,000,000 refits would hold "
                                             r"about .* TB .*beyond the memory limit.*Lower "
                                             r"n_resamples: at most [\d,]+ fit here"):
            Regressor(degree=4, n_resamples=10**12).fit(pendulum)


def test_the_largest_resampling_said_to_fit_does(pendulum):
    # The count the message gives is the boundary: it fits, one more does not
    # (a limit just above what the fit itself needs, 491 kB, to keep it short).
    n_terms = HamiltonianRegressor(degree=4, **PENDULUM)._n_terms(2)
    with sk_hamiltonian.config_context(memory_limit=600_000):
        largest = _resampling.largest_resamples(len(pendulum), n_terms)
        with pytest.raises(ValueError, match=f"at most {largest:,} fit here"):
            resampled(pendulum, n_resamples=largest + 1)
        assert resampled(pendulum, n_resamples=largest).resampled_coef_.shape[0] == largest
    assert 100 < largest < 10_000


def test_mixed_model_file_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    X = rng.uniform(-2, 2, size=(300, 2))
    # H = p^2/2 + q^2/2 - 3 cos q: a torsion pendulum, sparse in the mixed space.
    y = np.column_stack([-(X[:, 1] + 3 * np.sin(X[:, 1])), X[:, 0]])
    model = HamiltonianRegressor(4, mixed=[False, True], threshold=0.01).fit(X, y)
    assert (model.powers_[:, 1] < 0).any()
    sk_hamiltonian.save(model, tmp_path / "mixed.skh")
    loaded = sk_hamiltonian.load(tmp_path / "mixed.skh")
    assert np.array_equal(loaded.mixed_, [False, True])
    assert np.array_equal(loaded.predict(X), model.predict(X))
    assert format_hamiltonian(loaded) == format_hamiltonian(model)


# The command: one candidate of the quick example, so that each run takes seconds.
QUICK_ONE = ["--quick", "--paper-grid", "--degrees", "4", "--denoise-degrees", "5",
             "--threshold", "0.01"]


def test_command_resamples_its_choice_and_show_prints_the_intervals(tmp_path, capsys):
    assert main(QUICK_ONE + ["--output", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^resampling: 100 bootstrap resamples of the 60 trajectories", out, re.M)
    learned = re.search(r"^learned: (H~ = .*)$", out, re.M).group(1)
    assert "(±" in learned and learned.endswith("(90% intervals)")
    model = sk_hamiltonian.load(tmp_path / "model.skh")
    regressor = model[-1]
    assert regressor.n_resamples == 100
    assert regressor.resampled_coef_.shape == (100, regressor.powers_.shape[0])
    assert format_hamiltonian(regressor, intervals=True) == learned
    assert main(["show", str(tmp_path / "model.skh")]) == 0
    shown = capsys.readouterr().out
    assert f"learned: {learned}" in shown
    assert "resampling: 100 bootstrap resamples of whole trajectories (seed 0)" in shown


def test_command_without_resampling(tmp_path, capsys):
    assert main(QUICK_ONE + ["--no-resample", "--output", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "resampling:" not in out and "(±" not in out
    regressor = sk_hamiltonian.load(tmp_path / "model.skh")[-1]
    assert regressor.n_resamples == 0 and not hasattr(regressor, "resampled_coef_")
    with pytest.raises(SystemExit) as exit_info:
        main(QUICK_ONE + ["--resamples", "-1", "--output", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "--resamples must be 0 (off) or more; got -1" in capsys.readouterr().err


def test_command_refuses_too_many_resamples_before_the_search(tmp_path, capsys, monkeypatch):
    from sk_hamiltonian._cli import fit as cli_fit

    def never(*args):
        raise AssertionError("the search ran")

    monkeypatch.setattr(cli_fit, "run_search", never)
    with pytest.raises(SystemExit) as exit_info:
        main(QUICK_ONE + ["--resamples", str(10**12), "--output", str(tmp_path)])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and len(err.splitlines()) == 1
    assert re.match(r"sk-hamiltonian: error: --resamples 1,000,000,000,000: the refits would "
                    r"hold about .* TB \(each resample's draw of 60 trajectories and its 1 "
                    r"coefficient\(s\)\), beyond the memory limit of .*; give --resamples "
                    r"[\d,]+ or fewer \(default 100\), or --no-resample$", err)


def test_command_refuses_resamples_the_chosen_model_cannot_hold(tmp_path, capsys):
    # Enough for one coefficient per refit (the check before the search), too
    # many for the chosen model's: said after the search, in the same words.
    limit = 8.0 * 10**6 * (60 + 2 * 1)
    with sk_hamiltonian.config_context(memory_limit=limit):
        with pytest.raises(SystemExit) as exit_info:
            main(QUICK_ONE + ["--resamples", str(10**6), "--output", str(tmp_path)])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "Traceback" not in err
    n_terms = re.search(r"draw of 60 trajectories and its (\d+) coefficient", err)
    assert n_terms and int(n_terms.group(1)) > 1, err
    assert err.splitlines()[-1].startswith("sk-hamiltonian: error: --resamples 1,000,000: ")



def test_model_file_checks_the_resampled_shapes(pendulum, tmp_path):
    import copy

    from sk_hamiltonian import load, save
    from sk_hamiltonian.io import ModelFileError

    model = resampled(pendulum, n_resamples=4, damping=True, threshold=0.0)
    save(model, tmp_path / "valid.skh")
    np.testing.assert_array_equal(load(tmp_path / "valid.skh").resampled_coef_,
                                  model.resampled_coef_)  # as fitted: accepted
    for key, value in (("resampled_coef_", model.resampled_coef_[:, :-1]),
                       ("resampled_damping_", model.resampled_damping_[:2])):
        broken = copy.deepcopy(model)
        setattr(broken, key, value)
        save(broken, tmp_path / "broken.skh")
        with pytest.raises(ModelFileError, match=key):
            load(tmp_path / "broken.skh")
    undamped = copy.deepcopy(resampled(pendulum, n_resamples=4))
    undamped.resampled_damping_ = np.zeros((4, 1))
    save(undamped, tmp_path / "undamped.skh")
    with pytest.raises(ModelFileError, match="resampled_damping_ is present without damping"):
        load(tmp_path / "undamped.skh")
