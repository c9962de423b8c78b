"""state_names: the user's names of the state variables, in every formula, report and model file."""

import warnings

import numpy as np
import pytest

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor, load, save
from sk_hamiltonian.datasets import make_trajectories, single_pendulum
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV

SPACE = dict(degree=4, periodic=[False, True], momentum_degree=2, threshold=0.03)


@pytest.fixture(scope="module")
def layout():
    X = make_trajectories(single_pendulum(), 60, 40, dt=0.01, noise=0.01, random_state=0)
    return X, DerivativeTransformer(dt=0.01).fit_transform(X)


def fit(Xt, **params):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return HamiltonianRegressor(**SPACE, **params).fit(Xt)


def test_the_model_names_its_variables_in_formulas_and_model_files(layout, tmp_path):
    model = fit(layout[1], state_names=["L", "theta"])
    assert {t.text for t in hamiltonian_terms(model)} == {"L^2", "cos(theta)"}
    assert "cos(theta)" in model.equations() and "L^2" in format_hamiltonian(model)
    # Names given at the call win over the model's.
    assert "cos(x)" in format_hamiltonian(model, state_names=["P", "x"])
    save(model, tmp_path / "m.skh")
    assert load(tmp_path / "m.skh").equations() == model.equations()
    # They name; they do not reorder: the coefficients are those of p, q.
    plain = fit(layout[1])
    np.testing.assert_allclose(model.coef_, plain.coef_)
    assert "cos(q)" in plain.equations()


@pytest.mark.parametrize("names, match", [
    ("theta", "array-like"),  # scikit-learn's parameter check, naming it too
    (["p", "q", "r"], r"one name per state variable \(2, momenta first\); got 3"),
    (["q", "q"], "distinct"),
    (["p", ""], "non-empty"),
])
def test_bad_names_are_refused_naming_the_argument(layout, names, match):
    with pytest.raises(ValueError, match=f"state_names.*{match}|{match}.*state_names"):
        fit(layout[1], state_names=names)


def test_the_search_gives_its_names_to_the_chosen_model(layout):
    X, _ = layout
    small = dict(denoise_degrees=("finite_difference",), degrees=(4,), fit_on=("derivatives",),
                 thresholds=(0.03,), refine=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = HamiltonianSearchCV(dt=0.01, state_names=["L", "theta"], **small).fit(X)
    assert "cos(theta)" in search.best_estimator_[-1].equations()
    # Refused before any fit, by name.
    with pytest.raises(ValueError, match="state_names must have one name per state variable"):
        HamiltonianSearchCV(dt=0.01, state_names=["L"], **small).fit(X)


def test_the_command_names_the_variables_it_is_told(tmp_path, capsys):
    from sk_hamiltonian._cli import main

    X = make_trajectories(single_pendulum(), 40, 40, dt=0.01, noise=0.02, random_state=0)
    path = tmp_path / "runs.npz"
    np.savez(path, trajectories=X)
    out_dir = tmp_path / "out"
    args = [str(path), "--dt", "0.01", "--no-resample", "--degrees", "4", "--denoise-degrees",
            "fd", "--output", str(out_dir)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(args + ["--names", "L", "theta"]) == 0
    assert "cos(theta)" in capsys.readouterr().out
    assert "cos(theta)" in load(out_dir / "model.skh")[-1].equations()
    with pytest.raises(SystemExit) as exit_info:
        main(args + ["--names", "a", "b", "c"])
    assert exit_info.value.code == 2
    assert "--names must have one name per state variable" in capsys.readouterr().err
