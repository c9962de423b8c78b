"""Do the states look ordered ``(q, p)`` instead of ``(p_1..p_d, q_1..q_d)``?

A kinetic energy grows with the momenta: for every mechanical system the
Hessian of ``H = p^T M(q)^{-1} p / 2 + V(q)`` in ``p`` is positive definite,
at every state. Fitted to states given as ``(q, p)``, the same data give
``-H`` with the halves exchanged: the kinetic energy, negated, lands in the
columns taken for the positions (a Hessian there negative definite at every
state), and ``-V`` in those taken for the momenta (a Hessian ``-V''``,
negative wherever the potential is convex). None of this raises an error:
the fit is as good as ever, only of another system. So after a fit the
Hessian of ``H~`` is evaluated at (a sample of) the training states, and the
order looks swapped when

- its block in the momenta, averaged over all the states or over the half
  nearest the momenta's median, is negative definite (both averages, since
  a convex potential may be concave far out, as a pendulum's past a quarter
  turn, or in the middle, as a double well's); and
- its block in the positions is negative definite, by a margin, at
  :data:`SHARE` of the states at least: what a negated kinetic energy is
  everywhere, and what spares a Hamiltonian with a genuine maximum in
  ``p``, such as the paper's Example 2, ``exp(-p^2 - 1.1 q^4)``, whose
  curvature in ``q`` is near zero at ``q = 0`` and positive past
  ``|q| = 0.91`` (a negative definite block at 79 % of its states).

Measured on fits of degree 3 to 8: on the pendulum (1 % and the paper's 8 %
noise), an anharmonic spring, a double well, Henon-Heiles, coupled and
torsion pendula with the halves exchanged, both hold (the positions' block
at 99.4 % to 100 % of the states); in the right order, neither holds on
these, nor on the double pendulum, the FPUT chain and the Toda lattice (the
momenta's block never negative definite). Exchanged, the last three go
unnoticed (96 % of the double pendulum's states; poor fits of the chains).
Data whose time runs backwards, or whose momenta have the wrong sign, give
``-H`` too, which the message says.
"""

import numpy as np

from ._warnings import warn
from .exceptions import StateOrderWarning

# States the Hessian is taken at: evenly spaced through the data; a few
# hundred give its sign, and the check stays far below the fit's cost.
SAMPLE_STATES = 500
# An averaged eigenvalue counts as negative below this fraction of the
# largest magnitude of the whole averaged Hessian: a model without a term in
# p has a zero block there, whose round-off must not count.
NEGATIVE = 1e-8
# The positions' block counts as negative definite at a state when its
# largest eigenvalue is below -MARGIN times the block's median eigenvalue
# magnitude over the states (a kinetic energy's curvature never nears zero),
# and the order looks swapped when it does at SHARE of the states at least.
MARGIN, SHARE = 0.1, 0.99


def order_evidence(model, states):
    """What the check reads from the Hessian of ``H~`` at the training states.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    states : ndarray of shape (n_samples, 2 * d)
        Training states; at most :data:`SAMPLE_STATES` of them, evenly spaced,
        are used.

    Returns
    -------
    momenta : ndarray of shape (2, d)
        Eigenvalues (increasing) of the momenta's block averaged over all the
        sampled states (row 0) and over the half nearest the momenta's
        median (row 1).
    share : float
        Share of the sampled states at which the positions' block is
        negative definite by the margin.
    scale : float
        Largest eigenvalue magnitude of the whole averaged Hessian (zero for
        a constant model).
    """
    states = states[:: max(1, states.shape[0] // SAMPLE_STATES)]
    hessian = model._hessian(states)
    d = states.shape[1] // 2
    P = states[:, :d]
    spread = np.subtract(*np.percentile(P, [75, 25], axis=0))
    distance = np.max(np.abs(P - np.median(P, axis=0)) / np.where(spread > 0, spread, 1.0),
                      axis=1)
    central = distance <= np.median(distance)
    momenta = np.array([np.linalg.eigvalsh(hessian[rows, :d, :d].mean(axis=0))
                        for rows in (slice(None), central)])
    positions = np.linalg.eigvalsh(hessian[:, d:, d:])
    typical = np.median(np.abs(positions))
    share = float(np.mean(positions[:, -1] < -MARGIN * typical)) if typical > 0 else 0.0
    scale = float(np.max(np.abs(np.linalg.eigvalsh(hessian.mean(axis=0)))))
    return momenta, share, scale


def warn_if_order_looks_swapped(model, states):
    """A :class:`~sk_hamiltonian.exceptions.StateOrderWarning` when ``H~`` looks like ``-H`` exchanged."""
    if states.shape[0] == 0:
        return
    momenta, share, scale = order_evidence(model, states)
    falls = np.all(momenta < -NEGATIVE * scale, axis=1)
    if not (scale > 0 and falls.any() and share >= SHARE):
        return
    given = getattr(model, "state_order", "pq")
    if given == "qp":
        # Exchanged on input, the columns were (p, q) already.
        fix = ("the columns look ordered (p, q), not (q, p) as state_order='qp' says: fit "
               "with state_order='pq'")
    else:
        fix = ("the states look ordered (q, p). Fit with state_order='qp' (the columns of X, "
               "and of y if given, are then read as (q_1..q_d, p_1..p_d), and outputs come "
               "back in that order)")
    warn(
        f"{type(model).__name__}: the learned H~ curves down in every momentum (its Hessian "
        f"in p, averaged over the training states, is negative definite) and in every "
        f"position, as a negated kinetic energy does: {fix}; if the order is right, check "
        f"that time runs forward and the momenta's sign, or ignore this StateOrderWarning "
        f"if H~ really has a maximum in p.",
        StateOrderWarning,
    )


# ----------------------------------------------------------------------------
# The ``state_order`` parameter: columns given as (q, p), exchanged at the edges.
#
# Inside, a model is always in (p_1..p_d, q_1..q_d) order: its fitted
# attributes, basis and integrators. With ``state_order="qp"`` the user's
# columns are (q_1..q_d, p_1..p_d); exchanging the two halves maps one order
# onto the other, and exchanging them twice is the identity, so the same
# function reorders inputs (user to model) and outputs (model to user).

#: The values of ``state_order``.
STATE_ORDERS = ("pq", "qp")
#: Which half of the columns comes first, in words, for messages.
ORDER_WORDS = {"pq": "momenta", "qp": "positions"}


def swap_halves(values, axis=-1):
    """``values`` with the two halves of ``axis`` exchanged (unchanged if it is odd).

    An odd width is no state of a Hamiltonian system; it is left to the
    validation that reports it with the argument's name.
    """
    values = np.asarray(values)
    n = values.shape[axis]
    if n % 2:
        return values
    return np.roll(values, n // 2, axis=axis)


def swap_names(names):
    """A list of ``2d`` names (or None) with its halves exchanged (unchanged if odd)."""
    if names is None:
        return None
    names = list(names)
    if len(names) % 2:
        return names
    d = len(names) // 2
    return names[d:] + names[:d]


def swap_layout(Xt):
    """The derivative layout ``[t | states | derivatives | observed]`` with each block's halves exchanged.

    A 3-D array stays one, a list stays a list of 2-D arrays. A last axis
    that is no layout of an even number of states is returned unchanged, for
    :func:`~sk_hamiltonian.unpack_derivatives` to report.
    """
    first = Xt[0] if isinstance(Xt, (list, tuple)) else Xt
    width = np.shape(first)[-1]
    n = (width - 1) // 3
    if width != 1 + 3 * n or n % 2:
        return Xt
    perm = np.roll(np.arange(n), n // 2)
    columns = np.concatenate([[0], 1 + perm, 1 + n + perm, 1 + 2 * n + perm])
    if isinstance(Xt, (list, tuple)):
        return [np.asarray(T)[:, columns] for T in Xt]
    return np.asarray(Xt)[..., columns]


def swap_couplings(couplings, n_states):
    """Groups of state indices in the user's order mapped to the model's (p, q) order.

    Index ``i`` of the user's columns is ``(i + d) % 2d`` in the model's.
    Anything that is not a group of in-range integers is returned as given,
    for :func:`~sk_hamiltonian._space.builder.build_space` to report.
    """
    if couplings is None or n_states % 2:
        return couplings
    d = n_states // 2
    try:
        groups = [[int(i) for i in group] for group in couplings]
    except (TypeError, ValueError):
        return couplings
    if any(i != j or not 0 <= i < n_states for group, given in zip(groups, couplings)
           for i, j in zip(group, given)):
        return couplings
    return [tuple((i + d) % n_states for i in group) for group in groups]


def swap_space(space, n_states):
    """A dict of per-state model-space parameters with its halves exchanged.

    ``periodic``, ``mixed`` and ``couplings`` between the user's column order
    and the model's ``(p, q)`` order (either way: the exchange is its own
    inverse); the other entries are returned as given.
    """
    space = dict(space)
    for key in ("periodic", "mixed"):
        if space.get(key) is not None and np.ndim(space[key]) == 1:
            swapped = swap_names(space[key])
            space[key] = swapped if isinstance(space[key], list) else np.asarray(swapped)
    if space.get("couplings") is not None:
        space["couplings"] = swap_couplings(space["couplings"], n_states)
    return space


def swap_raw(X, offset):
    """Raw trajectories (time stamps first when ``offset`` is 1) with their states' halves exchanged."""
    def swap(T):
        T = np.asarray(T)
        return np.concatenate([T[..., :offset], swap_halves(T[..., offset:])], axis=-1)

    if isinstance(X, (list, tuple)):
        return [swap(T) for T in X]
    return swap(X)


def swap_search_inputs(trajectories, domain, spaces, dt):
    """A search's raw trajectories, ``domain`` and ``spaces`` with the states' halves exchanged.

    For ``state_order="qp"``: the search runs in the model's ``(p, q)``
    order, with the per-state parameters exchanged alike.
    """
    n_states = trajectories[0].shape[1] - (1 if dt is None else 0)
    trajectories = swap_raw(trajectories, 1 if dt is None else 0)
    if domain is not None and np.ndim(domain) >= 1:
        domain = swap_halves(np.asarray(domain, dtype=float), axis=0)
    if spaces is not None:
        spaces = [swap_space(space, n_states) for space in spaces]
    return trajectories, domain, spaces
