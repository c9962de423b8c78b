"""Stage 0 of the search, units: momenta rescaled where they and the positions differ by orders.

The search compares its candidates by the misfit of ``J dx/dt ≈ grad H``
summed over the rows of every variable. The rows of ``dq/dt`` carry the
positions' units per time, those of ``dp/dt`` the momenta's: a spring
recorded in millimetres and kilogram metres per second has position rows a
thousand times larger than its momentum rows, and the misfit, the thresholds
(each term's share of the fitted derivatives) and the screen then see the
position rows only. On ``p^2/2 + q^2/2 + q^4/4`` with its positions in
thousandths, the search kept ``p^2`` alone.

Multiplying every momentum by one factor ``beta`` is a canonical
transformation up to the constant ``beta`` (the law becomes ``beta H``):
the Hamiltonian keeps its terms, the positions (angles among them) keep
their values, and the two kinds of rows come back to one scale. Where the
spreads already agree within :data:`BALANCE_BOUND`, nothing is rescaled and
the search runs as before. The factor is a power of ten, the one nearest
the ratio of the spreads: records whose units differ from others' by powers
of ten (millimetres for metres, grams for kilograms) are searched as the
same numbers, wherever those spreads agree within ``sqrt(10)``, and so give
the same law. One factor balances the momenta against the positions as a
whole; positions of one record in units a thousand times apart
(millimetres beside radians) stay apart.
"""

import numpy as np
from sklearn.base import clone

from .._inspection.terms import hamiltonian_terms

# Momenta are rescaled where the geometric mean of the positions' spreads and
# that of the momenta's differ by more than this factor. On the anharmonic
# spring the search kept its law with positions 30 times the momenta and lost
# it at 100 (seeds 11 and 12); the study's scenes lie within 0.37 to 1.05,
# the robustness page's other scenes within 0.33 to 1.31.
BALANCE_BOUND = 10.0


def momentum_factor(states):
    """The factor that brings the momenta to the positions' spread, or 1.0 within the bound.

    Parameters
    ----------
    states : list of ndarray of shape (n_times_k, n_states)
        Trajectories in ``(p, q)`` order, states only.

    Returns
    -------
    factor : float
        The power of ten nearest ``exp(mean log sd(q) - mean log sd(p))``
        where that ratio lies outside ``[1 / BALANCE_BOUND,
        BALANCE_BOUND]``; 1.0 otherwise, or where a variable is constant.
    """
    samples = np.concatenate(states)
    spread = np.std(samples, axis=0)
    if not np.all(spread > 0):
        return 1.0
    d = samples.shape[1] // 2
    ratio = np.mean(np.log10(spread[d:])) - np.mean(np.log10(spread[:d]))
    if abs(ratio) <= np.log10(BALANCE_BOUND):
        return 1.0
    return float(10.0 ** np.round(ratio))


def times_momenta(X, factor, offset):
    """Trajectories (a list, or one array) with their momenta multiplied by ``factor``.

    ``offset`` is 1 where time stamps come first. Returns ``X`` itself for a
    factor of 1.
    """
    if factor == 1.0:
        return X
    if isinstance(X, (list, tuple)):
        return [times_momenta(T, factor, offset) for T in X]
    X = np.array(X, dtype=float)
    d = (X.shape[-1] - offset) // 2
    X[..., offset:offset + d] *= factor
    return X


def scaled_domain(domain, factor):
    """The search's ``domain`` (``(p, q)`` order, or None) for momenta times ``factor``."""
    if domain is None or factor == 1.0:
        return domain
    domain = np.array(domain, dtype=float)
    domain[: domain.shape[0] // 2] *= factor
    return domain


def refit_in_user_units(pipeline, X_user, X_balanced, factor):
    """The chosen pipeline fitted on the user's data.

    With momenta rescaled, the pipeline is fitted on the rescaled data first,
    and the terms it keeps are then fitted in the user's units with no
    threshold (``terms``, ``threshold=0``): a threshold compares terms by
    their share of the fitted derivatives, which the units shift. The terms
    read the same in both units (monomials of each variable).
    """
    if factor == 1.0:
        return pipeline.fit(X_user)
    balanced = clone(pipeline).fit(X_balanced)
    terms = [list(term.powers) for term in hamiltonian_terms(balanced[-1])]
    return pipeline.set_params(hamiltonianregressor__terms=terms,
                               hamiltonianregressor__threshold=0.0).fit(X_user)
