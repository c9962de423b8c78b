"""Mixed variables: Legendre polynomials and Fourier terms of one coordinate together.

A *mixed* variable ``x`` (a torsion pendulum's angle, say, whose potential
``k x**2 / 2 - g cos x`` is neither a short polynomial nor periodic) carries
both 1-D families: the Legendre polynomials of its interval (:mod:`.legendre`)
and the real Fourier terms ``cos(k x)``, ``sin(k x)`` of period ``2 pi``
(:mod:`.fourier`, measured from ``x = 0``, so that they are their own readable
form). A basis function takes one factor of one family per variable.

In a multi-index, the entry of a mixed variable is a *code*: ``a >= 0`` is the
Legendre degree ``a``; a negative code is a Fourier factor, minus its column in
the Fourier table (:func:`~.fourier.fourier_column`): ``-1`` is ``cos x``,
``-2`` is ``sin x``, ``-3`` is ``cos 2x``, and so on. A Fourier factor of
frequency ``k`` counts ``k`` toward a total degree, as for periodic variables.
In the factor table of a mixed variable, the Legendre columns ``0..L`` come
first and the Fourier columns follow, so code ``e < 0`` sits in column
``L - e``.
"""

import numpy as np

from .fourier import fourier_column, fourier_frequency

#: Period of the Fourier terms of a mixed variable.
MIXED_PERIOD = 2.0 * np.pi


def mixed_code(frequency):
    """Code of the Fourier factor of signed frequency ``frequency`` (``+k`` cos, ``-k`` sin)."""
    return -fourier_column(frequency)


def code_frequency(code):
    """Signed frequency of a mixed variable's code (0 for a Legendre code)."""
    code = np.asarray(code)
    return np.where(code < 0, fourier_frequency(-code), 0)


def factor_degrees(powers, mixed=None):
    """Degree of every factor of every multi-index: ``|entry|``, or the frequency of a code.

    Parameters
    ----------
    powers : ndarray of shape (n_terms, n_states)
        Multi-indices (signed frequencies for periodic variables, codes for
        mixed ones).
    mixed : ndarray of shape (n_states,) of bool, default=None
        Which variables are mixed; None: none.

    Returns
    -------
    degrees : ndarray of shape (n_terms, n_states)
    """
    powers = np.asarray(powers)
    degrees = np.abs(powers)
    if mixed is None or not np.any(mixed):
        return degrees
    trig = np.asarray(mixed, dtype=bool) & (powers < 0)
    return np.where(trig, np.abs(code_frequency(powers)), degrees)


def mixed_columns(codes, legendre_degree):
    """Table columns of the codes of a mixed variable (Legendre columns first)."""
    codes = np.asarray(codes)
    return np.where(codes < 0, legendre_degree - codes, codes)


def mixed_codes(columns, legendre_degree):
    """Codes of the table columns of a mixed variable; the inverse of :func:`mixed_columns`."""
    columns = np.asarray(columns)
    return np.where(columns > legendre_degree, legendre_degree - columns, columns)
