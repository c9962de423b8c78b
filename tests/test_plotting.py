"""sk_hamiltonian.plotting draws what it is given, where it is asked to."""

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from sk_hamiltonian import plotting  # noqa: E402
from sk_hamiltonian.plotting import (  # noqa: E402
    plot_energy,
    plot_errors,
    plot_phase,
    plot_states,
    plot_trajectories,
)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


T = np.linspace(0.0, 6.0, 61)
U = np.column_stack([np.sin(T), np.cos(T), np.sin(2 * T), np.cos(2 * T)])


def test_all_lists_the_public_functions():
    assert sorted(plotting.__all__) == [
        "plot_energy", "plot_errors", "plot_phase", "plot_prediction_band", "plot_states",
        "plot_threshold_path", "plot_trajectories",
    ]


def test_plot_errors_draws_each_curve_on_a_log_axis():
    _, ax = plt.subplots()
    e = np.full(T.shape, np.nan)
    e[:30] = 1e-3 * (1 + T[:30])  # blew up at T[30]
    out = plot_errors(T, {"SP": 1e-4 * (1 + T), "blown up": e}, ax=ax)
    assert out is ax and ax.get_yscale() == "log"
    lines = ax.get_lines()
    assert [line.get_label() for line in lines] == ["SP", "blown up"]
    np.testing.assert_array_equal(lines[1].get_ydata(), e)


def test_plot_errors_checks_lengths_and_dimensions():
    with pytest.raises(ValueError, match="errors\\['a'\\] has 3 times, but t has 61"):
        plot_errors(T, {"a": [1.0, 2.0, 3.0]})
    with pytest.raises(ValueError, match="must be 1-D"):
        plot_errors(T, {"a": U})
    with pytest.raises(ValueError, match="non-empty dict"):
        plot_errors(T, {})


def test_plot_states_one_panel_per_state_reference_first():
    V = U + 0.01
    axes = plot_states(T, {"exact": U, "model": V})
    assert axes.shape == (4,)
    assert [ax.get_ylabel() for ax in axes] == ["p1", "p2", "q1", "q2"]
    for i, ax in enumerate(axes):
        reference, model = ax.get_lines()
        np.testing.assert_array_equal(reference.get_ydata(), U[:, i])
        np.testing.assert_array_equal(model.get_ydata(), V[:, i])
        assert reference.get_color() == "k" and model.get_marker() == "o"
    # p panels on the top row, q panels below them.
    assert axes[0].get_subplotspec().rowspan.start == 0
    assert axes[2].get_subplotspec().rowspan.start == 1


def test_plot_states_uses_given_axes_and_names():
    _, given = plt.subplots(1, 2)
    axes = plot_states(T, {"exact": U[:, :2]}, axes=given, state_names=["$p$", "$q$"],
                       n_markers=0)
    assert list(axes) == list(given)
    assert axes[1].get_ylabel() == "$q$"
    with pytest.raises(ValueError, match="one Axes per state variable \\(4\\)"):
        plot_states(T, {"exact": U}, axes=given)
    with pytest.raises(ValueError, match="n_markers must be a non-negative integer"):
        plot_states(T, {"exact": U}, n_markers=-1)


def test_plot_phase_pair_index_and_tuple():
    ax = plot_phase({"exact": U}, pair=1)
    line, = ax.get_lines()
    np.testing.assert_array_equal(line.get_xdata(), U[:, 3])  # q2 horizontal
    np.testing.assert_array_equal(line.get_ydata(), U[:, 1])  # p2 vertical
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("q2", "p2")

    ax = plot_phase({"exact": U}, pair=(2, 1))
    line, = ax.get_lines()
    np.testing.assert_array_equal(line.get_xdata(), U[:, 2])
    np.testing.assert_array_equal(line.get_ydata(), U[:, 1])
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("q1", "p2")


@pytest.mark.parametrize("pair", [2, -1, (0, 4), (0,), (0.0, 1), True])
def test_plot_phase_rejects_bad_pairs(pair):
    with pytest.raises(ValueError, match="pair"):
        plot_phase({"exact": U}, pair=pair)


def test_plot_trajectories_and_energy_still_draw():
    ax = plot_trajectories(T, {"a": U[:, :2], "b": U[:, :2] * 2})
    assert len(ax.get_lines()) == 4
    H = 1.0 + 1e-9 * T
    ax = plot_energy(T, {"RK4": H})
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata()[1:], 1e-9 * T[1:], rtol=1e-6)
