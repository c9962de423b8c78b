"""Checks of :class:`~._search.HamiltonianSearchCV`'s list parameters, the fix in each message.

``_parameter_constraints`` checks each parameter's type; these check what a
type cannot say: the entries of the lists, and a de-noising degree against
the shortest trajectory.
"""

import warnings
from numbers import Integral, Real

import numpy as np
from sklearn.metrics import check_scoring

from .._hamiltonian import HamiltonianRegressor

FIT_TARGETS = ("derivatives", "steps", "simpson", "weak")
# Fit targets kept for exact data: those whose truncation error is O(dt**4).
CLEAN_FIT_TARGETS = ("simpson", "weak")
# The HamiltonianRegressor parameters an entry of ``spaces`` may set.
SPACE_PARAMETERS = ("periodic", "mixed", "momentum_degree", "separable", "max_interaction",
                    "couplings", "solver")


def check_denoise(denoise_degrees, shortest):
    """The usable entries of ``denoise_degrees`` for trajectories of at least ``shortest`` samples.

    A de-noising degree ``Q`` needs ``Q + 2`` samples; larger ones are left
    out with a warning, and none left is an error.
    """
    values = list(denoise_degrees)
    if not values:
        raise ValueError("denoise_degrees must name at least one derivative layout.")
    out = []
    for value in values:
        if isinstance(value, str) and value == "finite_difference":
            out.append(value)
        elif isinstance(value, Integral) and not isinstance(value, bool) and value >= 1:
            out.append(int(value))
        else:
            raise ValueError(
                f"denoise_degrees entries must be 'finite_difference' or a de-noising "
                f"degree Q >= 1; got {value!r}."
            )
    usable = [v for v in out if v == "finite_difference" or v <= shortest - 2]
    if not usable:
        raise ValueError(
            f"Every de-noising degree in denoise_degrees={values!r} is too large for the "
            f"shortest trajectory ({shortest} samples; Q must be at most samples - 2): give "
            f"lower degrees or 'finite_difference'."
        )
    if len(usable) < len(out):
        warnings.warn(
            f"HamiltonianSearchCV: de-noising degrees "
            f"{[v for v in out if v not in usable]} left out: the shortest trajectory has "
            f"{shortest} samples, and Q must be at most samples - 2.",
            UserWarning, stacklevel=3,
        )
    return list(dict.fromkeys(usable))


def check_values(name, values, integer, low):
    """``values`` (e.g. ``degrees``) sorted without repeats, each a number ``>= low``."""
    values = list(np.ravel(values))
    ok = bool(values) and all(
        not isinstance(v, bool) and isinstance(v, Integral if integer else Real)
        and np.isfinite(v) and v >= low for v in values
    )
    if not ok:
        kind = "integers" if integer else "finite numbers"
        raise ValueError(f"{name} must be a non-empty list of {kind} >= {low}; got {values!r}.")
    cast = int if integer else float
    return sorted({cast(v) for v in values})


def check_fit_on(fit_on):
    """``fit_on`` as a list of fit targets, in its order without repeats."""
    values = list(fit_on) if not isinstance(fit_on, str) else [fit_on]
    if not values or any(v not in FIT_TARGETS for v in values):
        raise ValueError(f"fit_on must be a non-empty list of {FIT_TARGETS}; got {fit_on!r}.")
    return list(dict.fromkeys(values))


def check_spaces(spaces):
    """A copy of ``spaces``, a list of dicts of :data:`SPACE_PARAMETERS`."""
    if not spaces:
        raise ValueError("spaces must be 'auto' or a non-empty list of dicts.")
    for space in spaces:
        if not isinstance(space, dict) or set(space) - set(SPACE_PARAMETERS):
            raise ValueError(
                f"spaces entries must be dicts of HamiltonianRegressor parameters among "
                f"{sorted(SPACE_PARAMETERS)}; got {space!r}."
            )
    return [dict(space) for space in spaces]


def check_scorer(scoring):
    """``scoring`` as a scorer of a fitted regressor (:func:`~._degrees.score_fold`).

    None stays None: the search then scores by rollouts.
    """
    if scoring is None:
        return None
    return check_scoring(HamiltonianRegressor(), scoring=scoring)
