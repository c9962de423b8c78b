"""Model spaces: 1-D families (Legendre, Fourier) combined over an index set.

One small module per idea: :mod:`.legendre` and :mod:`.fourier` are the 1-D
families, :mod:`.index_set` says which tensor products enter, :mod:`.tensor`
evaluates them (the hot path), :mod:`.contraction` and :mod:`.flat` contract
them with a model's coefficients (large spaces along a prefix tree, small
ones one product per function), :mod:`.gram` gives the closed-form Gram matrix
and the stability constant of the paper's Corollary 3.4, and
:class:`.ModelSpace` ties them to a box. :mod:`.builder` builds the space of
a regressor's parameters on its training data; :mod:`.compiled` and
:mod:`.kernel_tree` give a space to the compiled kernels as arrays.
"""

from .index_set import count_index_set, index_set
from .space import ModelSpace

__all__ = ["ModelSpace", "count_index_set", "index_set"]
