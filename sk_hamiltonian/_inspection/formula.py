"""The learned Hamiltonian as one line of text, with its intervals."""

import math
from numbers import Real

from .intervals import term_intervals
from .terms import hamiltonian_terms

def format_hamiltonian(model, *, state_names=None, max_terms=8, intervals=False):
    """The leading terms of a learned ``H~`` as one readable line.

    Parameters
    ----------
    model : HamiltonianRegressor
        A fitted model.
    state_names : list of str, default=None
        Names of the state variables, as in :func:`hamiltonian_terms`.
    max_terms : int, default=8
        How many terms to show; the rest are summarized.
    intervals : bool or float, default=False
        With a model fitted with ``fit_on="trajectories"`` or
        ``n_resamples > 0``: each coefficient is followed by ``(±h)``, half
        the width of its interval (:func:`term_intervals`: of the trajectory
        fit where there is one, else the percentile interval over the
        refits), at the level given (True: 0.9), and the coefficient is
        rounded to the interval's first digit; with refits, a term dropped by
        some says in how many it was kept, and terms the model dropped but
        some refits kept are listed after the formula, e.g. ``H~ = -9.795
        (±0.013) cos(q) + 0.5007 (±0.0007) p^2 + const; every term kept in
        100/100 resamples (90% intervals of the trajectory fit)``.

    Returns
    -------
    text : str
        ``"H~ = c1 t1 + c2 t2 + ... + const"``, terms in decreasing size.

    Raises
    ------
    ValueError
        With ``intervals`` and a model with neither a trajectory fit nor
        resampling.

    See Also
    --------
    hamiltonian_terms : The terms themselves.
    term_intervals : The intervals themselves.

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
    spread = None
    if intervals is not False and intervals is not None:
        level = 0.9 if intervals is True else intervals
        if isinstance(level, bool) or not (isinstance(level, Real) and 0 < level < 1):
            raise ValueError(
                f"intervals must be True (90% intervals), False, or a level in (0, 1); got "
                f"{intervals!r}."
            )
        spread = {t.powers: t for t in term_intervals(model, level=level,
                                                      state_names=state_names)}
    if not terms:
        return "H~ = const" + ("" if spread is None else _absent(spread.values(), set()))
    parts = []
    for term in terms[:max_terms]:
        sign = "-" if term.coefficient < 0 else "+"
        if spread is None:
            parts.append(f"{sign} {abs(term.coefficient):.4g} {term.text}")
            continue
        interval = spread[term.powers]
        value, half = _rounded(abs(term.coefficient), (interval.high - interval.low) / 2)
        kept = ("" if interval.n_kept == interval.n_resamples
                else f" [kept in {interval.n_kept}/{interval.n_resamples}]")
        parts.append(f"{sign} {value} (±{half}) {term.text}{kept}")
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
    text = "H~ = " + text + " + const"
    if spread is not None:
        source = (" of the trajectory fit"
                  if getattr(model, "coef_covariance_", None) is not None else "")
        text += _summary(spread, terms, level, source)
    return text


def _rounded(value, half):
    """``value`` to the first digit of ``half``, and ``half`` to one digit (six digits at most)."""
    if not half > 0:
        return f"{value:.6g}", "0"
    first = math.floor(math.log10(half))
    # Two digits of a half-width that starts with 1 (0.0016, not 0.002).
    first -= int(half < 2 * 10.0**first)
    digits = (math.floor(math.log10(value)) if value > 0 else first) - first + 1
    digits = min(max(digits, 1), 6)
    if 1e-4 <= value < 1e6:
        decimals = max(0, digits - 1 - math.floor(math.log10(value)))
        return f"{value:.{decimals}f}", _one_digit(half, first)
    return f"{value:.{digits}g}", _one_digit(half, first)


def _one_digit(half, first):
    """``half`` to the digit ``10**first``."""
    if -5 <= first < 6:
        return f"{round(half, -first):.{max(0, -first)}f}"
    return f"{half:.{2 if half < 2 * 10.0 ** (first + 1) else 1}g}"


def _summary(spread, terms, level, source):
    """What follows the formula: how often its terms were kept, which others were, and the intervals' source."""
    shown = {term.powers for term in terms}
    n = next(iter(spread.values())).n_resamples if spread else 0
    always = [t for t in terms if spread[t.powers].n_kept == n]
    if not n:
        kept = ""
    elif len(always) == len(terms):
        kept = f"; every term kept in {n}/{n} resamples"
    elif always:
        kept = f"; the others kept in {n}/{n} resamples"
    else:
        kept = ""
    return kept + _absent(spread.values(), shown) + f" ({level:.0%} intervals{source})"


def _absent(intervals, shown, most=3):
    """The terms some refits kept but the model did not, most often kept first."""
    others = sorted((t for t in intervals if t.powers not in shown and t.n_kept),
                    key=lambda t: -t.n_kept)
    if not others:
        return ""
    listed = ", ".join(f"{t.text} ({t.n_kept}/{t.n_resamples})" for t in others[:most])
    more = f" and {len(others) - most} more" if len(others) > most else ""
    return f"; not in H~ but kept in some resamples: {listed}{more}"


