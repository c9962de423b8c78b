"""The system a fitted ``H~`` defines: ``dx/dt = J^{-1} grad H~(x)``, with the fitted friction.

What :class:`~sk_hamiltonian.HamiltonianRegressor` hands to evaluation and
to the integrators: its vector field and Jacobian, the compiled fast path of
``predict``, the split ``H~ = T(p) + V(q)`` that the explicit symplectic
methods need, the :class:`~sk_hamiltonian._integrate.Dynamics` of a
simulation, and the fields of the resampled refits. Each function takes the
fitted regressor first; the regressor's private methods call them.
"""

import numpy as np

from ._config import use_numba
from ._design import quadrature_nodes
from ._integrate import Dynamics
from ._integrate.compiled import KernelModel
from ._kernels import LANE_ROWS
from ._space import ModelSpace, compiled
from ._structure import apply_structure
from ._validation import DOMAIN_SLACK


def friction(model):
    """The friction to apply: ``damping_``, or None where it is zero."""
    return model.damping_ if model.damping_.any() else None


def vector_field(model, X):
    """The learned field at the rows of ``X`` (model order)."""
    if use_numba():
        # One compiled pass with the structure applied (zero damping is none).
        return compiled.field(model._eval_space, X, model._eval_coef, model.damping_)
    return apply_structure(model._gradient(X), friction(model))


def jacobian(model, X):
    """Jacobians of the learned field at the rows of ``X``."""
    # S applied to the first index of the Hessian.
    return apply_structure(np.swapaxes(model._hessian(X), 1, 2), friction(model)).swapaxes(1, 2)


def checked_prediction(model, X):
    """``(dXdt, n_outside)`` of a few states in one compiled call, or None for the general path."""
    # The compiled path takes a few states of a plain float64 array (what
    # _validate_states passes unchanged, finite or not) with every check in
    # one call; anything else, and any state that is not finite, goes the
    # general way.
    if not (use_numba() and type(X) is np.ndarray and X.dtype == np.float64 and X.ndim == 2
            and 0 < X.shape[0] < LANE_ROWS and X.shape[1] == model.n_features_in_
            and X.flags.c_contiguous and not hasattr(model, "feature_names_in_")):
        return None
    # The fitted attributes as fit left them (the kernel does not check
    # shapes: a domain_ or damping_ set by hand goes the general way).
    m = X.shape[1]
    coef, damping = model._eval_coef, model.damping_
    domain, periodic = model.domain_, model.periodic_
    if not (_plain(coef, (model._eval_space.n_terms,)) and _plain(damping, (m // 2,))
            and _plain(domain, (m, 2)) and _plain(periodic, (m,), np.bool_)):
        return None
    return compiled.checked_field(model._eval_space, X, coef, damping, domain, periodic,
                                  DOMAIN_SLACK)


def _plain(a, shape, dtype=np.float64):
    """Whether ``a`` is a C-ordered ndarray of this shape and dtype (as the kernels take it)."""
    return type(a) is np.ndarray and a.dtype == dtype and a.shape == shape and a.flags.c_contiguous


def separable_parts(model):
    """Spaces and coefficients of ``T(p)`` and ``V(q)``, or None for a model that is not separable.

    A fit in a general space whose kept terms each hold momenta only or
    positions only (``p^2/2 - 9.8 cos q``) is separable too: the explicit
    symplectic methods can integrate it.
    """
    d = model.n_features_in_ // 2
    powers, coef = model.powers_[model.support_], model.coef_[model.support_]
    on_p = np.any(powers[:, :d] != 0, axis=1)
    on_q = np.any(powers[:, d:] != 0, axis=1)
    if not (model.separable or np.all(~on_p | ~on_q)):
        return None
    parts = []
    for terms, variables in ((on_p, slice(0, d)), (~on_p, slice(d, 2 * d))):
        part = ModelSpace(
            model.domain_[variables], powers[terms][:, variables], model.periodic_[variables],
            model._mixed()[variables],
        )
        parts.append((part, coef[terms]))
    return parts


def dynamics(model):
    """The :class:`~sk_hamiltonian._integrate.Dynamics` the integrators simulate."""
    split = {}
    if model._split is not None:
        (kinetic, c_p), (potential, c_q) = model._split
        split = {
            "kinetic_gradient": lambda p: kinetic.gradient_dot(p, c_p),
            "potential_gradient": lambda q: potential.gradient_dot(q, c_q),
        }
    return Dynamics(
        model._vector_field, jacobian=model._jacobian,
        damping=friction(model), n_nodes=quadrature_nodes(model._eval_space),
        phase_rates=model._eval_space.phase_rates if model._eval_space.has_fourier else None,
        wrap=model._space.wrap if model.periodic_.any() else None, **split,
        compiled=KernelModel(
            "gradient", model._eval_space, model._eval_coef, friction(model), model._split
        ),
    )


def resampled_field(model, coef=None, damping=None):
    """``field(Y, models)``: the vector fields of the refits ``models`` at the rows of ``Y``.

    The refits are ``resampled_coef_`` (and ``resampled_damping_``), or
    the rows of ``coef`` (and ``damping``) when given.
    """
    if coef is None:
        coef, damping = model.resampled_coef_, getattr(model, "resampled_damping_", None)
    rows = np.any(coef != 0, axis=0)
    space = ModelSpace(model.domain_, model.powers_[rows], model.periodic_, model._mixed())
    coef = coef[:, rows]

    def field(Y, models):
        gradient = np.einsum("sij,sj->si", space.gradients(Y), coef[models])
        return apply_structure(gradient, None if damping is None else damping[models])

    return field
