"""Errors and warnings raised by sk_hamiltonian."""


class SimulationError(RuntimeError):
    """A trajectory could not be continued.

    The state became non-finite (the model or the reference system blew up), or
    an implicit step could not be solved. The message gives the time at which it
    happened and how to avoid it.

    Parameters
    ----------
    message : str
        What failed, when, and how to avoid it.
    t_reached : float, default=nan
        The last output time every trajectory reached.
    t_failed : float, default=nan
        The first output time some trajectory could not reach.
    failed_at : ndarray of shape (n_initial,), default=None
        Per initial state, the index of the first output time not reached.

    Attributes
    ----------
    t_reached : float
        The last output time every trajectory reached.
    t_failed : float
        The first output time some trajectory could not reach.
    failed_at : ndarray of shape (n_initial,)
        For each initial state, the index into the output times of the first one
        it could not reach, or ``n_times`` if it reached them all.
    """

    def __init__(self, message, *, t_reached=float("nan"), t_failed=float("nan"), failed_at=None):
        super().__init__(message)
        self.t_reached = t_reached
        self.t_failed = t_failed
        self.failed_at = failed_at


class DomainWarning(UserWarning):
    """Points lie outside the box the model was fitted on.

    A polynomial model is only trusted inside its domain; outside, Legendre
    polynomials grow like ``|x|**degree`` and predictions degrade quickly.
    Also raised when ``predict`` or ``hamiltonian`` return NaN or inf: the
    states are so large that the learned polynomial overflows float64; the
    message names the rows of ``X``.
    """


class IllConditionedWarning(UserWarning):
    """The least-squares problem is close to singular.

    Usually the data do not cover the domain (for example a few long trajectories
    in a high-degree space); more trajectories, a smaller ``domain`` or a lower
    ``degree`` help. Also raised by
    :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV` when every
    trajectory lies on one level of the chosen law's energy (one record, or
    records all at one energy): such data determine the law only on that
    level, ``H`` and ``H + (H - E)^2 g`` agree there for any ``g``. The
    search prefers few terms among laws that explain the data alike, which
    does not make the law it keeps the true one (one record of ``p^2/2 +
    p^4/4 + q^2/2`` kept six terms in ``p^2`` and powers of ``q``, right on
    the recorded level and wrong off it); trajectories at other energies pin
    it down.
    """


class ConservationWarning(UserWarning):
    """The learned energy trends along the training trajectories.

    A conservative model fitted to data whose learned energy ``H~`` rises or
    falls along the trajectories: the data look dissipative or driven, and
    ``HamiltonianRegressor(damping=True)`` may fit them better. Also raised
    when a fitted damping is not backed by a loss of energy in the data.
    """


class SmoothingWarning(UserWarning):
    """The de-noising polynomials cannot follow the trajectories.

    Raised by :class:`~sk_hamiltonian.DerivativeTransformer` when the
    residuals of its least-squares polynomials in time are far above the noise
    level estimated from the data: each polynomial spans too much of a
    trajectory for its degree, and the derivatives it gives are biased. A
    smaller ``window`` or a larger ``degree`` helps.

    Parameters
    ----------
    message : str
        How far above the noise, and what to do.
    ratio : float, default=nan
        The residuals' root-mean-square over the noise level's (``inf`` where
        the noise level is zero), for the worst state variable.

    Attributes
    ----------
    ratio : float
        As given.

    Examples
    --------
    >>> import warnings
    >>> from sk_hamiltonian import SmoothingWarning
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn(SmoothingWarning("residuals 41 times above ...", ratio=41.0))
    >>> caught[0].message.ratio
    41.0
    """

    def __init__(self, message, ratio=float("nan")):
        super().__init__(message)
        self.ratio = float(ratio)


class StateOrderWarning(UserWarning):
    """The states look ordered ``(q, p)`` rather than ``(p_1..p_d, q_1..q_d)``.

    Raised after a :class:`~sk_hamiltonian.HamiltonianRegressor` fit whose
    learned ``H~`` curves down in every momentum (its Hessian in ``p``,
    averaged over the training states, is negative definite), where a
    kinetic energy grows, and in every position at nearly every state, as a
    negated kinetic energy does: what data in ``(q, p)`` order give (``-H``
    with the halves exchanged), and data whose time runs backwards or whose
    momenta have the wrong sign. Fit with ``state_order="qp"``, which reads
    the columns as ``(q_1..q_d, p_1..p_d)`` and returns outputs in that order
    (after a fit with ``state_order="qp"`` on data already in ``(p, q)``
    order, the warning says to use ``"pq"``).
    """


class OutlierWarning(UserWarning):
    """Some trajectories lie far outside the rest.

    Raised after a fit on trajectories when a few of them leave residuals far
    above the others (by :class:`~sk_hamiltonian.HamiltonianRegressor` and
    :class:`~sk_hamiltonian.VectorFieldRegressor`: their derivatives disagree
    with the learned field; by :class:`~sk_hamiltonian.DerivativeTransformer`:
    the de-noising polynomials cannot follow them). Such trajectories are
    often corrupt (reversed in time, spiky, from another system), but may be
    sound and where the model fits worst (the highest energies, near a
    separatrix); inspect them, and drop or repair those that are corrupt.
    The message names them by their index in the X the fit was given, and
    so does the attribute ``trajectories``: inside a cross-validation fold
    (e.g. :class:`~sklearn.model_selection.GridSearchCV`) that X is the
    fold's subset of the user's, so the indices are not the user's.

    Parameters
    ----------
    message : str
        Which trajectories, why, and what to do.
    trajectories : sequence of int, default=()
        Their indices in the X the fit was given.

    Attributes
    ----------
    trajectories : tuple of int
        The indices of the outlying trajectories.

    Examples
    --------
    >>> import warnings
    >>> from sk_hamiltonian import OutlierWarning
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     warnings.warn(OutlierWarning("trajectories [3] ...", trajectories=[3]))
    >>> caught[0].message.trajectories
    (3,)
    """

    def __init__(self, message, trajectories=()):
        super().__init__(message)
        self.trajectories = tuple(int(k) for k in trajectories)
