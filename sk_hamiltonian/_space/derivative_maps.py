"""The gradient of a tensor basis as linear maps of a value basis.

Each 1-D family is closed under differentiation: ``P'_n = sum_k D[k, n] P_k``
over ``k < n`` (:func:`.legendre.legendre_derivative_matrix`), and the
derivative of a Fourier column is its partner of the same frequency
(:func:`.fourier.fourier_derivative_matrix`). So the derivative of a basis
function ``phi_j`` with respect to ``x_i`` is a combination of tensor products
``psi_l`` of the same families, over the multi-indices those derivatives
reach (the *value basis*)::

    d phi_j / d x_i = sum_l T_i[l, j] psi_l.

A design whose rows of variable ``i`` hold gradients is then ``A_i = B T_i``,
with ``B`` the values of ``psi`` at the same points and weights, and its
normal matrix is ``sum_i T_i^T (B^T B) T_i``: one Gram matrix of ``B``
instead of one per variable (:mod:`sk_hamiltonian._factored`). For a
total-degree set of degree ``n`` the value basis is the set of degree
``n - 1``, as large as the group of functions that depend on any one
variable, so the Gram matrices cost ``n_states`` times fewer multiply-adds.
"""

import numpy as np
from scipy import sparse

from scipy.linalg import block_diag

from .fourier import fourier_derivative_matrix, period_to_angle
from .legendre import interval_to_window, legendre_derivative_matrix


class DerivativeMaps:
    """The maps ``T_i`` of a model space's gradient onto its value basis.

    Parameters
    ----------
    space : ModelSpace
        The space whose gradient is mapped.

    Attributes
    ----------
    value_space : ModelSpace
        The value basis ``psi``: the same box and families, over the
        multi-indices the derivatives reach (sorted).
    maps_t : list of scipy.sparse.csr_array of shape (n_terms, n_values)
        ``T_i^T`` for each state variable ``i``, the chain rule of the box
        included.
    n_values : int
        Functions of the value basis.
    n_terms : int
        Functions of the mapped space.
    """

    def __init__(self, space):
        n_terms, n_states = space.columns.shape
        reached, entries, terms, variables = [], [], [], []
        for i in range(n_states):
            D = _derivative_matrix(space, i)
            for k, c in zip(*np.nonzero(D)):
                j = np.flatnonzero(space.columns[:, i] == c)
                columns = space.columns[j].copy()
                columns[:, i] = k
                reached.append(columns)
                entries.append(np.full(j.size, D[k, c]))
                terms.append(j)
                variables.append(np.full(j.size, i))
        if reached:
            reached, index = np.unique(np.concatenate(reached), axis=0, return_inverse=True)
            index = index.ravel()
        else:
            reached, index = np.zeros((0, n_states), dtype=np.intp), np.zeros(0, np.intp)
        entries, terms = np.concatenate(entries or [[]]), np.concatenate(terms or [[]])
        variables = np.concatenate(variables or [[]])
        self.n_values, self.n_terms = reached.shape[0], n_terms
        powers = space.codes_of_columns(reached)
        self.value_space = type(space)(space.domain, powers, space.periodic, space.mixed)
        self.maps_t = []
        for i in range(n_states):
            mine = variables == i
            self.maps_t.append(sparse.csr_array(
                (entries[mine], (terms[mine].astype(np.intp), index[mine])),
                shape=(n_terms, self.n_values),
            ))

    def pays(self, groups):
        """Whether one Gram matrix of the value basis costs less than one per group.

        Parameters
        ----------
        groups : list of ndarray of int
            The columns of each variable's rows in the grouped design
            (:func:`~sk_hamiltonian._design.column_groups`).
        """
        return self.n_values**2 < sum(g.size**2 for g in groups)


def _derivative_matrix(space, i):
    """``D`` with ``d f_c / d x_i = sum_k D[k, c] f_k`` for the columns of variable ``i``."""
    low, high = space.domain[i]
    if space.periodic[i]:
        _, scale = period_to_angle(low, low, high)
        return fourier_derivative_matrix(space.fourier_degree) * scale
    _, scale = interval_to_window(low, low, high)
    D = legendre_derivative_matrix(space.legendre_degree) * scale
    if space.mixed[i]:
        # Legendre columns first, then the Fourier ones without their
        # constant (the Legendre P_0); angle rate 1 (period 2 pi).
        trig = fourier_derivative_matrix(space.fourier_degree)[1:, 1:]
        D = block_diag(D, trig * space.factor_tables.mixed_rate)
    return D
