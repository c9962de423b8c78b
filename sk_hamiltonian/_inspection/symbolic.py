"""The learned Hamiltonian as a sympy expression (the ``symbolic`` extra)."""

import numpy as np

from .._space.mixed import MIXED_PERIOD, code_frequency
from .terms import _mixed, _state_names, hamiltonian_terms

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


