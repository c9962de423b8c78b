"""What the regressors check of their parameters and inputs, and the DomainWarnings they give.

Checks before anything is computed (integer parameters, a fit's refusals,
the training data, fittedness, states of any leading shape, the Hamiltonian
fit's count of equations) and warnings after (states outside the fitted
domain, results that overflow float64). Each function takes the regressor
first; the regressors call them from private methods of the same names
(``_check_states`` for :func:`check_states`), which other modules call.
"""

import warnings
from numbers import Integral

import numpy as np
from sklearn.utils import check_array
from sklearn.utils._param_validation import InvalidParameterError
from sklearn.utils.validation import check_is_fitted, validate_data

from . import _training_data
from ._outliers import listed
from ._space.space import all_finite, count_outside
from ._state_order import swap_halves, swap_layout
from ._trajectories import is_trajectory_container
from ._warnings import warn
from .exceptions import DomainWarning

# Relative slack for "outside the domain", so that training points on the
# bounding box do not warn after round-off.
DOMAIN_SLACK = 1e-9

# What one equation of each fit target is called in the size check's message.
_ROWS = {"steps": "observed steps", "simpson": "pairs of steps", "weak": "weak-form windows"}


# ---------------------------------------------------------------- parameters
def check_integer_params(model):
    """Refuse a boolean for an integer parameter (``degree=True``)."""
    # scikit-learn's Interval(Integral) lets booleans through; True is no degree.
    for name in ("degree", "momentum_degree", "max_interaction", "n_resamples"):
        value = getattr(model, name)
        if isinstance(value, (bool, np.bool_)):
            raise InvalidParameterError(
                f"The {name!r} parameter of {type(model).__name__} must be an int, not "
                f"a boolean; got {value!r}."
            )


def check_no_swap(model, what):
    """Refuse ``state_order="qp"`` where the columns cannot be exchanged on the way in."""
    if model._swapped():
        raise ValueError(
            f"{type(model).__name__}: state_order='qp' is not supported for {what}. "
            f"Exchange the columns into (p_1..p_d, q_1..q_d) order yourself (e.g. "
            f"np.roll(X, d, axis=-1) for d degrees of freedom) and use state_order='pq'."
        )


def check_no_resampling(model, what):
    """Refuse ``n_resamples > 0`` where the trajectories are not at hand."""
    if isinstance(model.n_resamples, Integral) and model.n_resamples > 0:
        raise ValueError(
            f"{type(model).__name__}: n_resamples={model.n_resamples} refits on resamples "
            f"of the training trajectories, which {what} does not keep. Fit on "
            f"trajectories in memory (fit with the derivative layout), or set "
            f"n_resamples=0."
        )


def training_data(model, X, y, sample_weight, reset=True):
    """Validate the input and gather what the fit needs (a :class:`~sk_hamiltonian._training_data.TrainingData`).

    The states and derivatives come out in the model's ``(p, q)`` order:
    a layout is exchanged before its validation, 2-D states after theirs,
    so that ``feature_names_in_`` keeps the user's column order.
    """
    if not model._swapped():
        return _training_data.training_data(model, X, y, sample_weight, reset)
    if is_trajectory_container(X):
        return _training_data.training_data(model, swap_layout(X), y, sample_weight, reset)
    data = _training_data.training_data(model, X, y, sample_weight, reset)
    data.states, data.derivatives = swap_halves(data.states), swap_halves(data.derivatives)
    return data


def check_equation_count(model, data):
    """Refuse a Hamiltonian fit whose least-squares problem is underdetermined.

    ``data`` is a :class:`~sk_hamiltonian._training_data.TrainingData` (or
    its shape); every state variable's derivative gives one equation per
    row of the fit target.
    """
    n_states = data.states.shape[1]
    if data.derivatives.shape != data.states.shape:
        raise ValueError(
            f"y must hold the time derivative of every state variable, with the "
            f"same shape as X {data.states.shape}; got shape {data.derivatives.shape}."
        )
    n_rows = data.n_rows(model._fit_target) * n_states
    n_unknowns = model._n_terms(n_states)
    if n_rows < n_unknowns:
        what = _ROWS.get(model._fit_target, "samples")
        raise ValueError(
            f"The data give {data.n_rows(model._fit_target)} {what}, that is {n_rows} "
            f"equations for {n_unknowns} unknowns at degree={model.degree}: the "
            f"least-squares problem is underdetermined. Provide more samples (more "
            f"or longer trajectories), lower `degree`, or restrict the space "
            f"(momentum_degree, separable, max_interaction, couplings)."
        )


# -------------------------------------------------------------------- states
def check_fitted(model):
    """``check_is_fitted(model)``, short-cut for a model that has ``coef_``.

    ``check_is_fitted`` reads the tags and every attribute's name (about
    15 us, as long as the compiled prediction of one state); a model with
    ``coef_`` is fitted, and any other goes the full way to its error.
    """
    if "coef_" not in model.__dict__:
        check_is_fitted(model)


def check_states(model, X):
    """Validate states of shape (..., n_states); return them 2-D and the lead shape."""
    if hasattr(X, "columns") or np.ndim(X) == 2:
        X = validate_states(model, X)
        return X, X.shape[:-1]
    X = np.asarray(X)
    if X.ndim < 2 or X.shape[-1] != model.n_features_in_:
        raise ValueError(
            f"X must have shape (..., {model.n_features_in_}): states on the last axis, "
            f"as in fit; got shape {X.shape}. For a single state x, pass x[None]."
        )
    flat = check_array(X.reshape(-1, X.shape[-1]), ensure_min_samples=1)
    return flat, X.shape[:-1]


def validate_states(model, X):
    """``validate_data(model, X, reset=False)``, short-cut for a plain finite float64 array.

    For such an array (no feature names at fit) the validation returns
    it unchanged; its generic path costs about ten times the prediction
    of one state.
    """
    if (
        type(X) is np.ndarray and X.dtype == np.float64 and X.ndim == 2
        and X.shape[0] > 0 and X.shape[1] == model.n_features_in_
        and not hasattr(model, "feature_names_in_") and all_finite(X)
    ):
        return X
    return validate_data(model, X, reset=False)


# ------------------------------------------------------------------ warnings
def warn_outside(model, X, space=None, what="X", stacklevel=3):
    """A :class:`DomainWarning` for the rows of ``X`` outside ``space``'s box (default: the fitted one)."""
    domain, periodic = (model.domain_, model.periodic_) if space is None else (
        space.domain, space.periodic)
    n_outside = count_outside(X, domain, periodic, slack=DOMAIN_SLACK)
    warn_n_outside(model, n_outside, X.shape[0], domain, what, stacklevel + 1)


def warn_n_outside(model, n_outside, n_samples, domain=None, what="X", stacklevel=3):
    """The ``DomainWarning`` for ``n_outside`` of ``n_samples`` states (none for none)."""
    if n_outside:
        domain = model.domain_ if domain is None else domain
        warnings.warn(
            f"{n_outside / n_samples:.1%} of {what} lie outside the domain "
            f"{domain.tolist()}, where the model is not trusted.",
            DomainWarning,
            stacklevel=stacklevel,
        )


def warn_non_finite(model, values, X, method):
    """A :class:`DomainWarning` when ``method`` returns NaN or inf for some rows of ``X``.

    ``values`` has one row (or one value) per row of ``X`` (both in any
    state order). Finite states can still overflow the learned field
    (a degree-n polynomial at ``|x| = 1e300``); the result then holds NaN
    or inf, which must not leave a public method unannounced.
    """
    bad = ~np.isfinite(values.reshape(values.shape[0], -1)).all(axis=1)
    if not bad.any():
        return
    warn(
        DomainWarning(
            f"{method} returned NaN or inf for {bad.sum()} of {bad.size} states of X "
            f"(rows {listed(np.flatnonzero(bad))}): the learned "
            f"{'H~' if method == 'hamiltonian' else 'field'} overflows float64 there "
            f"(largest |X| there {np.max(np.abs(X[bad])):.3g}; the fitted domain is "
            f"{model.domain_.tolist()}). Pass states within the domain, or drop those "
            f"rows of the result (np.isfinite)."
        ),
        DomainWarning,
    )
