"""The conservation check: calibrated on conservative data, still sees friction, right advice.

Issue 32: ConservationWarning fired on conservative noisy pendulum data in
5 of 20 seeds (the naive z-score treated the correlated samples of a
trajectory as independent), read "-0.00 % of its spread per unit time
(z = -11.0) ... dissipative" on noise-free data, suggested ``damping=True``
for an energy gain, and pointed at scikit-learn's ``base.py``.
"""

import os
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.signal import lfilter
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import (
    ConservationWarning,
    DerivativeTransformer,
    DomainWarning,
    HamiltonianRegressor,
)
from sk_hamiltonian._cli.report import describe_energy_trend
from sk_hamiltonian._conservation import TREND_Z, energy_trend, trend_verdict
from sk_hamiltonian.datasets import damped_pendulum, make_trajectories, single_pendulum


def pendulum_fit(system, seed, noise=0.08, reverse=False):
    """The issue's setting: 100 trajectories of 40 steps, Q = 3, n = 8."""
    X = make_trajectories(system, 100, 40, dt=0.01, noise=noise, random_state=seed)
    if reverse:
        # Played backwards with the momenta flipped: the same H, with friction
        # turned into a drive (H(p, q) is even in p).
        X = X[:, ::-1] * np.array([-1.0, 1.0])
    Xt = DerivativeTransformer(dt=0.01, degree=3).fit_transform(X)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = HamiltonianRegressor(degree=8).fit(Xt)
    return model, [w for w in caught if issubclass(w.category, ConservationWarning)]


# The seeds on which the old check warned (z = -5.5, 6.9, -10.3, -8.1, -9.8).
@pytest.mark.parametrize("seed", [1, 5, 6, 13, 19])
def test_conservative_noisy_data_no_longer_cry_wolf(seed):
    model, caught = pendulum_fit(single_pendulum(), seed)
    assert not caught, [str(w.message) for w in caught]
    # Measured with the cluster-robust z: -2.1 to 1.6 on these seeds.
    assert abs(model.energy_trend_z_) < TREND_Z
    assert "look conservative" in describe_energy_trend(model)


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("SK_HAMILTONIAN_SLOW_TESTS"),
                    reason="40 fits, about 30 s; set SK_HAMILTONIAN_SLOW_TESTS=1")
def test_false_alarm_rate_over_twenty_seeds():
    # Target of issue 32: at most 1 in 20 (measured: 0 with noise, 0 without;
    # docs/measurements.rst).
    for noise in (0.08, 0.0):
        alarms = sum(bool(pendulum_fit(single_pendulum(), seed, noise)[1]) for seed in range(20))
        assert alarms <= 1, noise


def test_a_damped_pendulum_is_still_flagged_as_losing_energy():
    # damped_pendulum(0.1) in the same setting: flagged in 17 of 20 seeds
    # (z from -6.2 to -2.3); seed 0 is one of them.
    model, caught = pendulum_fit(damped_pendulum(0.1), 0)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "H~ loses" in message and "per period of the learned system" in message
    assert "dissipative (friction: consider damping=True)" in message
    assert model.energy_trend_z_ < -TREND_Z
    assert "H~ falls along the data" in describe_energy_trend(model)


def test_an_energy_gain_is_not_told_to_add_damping():
    # The damped pendulum's trajectories played backwards (momenta flipped)
    # are those of a driven pendulum: they gain energy.
    model, caught = pendulum_fit(damped_pendulum(0.1), 0, reverse=True)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "H~ gains" in message and "driven" in message
    assert "damping=True" not in message and "Damping would only remove energy" in message
    assert model.energy_trend_z_ > TREND_Z
    line = describe_energy_trend(model)
    assert "H~ rises along the data" in line and "--damping" not in line


def test_a_significant_but_tiny_trend_reads_conservative():
    # Issue 32's noise-free reading: "-0.00 % of its spread per unit time
    # (z = -11.0) ... they look dissipative".
    model = SimpleNamespace(energy_trend_=-2e-5, energy_trend_z_=-11.0, time_scale_=0.32)
    assert trend_verdict(model.energy_trend_, model.energy_trend_z_, model.time_scale_)[0] is None
    line = describe_energy_trend(model)
    assert line.startswith("energy trend of H~ along the data: -0.002% of its spread per unit "
                           "time (z = -11.0): significant but small")
    assert "look conservative" in line and "dissipative" not in line
    # Noise-free data fitted as the issue did: no warning, a conservative reading.
    fitted, caught = pendulum_fit(single_pendulum(), 0, noise=0.0)
    assert not caught and "look conservative" in describe_energy_trend(fitted)


def test_the_standard_error_accounts_for_correlation_along_trajectories():
    # Conservative "energies" with strongly correlated noise along each
    # trajectory (AR(1), correlation 0.95 between samples): over many data
    # sets the z-score must spread like a standard normal (or narrower),
    # for many short trajectories and for one long record cut into
    # stretches. Treating the samples as independent, it spread about five
    # times wider.
    rng = np.random.default_rng(0)

    def ar1(n, rho=0.95):
        w = rng.normal(size=n) * np.sqrt(1 - rho**2)
        w[0] = rng.normal()
        return lfilter([1.0], [1.0, -rho], w)

    for n_trajectories, n_times in ((100, 41), (1, 2000), (5, 400)):
        t = 0.01 * np.arange(n_times)
        z = [energy_trend([(t, ar1(n_times)) for _ in range(n_trajectories)])[1]
             for _ in range(200)]
        # Measured: standard deviations 1.04, 0.79, 0.84; largest |z| 3.65,
        # 2.10, 2.42.
        assert 0.6 < np.std(z) < 1.2
        assert np.max(np.abs(z)) < TREND_Z
    # A real trend stands out.
    t = 0.01 * np.arange(41)
    rate, z = energy_trend([(t, -0.5 * t + 0.01 * ar1(t.size)) for _ in range(100)])
    assert rate < 0 and z < -10


def test_warnings_point_at_the_users_line():
    # Issue 32: ConservationWarnings named sklearn/base.py, partial_fit's
    # DomainWarning sys:1.
    X = make_trajectories(damped_pendulum(0.1), 100, 40, dt=0.01, noise=0.08, random_state=0)
    Xt = DerivativeTransformer(dt=0.01, degree=3).fit_transform(X)
    with pytest.warns(ConservationWarning) as record:
        HamiltonianRegressor(degree=8).fit(Xt)
    assert {w.filename for w in record} == {__file__}
    with pytest.warns(ConservationWarning) as record:
        make_pipeline(DerivativeTransformer(dt=0.01, degree=3), HamiltonianRegressor(8)).fit(X)
    assert {w.filename for w in record} == {__file__}
    domain = [[-1.0, 1.0], [-1.0, 1.0]]  # narrower than the data
    model = HamiltonianRegressor(degree=4, domain=domain)
    for chunk in (Xt[:50], Xt[50:]):  # the first call builds the space, the others not
        with pytest.warns(DomainWarning) as record:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ConservationWarning)
                model.partial_fit(chunk)
        assert {w.filename for w in record} == {__file__}


@pytest.mark.parametrize("rate, reading", [
    (-0.4, "H~ falls along the data (25.13% of its spread per period (0.628)), but not clearly"),
    (0.4, "H~ rises along the data"),
])
def test_a_large_trend_just_under_the_rule_is_reported_as_a_hint(rate, reading):
    # z = 3.8 does not count (|z| > 4 does), but 25 % per period is not
    # "within the noise": the report says what it saw.
    model = SimpleNamespace(energy_trend_=rate, energy_trend_z_=3.8 * np.sign(rate),
                            time_scale_=0.1, damping_=np.zeros(1))
    assert trend_verdict(rate, model.energy_trend_z_, model.time_scale_)[0] is None
    line = describe_energy_trend(model)
    assert reading in line and "look conservative" not in line
    assert ("--damping" in line) == (rate < 0)
    # A small trend at the same z, or a large one at z = 2, still reads conservative.
    small = SimpleNamespace(energy_trend_=rate / 100, energy_trend_z_=model.energy_trend_z_,
                            time_scale_=0.1)
    noise = SimpleNamespace(energy_trend_=rate, energy_trend_z_=2.0 * np.sign(rate),
                            time_scale_=0.1)
    assert "look conservative" in describe_energy_trend(small)
    assert "look conservative" in describe_energy_trend(noise)
