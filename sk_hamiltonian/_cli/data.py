"""What the ``sk-hamiltonian`` command fits: the built-in example or a data file.

Trajectories too short for a derivative are dropped (with a note naming
them); records too few to fill the folds are cut into segments for blocked
cross-validation.
"""

import warnings

import numpy as np

from .._inspection.terms import check_state_names
from .._state_order import swap_names, swap_raw
from .._trajectories import check_trajectories
from ..datasets import PAPER_DT, make_trajectories, single_pendulum
from ..exceptions import OutlierWarning
from ..model_selection import segment_trajectories
from ..model_selection._prepare import MIN_PIECE_SAMPLES, prepare
from .datafiles import MIN_SAMPLES, load_trajectories
from .errors import UsageError, check_positive
from .words import counted

EXAMPLE = dict(n_trajectories=500, n_intervals=40, noise=0.08, horizon=20.0)
QUICK = dict(n_trajectories=60, n_intervals=40, noise=0.08, horizon=5.0)
# Segments of a record too long to cross-validate whole: the paper's
# trajectory length (one de-noising polynomial each with the default window),
# shortened so that every fold gets at least two segments.
SEGMENT_SAMPLES = 41


class Data:
    """What the command fits and reports on.

    ``X`` is what the pipeline gets (time stamps as first column when
    ``stamped``); ``times`` and ``states`` are the same trajectories split;
    ``dt`` is the transformer's step (None with time stamps), ``step`` the
    (median) sampling step; ``groups`` the CV groups of segments (or None);
    ``folds`` the held-out rows of each fold of the default search, once the
    data are prepared for it (:meth:`use_prepared`). ``horizon`` is the
    report's simulated span: the one given (the built-in example's), or ten
    times the median duration of the trajectories as they are now.
    """

    def __init__(self, X, names, ids, stamped, dt, title, system=None, horizon=None):
        self.X, self.names, self.ids, self.stamped = X, names, ids, stamped
        self.dt, self.title, self.system = dt, title, system
        self.groups = self.folds = None
        self.segmented = False
        # Kept apart so that cutting or preparing the data, which re-splits
        # them, does not replace a given horizon by one from the segments.
        self._given_horizon = horizon
        self._split()

    def _split(self):
        if self.stamped:
            self.times = [np.asarray(T)[:, 0] for T in self.X]
            self.states = [np.asarray(T)[:, 1:] for T in self.X]
        else:
            self.times = [self.dt * np.arange(len(T)) for T in self.X]
            self.states = [np.asarray(T) for T in self.X]
        steps = np.concatenate([np.diff(t) for t in self.times])
        self.step = self.dt if self.dt is not None else float(np.median(steps))
        # By default, ten times the median duration over all trajectories.
        self.horizon = self._given_horizon or 10.0 * float(np.median([t[-1] - t[0] for t in self.times]))

    def use_segments(self, segments, ids, groups):
        self.X, self.ids, self.groups = segments, ids, groups
        self._split()

    def use_prepared(self, prepared):
        """The search's data (:func:`~sk_hamiltonian.model_selection._prepare.prepare`) and its folds."""
        ids = []
        for k, start, stop in prepared.origin:
            whole = start == 0 and stop == len(self.times[k])
            ids.append(self.ids[k] if whole else f"{self.ids[k]}, samples {start}-{stop - 1}")
        self.X, self.ids = prepared.user_X, ids
        self.folds = prepared.folds
        self.segmented = prepared.report["segments"] is not None
        self.groups = None
        self._split()


def load_data(args):
    """The data to fit, with their names, title, true system (or None) and horizon.

    With ``--order qp`` the state columns (after any time stamps) and their
    names, the header's or ``--names`` (both in file order), are exchanged
    into ``(p, q)`` order, in which the command fits and reports.
    """
    data = _load_data(args)
    if getattr(args, "names", None):
        try:
            data.names = check_state_names(args.names, len(data.names), name="--names",
                                           order="in the order of the file's columns")
        except ValueError as error:
            raise UsageError(str(error)) from None
    if getattr(args, "order", "pq") == "qp":
        if args.data is None:
            raise UsageError(
                "--order qp says how DATA's columns are ordered; the built-in example is "
                "generated as p, q: drop --order, or give DATA")
        if len(data.names) % 2:
            raise UsageError(
                f"--order qp: the data have {len(data.names)} state columns; positions and "
                f"momenta come in pairs, so their number must be even")
        data.X = swap_raw(data.X, 1 if data.stamped else 0)
        data.names = swap_names(data.names)
        data._split()
        print(f"note: --order qp: columns read as positions, then momenta; fitted and "
              f"reported as {', '.join(data.names)}")
    return data


def _load_data(args):
    if args.data is None:
        setting = QUICK if args.quick else EXAMPLE
        dt = PAPER_DT if args.dt is None else args.dt
        check_positive("--dt", dt)
        system = single_pendulum()
        X = make_trajectories(
            system, setting["n_trajectories"], setting["n_intervals"], dt,
            noise=setting["noise"], random_state=args.seed,
        )
        title = (
            f"single pendulum (Example 1 of Wu, Qin & Xiu): "
            f"{counted(X.shape[0], 'trajectory', 'trajectories')} x "
            f"{X.shape[1]} samples, dt={dt:g}, +-{setting['noise']:.0%} noise"
        )
        return Data(
            X, ["p", "q"], [str(k) for k in range(len(X))], False, dt, title, system,
            setting["horizon"],
        )
    if args.dt is not None:
        check_positive("--dt", args.dt)
    loaded = load_trajectories(args.data)
    if loaded.stamped and args.dt is not None:
        raise UsageError(
            f"{args.data} carries time stamps; --dt would contradict them: drop --dt"
        )
    if not loaded.stamped and args.dt is None:
        raise UsageError(
            "--dt is required with a data file without time stamps: give the sampling "
            "step, e.g. --dt 0.01, or add the times (see --help)"
        )
    X, ids = _drop_short(loaded.trajectories, loaded.ids, args.data)
    lengths = [len(T) for T in X]
    span = f"{min(lengths)}" + (f"-{max(lengths)}" if max(lengths) > min(lengths) else "")
    data = Data(X, loaded.names, ids, loaded.stamped, args.dt, "")
    sampling = (
        f"dt={args.dt:g}" if not loaded.stamped
        else f"time stamps (median step {data.step:.4g})"
    )
    data.title = (
        f"{args.data}: {counted(len(lengths), 'trajectory', 'trajectories')} x {span} samples, "
        f"{len(loaded.names)} states, {sampling}"
    )
    return data


def _drop_short(X, ids, path):
    """Drop trajectories too short for any derivative estimate, saying which."""
    short = [k for k, T in enumerate(X) if len(T) < MIN_SAMPLES]
    if not short:
        return X, ids
    if len(short) == len(X):
        raise UsageError(
            f"{path}: every trajectory has fewer than {MIN_SAMPLES} samples; time "
            f"derivatives need at least {MIN_SAMPLES} per trajectory"
        )
    named = ", ".join(f"{ids[k]} ({len(X[k])} samples)" for k in short[:5])
    more = f" and {len(short) - 5} more" if len(short) > 5 else ""
    print(
        f"note: dropped {len(short)} of {len(X)} trajectories with fewer than {MIN_SAMPLES} "
        f"samples, from which no time derivative can be estimated: {named}{more}"
    )
    kept = [k for k in range(len(X)) if k not in set(short)]
    X = [X[k] for k in kept]
    if len({len(T) for T in X}) == 1:
        X = np.stack(X)
    return X, [ids[k] for k in kept]


def check_complete(args, data):
    """Refuse missing readings where the command does not run the default search's preparation."""
    broken = [label for label, T in zip(data.ids, data.X) if not np.isfinite(T).all()]
    if broken:
        option = "--paper-grid" if args.paper_grid else "--segment-length"
        raise UsageError(
            f"trajectories {', '.join(broken[:10])} hold missing readings (NaN or infinity): "
            f"{option} takes complete records; drop {option} (the default search leaves such "
            f"samples out and says which), or remove or interpolate them"
        )


def segment_if_needed(args, data):
    """Cut the trajectories into segments when they cannot fill the folds."""
    if len(data.X) >= args.cv:
        return data
    total = sum(len(T) for T in data.X)
    length = args.segment_length or min(SEGMENT_SAMPLES, total // (2 * args.cv))
    if length < MIN_SAMPLES or total // length < args.cv:
        raise UsageError(
            f"{len(data.X)} trajectories of {total} samples in all cannot fill {args.cv} "
            f"folds, even cut into segments of {max(length, MIN_SAMPLES)} samples: give more "
            f"data, a lower --cv or a shorter --segment-length"
        )
    segments, groups = segment_trajectories(data.X, length, n_groups=args.cv)
    ids = []
    for label, T in zip(data.ids, data.X):
        count = len(segment_trajectories([np.asarray(T)], length)[0])
        ids.extend(f"{label}, segment {k}" for k in range(count))
    n_records = len(data.X)
    data.use_segments(segments, ids, groups)
    longest = max(len(S) for S in segments)
    print(
        f"note: {n_records} {'trajectory' if n_records == 1 else 'trajectories'} cannot fill "
        f"{args.cv} folds: cut into {len(segments)} segments of {length} samples"
        + (f" (the last of a record up to {longest})" if longest > length else "")
        + "; blocked cross-validation, each fold holds out a contiguous stretch of segments"
    )
    return data


def prepare_for_search(args, data):
    """The default search's own preparation of the data, said in the command's words.

    Spikes and repeated trajectories are left out, a few long records cut
    into segments, exactly as :class:`~sk_hamiltonian.model_selection.HamiltonianSearchCV`
    does with ``cv=--cv``; ``data`` then holds the prepared trajectories and
    their folds, so that the command's search, resampling and refinement see
    what a Python user's search sees.
    """
    trajectories, _ = check_trajectories(data.X, min_times=MIN_SAMPLES, allow_missing=True)
    try:
        with warnings.catch_warnings():
            # What was left out is said below, in the command's words.
            warnings.simplefilter("ignore", OutlierWarning)
            prepared = prepare(trajectories, data.dt, args.cv, None)
    except ValueError as error:
        raise UsageError(" ".join(str(error).split()).replace("cv)", "--cv)")) from None
    report = prepared.report

    def named(indices):
        names = [data.ids[k] for k in sorted(indices)]
        return ", ".join(names[:10]) + (f" and {len(names) - 10} more" if len(names) > 10 else "")

    if report["missing"]:
        n = sum(len(v) for v in report["missing"].values())
        print(f"note: {counted(n, 'missing reading')} (NaN or infinite) in "
              f"{counted(len(report['missing']), 'trajectory', 'trajectories')}: "
              f"{named(report['missing'])}")
    if report["left_out"]:
        n = sum(len(v) for v in report["left_out"].values())
        print(f"note: left out {counted(n, 'sample')} of "
              f"{counted(len(report['left_out']), 'trajectory', 'trajectories')} as spikes"
              + (" or missing readings" if report["missing"] else "") + " (far "
              f"from their neighbours; each trajectory is cut there, and pieces of fewer than "
              f"{MIN_PIECE_SAMPLES} samples are left out with them): "
              f"{named(report['left_out'])}")
    if report["dropped"]:
        print(f"note: left out {counted(len(report['dropped']), 'trajectory', 'trajectories')} "
              f"made mostly of spikes: {named(report['dropped'])}")
    if report["duplicates"]:
        pairs = [f"{data.ids[k]} (= {data.ids[j]})" for k, j in sorted(report["duplicates"].items())]
        print(f"note: left out {counted(len(pairs), 'repeated trajectory', 'repeated trajectories')}: "
              f"{', '.join(pairs[:10])}" + (f" and {len(pairs) - 10} more" if len(pairs) > 10 else ""))
    if report["segments"] is not None:
        print(f"note: {report['segments']['rule']} (blocked cross-validation)")
    factor = report["momentum_scale"]
    if factor != 1.0:
        print(f"note: the {'positions' if factor > 1 else 'momenta'} spread about "
              f"{max(factor, 1 / factor):g} times more than the "
              f"{'momenta' if factor > 1 else 'positions'} (to the nearest power of ten): the "
              f"search compares its candidates with the momenta multiplied by {factor:g}, so "
              f"that the equations of both weigh alike, and fits the chosen terms in the "
              f"file's units")
    if report["clean"]:
        print("note: the data look exact (noise below 0.001% of every variable): finite "
              "differences, Simpson's pairs and the weak form only")
    data.use_prepared(prepared)
    return data
