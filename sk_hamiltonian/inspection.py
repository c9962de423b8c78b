"""Read a learned Hamiltonian: its terms in the user's own coordinates.

The regressors expand ``H~`` in Legendre polynomials on the box mapped to
``[-1, 1]`` and in Fourier series of angles measured from the start of their
period, which is good for fitting and opaque for reading. :func:`hamiltonian_terms`
re-expands ``H~`` in monomials ``x**k`` of the state variables as the user
gave them, times ``cos(k w x)`` and ``sin(k w x)`` for periodic variables
(``w = 2 pi / period``), and ranks the terms by their size over the domain;
:func:`format_hamiltonian` writes the leading ones as one line.
"""

from collections import namedtuple

import numpy as np
from sklearn.utils.validation import check_is_fitted

from ._space.mixed import MIXED_PERIOD, code_frequency
from ._space.readable import ReadableBasis

__all__ = ["HamiltonianTerm", "format_hamiltonian", "hamiltonian_terms", "to_sympy"]

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
    """The given names checked, else ``feature_names_in_``, else ``p, q`` or ``p1.., q1..``."""
    n_states = model.n_features_in_
    if state_names is None:
        names = getattr(model, "feature_names_in_", None)
        return list(names) if names is not None else _default_names(n_states)
    if len(state_names) != n_states:
        raise ValueError(
            f"state_names must have one name per state variable ({n_states}); got "
            f"{len(state_names)}."
        )
    return list(state_names)


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
    state_names = _state_names(model, state_names)
    unique = np.asarray(model.powers_)
    mixed = _mixed(model)
    # Readable coefficients of every output (one for H~), by the change of basis.
    coef = ReadableBasis(unique, model.domain_, model.periodic_, mixed).from_fitting @ np.ravel(
        model.coef_
    )
    low, high = model.domain_[:, 0], model.domain_[:, 1]
    magnitude = model._state_magnitude
    scale = np.array([
        np.prod([_factor_size(p, magnitude[i], model.periodic_[i]) for i, p in enumerate(row)])
        for row in unique
    ])
    size = np.abs(coef) * scale
    nonconstant = np.any(unique != 0, axis=1)
    largest = size[nonconstant].max(initial=0.0)
    if largest == 0:
        return []
    keep = nonconstant & (size > rtol * largest)
    omega = np.where(mixed, 2 * np.pi / MIXED_PERIOD, 2 * np.pi / (high - low))
    terms = []
    for row, c, s in zip(unique[keep], coef[keep], size[keep]):
        parts = [
            _factor_text(state_names[i], int(p), bool(model.periodic_[i]), omega[i],
                         bool(mixed[i]))
            for i, p in enumerate(row)
        ]
        terms.append(HamiltonianTerm(float(c), tuple(int(p) for p in row),
                                     "*".join(part for part in parts if part), float(s)))
    terms.sort(key=lambda term: -term.size)
    return terms


def format_hamiltonian(model, *, state_names=None, max_terms=8):
    """The leading terms of a learned ``H~`` as one readable line.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the state variables, as in :func:`hamiltonian_terms`.
    max_terms : int, default=8
        How many terms to show; the rest are summarized.

    Returns
    -------
    text : str
        ``"H~ = c1 t1 + c2 t2 + ... + const"``, terms in decreasing size.

    See Also
    --------
    hamiltonian_terms : The terms themselves.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.inspection import format_hamiltonian
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform(-1, 1, size=(200, 2))
    >>> y = np.column_stack([-X[:, 1], X[:, 0]])
    >>> print(format_hamiltonian(HamiltonianRegressor(degree=2).fit(X, y)))
    H~ = 0.5 q^2 + 0.5 p^2 + const
    """
    terms = hamiltonian_terms(model, state_names=state_names)
    if not terms:
        return "H~ = const"
    parts = []
    for term in terms[:max_terms]:
        sign = "-" if term.coefficient < 0 else "+"
        parts.append(f"{sign} {abs(term.coefficient):.4g} {term.text}")
    text = " ".join(parts)
    text = text[2:] if text.startswith("+ ") else "-" + text[2:]
    rest = terms[max_terms:]
    if rest:
        share = rest[0].size / terms[0].size
        # Two significant digits: "0.0%" would hide how small the rest is.
        text += (
            f" + ... ({len(rest)} smaller terms, each below {100 * share:.2g}% of the largest)"
            if len(rest) > 1
            else f" + ... (1 smaller term, below {100 * share:.2g}% of the largest)"
        )
    return "H~ = " + text + " + const"


def to_sympy(model, *, state_names=None, rtol=1e-9):
    """The learned ``H~`` as a sympy expression in the user's coordinates.

    The terms of :func:`hamiltonian_terms` summed: monomials of the ordinary
    variables times ``cos``/``sin`` of the periodic ones, with float
    coefficients and without the constant. Needs sympy (the ``symbolic``
    extra: ``pip install "sk_hamiltonian[symbolic]"``); the package does not
    depend on it otherwise.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the symbols, as in :func:`hamiltonian_terms`.
    rtol : float, default=1e-9
        Terms smaller than this fraction of the largest are left out, as in
        :func:`hamiltonian_terms`.

    Returns
    -------
    expression : sympy.Expr
        ``H~`` up to its constant; its free symbols are named after the state
        variables.

    Raises
    ------
    ImportError
        If sympy is not installed, with the command that installs it.

    See Also
    --------
    hamiltonian_terms : The same terms as data.

    Examples
    --------
    >>> import numpy as np
    >>> from sk_hamiltonian import HamiltonianRegressor
    >>> from sk_hamiltonian.inspection import to_sympy
    >>> rng = np.random.default_rng(0)
    >>> X = rng.uniform([-2, -np.pi], [2, np.pi], size=(300, 2))
    >>> y = np.column_stack([-9.8 * np.sin(X[:, 1]), X[:, 0]])  # H = p^2/2 - 9.8 cos q
    >>> model = HamiltonianRegressor(degree=4, periodic=[False, True], threshold=0.01)
    >>> to_sympy(model.fit(X, y)).evalf(4)
    0.5*p**2 - 9.8*cos(q)
    """
    try:
        import sympy
    except ImportError as error:
        raise ImportError(
            'to_sympy needs sympy: pip install "sk_hamiltonian[symbolic]" (or pip install sympy).'
        ) from error
    terms = hamiltonian_terms(model, state_names=state_names, rtol=rtol)
    state_names = _state_names(model, state_names)
    symbols = sympy.symbols(list(state_names), real=True)
    mixed = _mixed(model)
    omega = np.where(mixed, 2 * np.pi / MIXED_PERIOD,
                     2 * np.pi / (model.domain_[:, 1] - model.domain_[:, 0]))
    expression = sympy.Integer(0)
    for term in terms:
        factor = sympy.Float(term.coefficient)
        for i, power in enumerate(term.powers):
            if power == 0:
                continue
            if mixed[i] and power < 0:
                power = int(code_frequency(power))  # as the signed frequency of an angle
            elif not model.periodic_[i]:
                factor *= symbols[i] ** power
                continue
            frequency = abs(power) * omega[i]
            argument = (
                abs(power) * symbols[i] if np.isclose(omega[i], 1.0)
                else sympy.Float(frequency) * symbols[i]
            )
            factor *= sympy.cos(argument) if power > 0 else sympy.sin(argument)
        expression += factor
    return expression


def _mixed(model):
    """The model's mixed variables (none for a model fitted before they existed)."""
    mixed = getattr(model, "mixed_", None)
    return np.zeros(model.n_features_in_, dtype=bool) if mixed is None else np.asarray(mixed)
