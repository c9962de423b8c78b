"""The learned Hamiltonian in the user's coordinates: its readable terms.

The regressors expand ``H~`` in Legendre polynomials on the box mapped to
``[-1, 1]`` and in Fourier series of angles measured from the start of their
period, which is good for fitting and opaque for reading;
:func:`hamiltonian_terms` re-expands it in monomials ``x**k`` of the state
variables as the user gave them, times ``cos(k w x)`` and ``sin(k w x)`` for
periodic variables (``w = 2 pi / period``), ranked by their size in the data.
"""

from collections import namedtuple

import numpy as np
from sklearn.utils.validation import check_is_fitted

from .._space.mixed import MIXED_PERIOD, code_frequency
from .._space.readable import ReadableBasis
from .._state_order import swap_names

HamiltonianTerm = namedtuple("HamiltonianTerm", ["coefficient", "powers", "text", "size"])
HamiltonianTerm.__doc__ = """One term of a learned Hamiltonian in the user's coordinates.

Parameters
----------
coefficient : float
    Its coefficient.
powers : tuple of int
    Per state variable: the exponent ``k`` of ``x**k``, or for a periodic
    variable a signed frequency (``+k``: ``cos(k w x)``, ``-k``: ``sin(k w x)``);
    for a mixed variable (``mixed=True``) an exponent ``k >= 0`` or a negative
    code of ``cos(k x)`` (``-(2k - 1)``) or ``sin(k x)`` (``-2k``).
text : str
    The term's factors, e.g. ``"p^2"`` or ``"p1*cos(q2)"`` (without coefficient).
size : float
    Its size in the data: ``|coefficient|`` times, for each variable with a
    non-zero exponent ``k``, ``r**k``, where ``r`` is the root-mean-square of
    that variable over the training states (trigonometric factors count 1).
    The ranking key.
"""


def _factor_size(power, magnitude, periodic):
    if periodic or power <= 0:
        return 1.0
    return float(magnitude) ** int(power)


def term_scales(powers, magnitude, periodic):
    """Each readable term's size per unit coefficient: ``r_i**k`` over its variables.

    ``r_i`` is the typical size of variable ``i`` (``magnitude``); periodic and
    trigonometric factors count 1. A coefficient times its scale is the
    term's size in the data, which does not depend on the units.
    """
    return np.array([np.prod([_factor_size(p, magnitude[i], periodic[i])
                              for i, p in enumerate(row)]) for row in powers])


def _factor_text(name, power, periodic, omega, mixed=False):
    if power == 0:
        return None
    if mixed and power < 0:
        # A mixed variable's Fourier factor, named by its signed frequency.
        return _factor_text(name, int(code_frequency(power)), True, omega)
    if not periodic:
        return name if power == 1 else f"{name}^{power}"
    k = abs(power) * omega
    scale = "" if np.isclose(k, 1.0) else (f"{abs(power)} " if np.isclose(omega, 1.0) else f"{k:.4g} ")
    return f"{'cos' if power > 0 else 'sin'}({scale}{name})"


def _state_names(model, state_names):
    """The given names checked, else the model's ``state_names``, else ``feature_names_in_``,
    else ``p, q`` or ``p1.., q1..``; in the model's ``(p, q)`` order.

    Names are given in the order of the user's columns, which
    ``state_order="qp"`` makes ``(q, p)``: they are exchanged into the order
    of the model's variables (``powers_``, ``domain_``), which the terms use.
    """
    n_states = model.n_features_in_
    swapped = getattr(model, "_swapped", lambda: False)()
    if state_names is None:
        state_names = getattr(model, "state_names", None)
    if state_names is None:
        names = getattr(model, "feature_names_in_", None)
        if names is None:
            return _default_names(n_states)
        names = list(names)
    else:
        names = check_state_names(state_names, n_states)
    return swap_names(names) if swapped else names


def check_state_names(state_names, n_states, *, name="state_names", order="momenta first"):
    """``state_names`` as a list of distinct non-empty strings, one per state variable.

    None passes through. Raises ``ValueError`` naming the argument (``name``:
    ``"state_names"``, or the command's ``"--names"``) and what it needs, the
    variables in ``order`` (how the caller's columns are ordered).
    """
    if state_names is None:
        return None
    if isinstance(state_names, str):
        raise ValueError(
            f"{name} must be a list of {n_states} names, one per state variable ({order}); "
            f"got the single string {state_names!r}. Pass e.g. {_default_names(n_states)!r}."
        )
    names = list(state_names)
    if len(names) != n_states:
        raise ValueError(
            f"{name} must have one name per state variable ({n_states}, {order}); "
            f"got {len(names)}."
        )
    bad = [value for value in names if not isinstance(value, str) or not value.strip()]
    if bad:
        raise ValueError(f"{name} must be non-empty strings; got {bad[0]!r}.")
    if len(set(names)) != len(names):
        raise ValueError(f"{name} must be distinct; got {names!r}.")
    return names


def _default_names(n_states):
    d = n_states // 2
    if d == 1:
        return ["p", "q"]
    return [f"p{i + 1}" for i in range(d)] + [f"q{i + 1}" for i in range(d)]


def hamiltonian_terms(model, *, state_names=None, rtol=1e-9):
    """The terms of a learned ``H~`` in the user's coordinates, largest first.

    ``H~`` is re-expanded in products of monomials ``x**k`` (ordinary
    variables, in the units of the data) and of ``cos(k w x)``, ``sin(k w x)``
    (periodic variables with period ``2 pi / w``), and each term is measured by
    its size at the typical magnitude of the training states (see
    :class:`HamiltonianTerm`). Measuring at the data's scale rather than at the
    corners of the box keeps the low-order terms that carry the physics (say
    ``p**2 / 2`` and ``q**2``) ahead of the high-order terms of a truncated
    series, which are large at the corners and largely cancel each other.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the state variables; None uses ``feature_names_in_`` if the
        model has them, else ``p, q`` or ``p1.., q1..``.
    rtol : float, default=1e-9
        Terms smaller than this fraction of the largest are dropped: they are
        round-off of the change of basis.

    Returns
    -------
    terms : list of HamiltonianTerm
        Sorted by decreasing ``size``. The constant is left out (``H~`` is
        defined up to one).

    See Also
    --------
    format_hamiltonian : The leading terms as one line.

    Notes
    -----
    Converting Legendre expansions of high degree to monomials cancels large
    terms against each other; beyond degree ~10 on wide domains the
    coefficients carry fewer digits than the model. The ranking, not the
    last digit, is what this view is for.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.inspection import hamiltonian_terms
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform([-2, 0], [2, 3], size=(200, 2))
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])           # H = (p^2 + q^2) / 2
    >>> model = HamiltonianRegressor(degree=2).fit(X, y)
    >>> [(t.text, round(t.coefficient, 6)) for t in hamiltonian_terms(model)]
    [('q^2', 0.5), ('p^2', 0.5)]
    """
    check_is_fitted(model, "coef_")
    readable = _Readable(model, state_names)
    # Readable coefficients of every output (one for H~), by the change of basis.
    coef = readable.from_fitting @ np.ravel(model.coef_)
    keep = readable.kept(coef, rtol)
    terms = [HamiltonianTerm(float(coef[j]), readable.powers(j), readable.text(j),
                             float(abs(coef[j]) * readable.scale[j]))
             for j in np.flatnonzero(keep)]
    terms.sort(key=lambda term: -term.size)
    return terms


class _Readable:
    """The readable basis of a fitted model: change of basis, term sizes and texts."""

    def __init__(self, model, state_names):
        self.names = _state_names(model, state_names)
        self.unique = np.asarray(model.powers_)
        self.periodic = np.asarray(model.periodic_)
        self.mixed = _mixed(model)
        self.from_fitting = ReadableBasis(self.unique, model.domain_, self.periodic,
                                          self.mixed).from_fitting
        self.scale = term_scales(self.unique, model._state_magnitude, self.periodic)
        self.nonconstant = np.any(self.unique != 0, axis=1)
        low, high = model.domain_[:, 0], model.domain_[:, 1]
        self.omega = np.where(self.mixed, 2 * np.pi / MIXED_PERIOD, 2 * np.pi / (high - low))

    def kept(self, coef, rtol):
        """Terms of readable coefficients ``coef`` (last axis: models) above ``rtol`` of the largest."""
        size = np.abs(coef) * (self.scale if coef.ndim == 1 else self.scale[:, None])
        size[~self.nonconstant] = 0.0
        largest = size.max(axis=0)
        return (size > rtol * largest) & (largest > 0)

    def powers(self, j):
        return tuple(int(p) for p in self.unique[j])

    def text(self, j):
        parts = [
            _factor_text(self.names[i], int(p), bool(self.periodic[i]), self.omega[i],
                         bool(self.mixed[i]))
            for i, p in enumerate(self.unique[j])
        ]
        return "*".join(part for part in parts if part)


def _mixed(model):
    """The model's mixed variables (none for a model fitted before they existed)."""
    mixed = getattr(model, "mixed_", None)
    return np.zeros(model.n_features_in_, dtype=bool) if mixed is None else np.asarray(mixed)
