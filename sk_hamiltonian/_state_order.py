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
    d = momenta.shape[1]
    example = ("X[..., ::-1]" if d == 1
               else f"np.concatenate([X[..., {d}:], X[..., :{d}]], axis=-1)")
    warn(
        f"{type(model).__name__}: the learned H~ curves down in every momentum (its Hessian "
        f"in p, averaged over the training states, is negative definite) and in every "
        f"position, as a negated kinetic energy does: the states look ordered (q, p). Pass "
        f"them as (p_1..p_d, q_1..q_d), here {example} (with derivatives y, reorder them "
        f"the same way); if they are in that order, check that time runs forward and the "
        f"momenta's sign, or ignore this StateOrderWarning if H~ really has a maximum in p.",
        StateOrderWarning,
    )
