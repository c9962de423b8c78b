"""The default search on scenes, record shapes and noise the robustness study does not hold.

Each row: ``HamiltonianSearchCV(dt=dt).fit(X)`` with its defaults on records
that start at uniform states of the scene's box below an energy, noise
Gaussian (``add``: that fraction of each variable's root-mean-square;
``mult``: each sample times ``1 + level z``); the law it prints, whether it
keeps the scene's exact terms (``-`` where the law is in none of the search's
spaces), stage 3's verdict, and the median relative state error at
``T = 20`` from 50 fresh states of the same box and energies (``inf`` where
a simulation fails). CPU seconds of the search, BLAS on one thread::

    python benchmarks/outside_scenes.py                     # every row below
    python benchmarks/outside_scenes.py --scenes softening --seeds 11 12
    python benchmarks/outside_scenes.py --scenes exponential --by-hand
    python benchmarks/outside_scenes.py --scenes small_angles --splits 5
    python benchmarks/outside_scenes.py --scenes small_angles --stamps
    python benchmarks/outside_scenes.py --scenes stiff --units 1000 1
    python benchmarks/outside_scenes.py --scenes softening cubic --dt 0.5

With ``--splits N``, each case is also searched with ``cv=KFold(5,
shuffle=True, random_state=r)`` for ``r = 1 .. N`` (rows marked ``split r``),
and a last line per case says whether every split kept the same terms.

With ``--stamps``, each record is sampled at times of its own: its steps
``dt`` times a uniform factor in ``[0.6, 1.4]``, the time stamps in the
first column and the search given ``dt=None`` (a lab clock's stamps).

With ``--units P Q``, every momentum is multiplied by ``P`` and every
position by ``Q`` (records in other units: ``1 1000`` reads the positions in
thousandths); the model is simulated in those units and its error measured
back in the scene's own.

With ``--dt DT``, every record is sampled every ``DT`` instead of the
scene's step (the same number of samples, so over a longer time).

With ``--by-hand``, the scenes whose law is in none of the spaces are also
fitted as the paper does, by a polynomial of one degree (8, then 10) on
finite-difference derivatives, and its error printed beside the search's.

The scenes (``p`` the momentum, ``q`` the position):

* ``small_angles``: the paper's pendulum ``p^2/2 - 9.8 cos q`` below
  ``H = 5`` (angles within 1.3 rad), ``dt = 0.02``: its Taylor series and
  its law are nearly collinear;
* ``softening``: ``p^2/2 + q^2/2 - q^4/8`` (a softening Duffing spring, whose
  series looks like a pendulum's), below ``H = 0.4``;
* ``cubic``: ``p^2/2 + q^2/2 - q^3/3`` below ``H = 0.13`` (the well's rim is
  at 1/6);
* ``quartic``: ``p^2/2 + q^4/4``;
* ``mass``: ``(1 + q^2) p^2/2 + q^2/2``, a mass that depends on the position;
* ``anisotropic``: ``(p1^2 + p2^2)/2 + q1^2/2 + q2^2 + 0.3 q1 q2``;
* ``pendulum_spring``: ``p^2/2 - 2 cos q + q^2/2``, a pendulum with a spring,
  below ``H = 1.5`` (angles within 1.1 rad): its exact law mixes ``cos q``
  and ``q^2``, and its Taylor series ``q^2, q^4`` keeps as many terms;
* ``tilted``: ``p^2/2 - cos q - 0.3 q``, a pendulum under a constant torque,
  below ``H = -0.2`` (under the barrier at ``q = 2.84``);
* ``top``: the paper's pendulum as an angle measured from the top reads it,
  ``p^2/2 + 9.8 cos q`` with ``q`` within 1.3 of ``pi``, below ``H = -4.8``,
  ``dt = 0.02``: the search's models wrap an angle into ``[-pi, pi)``, so the
  error takes angle differences modulo ``2 pi`` for the model's periodic
  variables (as it does wherever a model is periodic);
* ``torsion_top``: a torsion pendulum about its top, ``p^2/2 + 2 cos q + (q -
  pi)^2/2`` below ``H = -0.5`` (``q`` within 1.0 of ``pi``): in the data's
  chart its law is ``cos q, q^2, q`` and its Taylor series holds odd powers;
* ``harmonics``: ``p^2/2 - cos q - cos(2 q)/2``, two harmonics, below
  ``H = 0.3`` (angles within 1.4 rad);
* ``offset``: a hardening spring about ``q = 2``, ``p^2/2 + (q - 2)^2/2 +
  (q - 2)^4/4`` below ``H = 0.8``: in the data's chart its law is ``q, q^2,
  q^3, q^4``;
* ``stiff``: ``2 p^2 + 8 q^2 + 2 q^4`` (a mass of 1/4, a period of 0.8),
  ``dt = 0.01``, below ``H = 0.6``;
* ``separatrix``: the paper's pendulum below ``H = 14``, librations and
  rotations over the top (the separatrix at ``9.8``), ``dt = 0.02``;
* ``kinetic_coupling``: ``(p1^2 + p2^2)/2 + 0.3 p1 p2 + q1^2/2 + q2^2``, momenta
  coupled in the kinetic energy, below ``H = 1``;
* ``quartic_coupling``: ``(p1^2 + p2^2)/2 + (q1^2 + q2^2)/2 + q1^2 q2^2/2`` below
  ``H = 1``;
* ``morse``: ``p^2/2 + (1 - exp(-q))^2`` below ``H = 0.5``, in none of the spaces;
* ``exponential``: the paper's ``exp(-p^2 - 1.1 q^4)``, in none of the spaces.
"""

import argparse
import os
import sys
import time
import warnings
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from sklearn.model_selection import KFold  # noqa: E402
from sklearn.pipeline import Pipeline  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor  # noqa: E402
from sk_hamiltonian.datasets import HamiltonianSystem, exponential, single_pendulum  # noqa: E402
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms  # noqa: E402
from sk_hamiltonian.model_selection import HamiltonianSearchCV  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness_study import noise_of  # noqa: E402
from search_study import T_END, model_error  # noqa: E402

SHAPES = {"many": (200, 41), "few": (5, 801), "one": (1, 4001), "four": (4, 1001),
          "one3": (1, 3001), "two": (2, 2001), "three": (3, 1501), "twenty": (20, 201)}
# Each step of a record sampled by --stamps: dt times a factor within this of 1.
JITTER = 0.4


def one_degree(name, potential, force, box, law):
    """``H = p^2/2 + V(q)``; ``force`` is ``V'``."""
    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        return X[..., 0] ** 2 / 2 + potential(X[..., 1])

    def gradient(X):
        X = np.asarray(X, dtype=float)
        return np.stack([X[..., 0], force(X[..., 1])], axis=-1)

    return HamiltonianSystem(name, hamiltonian, gradient, domain=box,
                             initial_state=[0.3, 0.5]), law


def mass():
    def hamiltonian(X):
        p, q = np.asarray(X, dtype=float)[..., 0], np.asarray(X, dtype=float)[..., 1]
        return (1 + q**2) * p**2 / 2 + q**2 / 2

    def gradient(X):
        p, q = np.asarray(X, dtype=float)[..., 0], np.asarray(X, dtype=float)[..., 1]
        return np.stack([(1 + q**2) * p, q * p**2 + q], axis=-1)

    return (HamiltonianSystem("mass", hamiltonian, gradient, domain=[[-1, 1], [-1, 1]],
                              initial_state=[0.3, 0.5]), {"p^2", "q^2", "p^2*q^2"})


def anisotropic():
    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        return ((X[..., 0] ** 2 + X[..., 1] ** 2) / 2 + X[..., 2] ** 2 / 2 + X[..., 3] ** 2
                + 0.3 * X[..., 2] * X[..., 3])

    def gradient(X):
        X = np.asarray(X, dtype=float)
        return np.stack([X[..., 0], X[..., 1], X[..., 2] + 0.3 * X[..., 3],
                         2 * X[..., 3] + 0.3 * X[..., 2]], axis=-1)

    return (HamiltonianSystem("anisotropic", hamiltonian, gradient, domain=[[-1, 1]] * 4,
                              initial_state=[0.3, 0.2, 0.5, 0.1]),
            {"p1^2", "p2^2", "q1^2", "q2^2", "q1*q2"})


def two_degrees(name, hamiltonian, gradient, law):
    """A system of ``(p1, p2, q1, q2)``; ``gradient`` returns the four partial derivatives."""
    def h(X):
        X = np.asarray(X, dtype=float)
        return hamiltonian(*(X[..., i] for i in range(4)))

    def g(X):
        X = np.asarray(X, dtype=float)
        return np.stack(gradient(*(X[..., i] for i in range(4))), axis=-1)

    return (HamiltonianSystem(name, h, g, domain=[[-1.2, 1.2]] * 4,
                              initial_state=[0.3, 0.2, 0.5, 0.1]), law)


def stiff():
    def hamiltonian(X):
        X = np.asarray(X, dtype=float)
        return 2 * X[..., 0] ** 2 + 8 * X[..., 1] ** 2 + 2 * X[..., 1] ** 4

    def gradient(X):
        X = np.asarray(X, dtype=float)
        return np.stack([4 * X[..., 0], 16 * X[..., 1] + 8 * X[..., 1] ** 3], axis=-1)

    return (HamiltonianSystem("stiff", hamiltonian, gradient, domain=[[-2.5, 2.5], [-0.6, 0.6]],
                              initial_state=[0.3, 0.2]), {"p^2", "q^2", "q^4"})


# name: (system and its terms, energy bound, dt, cases as (shape, noise) pairs)
SCENES = {
    "small_angles": ((single_pendulum(), {"p^2", "cos(q)"}), 5.0, 0.02,
                     [("four", "add2"), ("one3", "add2"), ("one3", "mult2")]),
    "softening": (one_degree("softening", lambda q: q**2 / 2 - q**4 / 8, lambda q: q - q**3 / 2,
                             [[-1.2, 1.2], [-1.2, 1.2]], {"p^2", "q^2", "q^4"}), 0.4, 0.05,
                  [("many", "add2"), ("few", "add2"), ("one3", "mult2")]),
    "cubic": (one_degree("cubic", lambda q: q**2 / 2 - q**3 / 3, lambda q: q - q**2,
                         [[-0.6, 0.6], [-0.8, 0.9]], {"p^2", "q^2", "q^3"}), 0.13, 0.05,
              [("many", "add2"), ("few", "add2"), ("one", "add2")]),
    "quartic": (one_degree("quartic", lambda q: q**4 / 4, lambda q: q**3,
                           [[-1.5, 1.5], [-1.5, 1.5]], {"p^2", "q^4"}), 1.5, 0.05,
                [("many", "add2"), ("few", "add2"), ("one", "add2")]),
    "mass": (mass(), 1.0, 0.05, [("many", "add2"), ("few", "add2"), ("one", "add2")]),
    "anisotropic": (anisotropic(), 1.0, 0.05,
                    [("many", "add2"), ("few", "add2"), ("one", "add2")]),
    "pendulum_spring": (one_degree("pendulum_spring", lambda q: q**2 / 2 - 2 * np.cos(q),
                                   lambda q: q + 2 * np.sin(q), [[-2.5, 2.5], [-2.5, 2.5]],
                                   {"p^2", "q^2", "cos(q)"}), 1.5, 0.05,
                        [("many", "add2"), ("many", "add8"), ("many", "mult2"), ("few", "add2"),
                         ("two", "add2")]),
    "tilted": (one_degree("tilted", lambda q: -np.cos(q) - 0.3 * q, lambda q: np.sin(q) - 0.3,
                          [[-2, 2], [-1.5, 2.0]], {"p^2", "cos(q)", "q"}), -0.2, 0.05,
               [("many", "add2"), ("few", "add2"), ("many", "mult2")]),
    "top": (one_degree("top", lambda q: 9.8 * np.cos(q), lambda q: -9.8 * np.sin(q),
                       [[-4, 4], [np.pi - 1.3, np.pi + 1.3]], {"p^2", "cos(q)"}), -4.8, 0.02,
            [("many", "add2"), ("four", "add2")]),
    "torsion_top": (one_degree("torsion_top", lambda q: 2 * np.cos(q) + (q - np.pi) ** 2 / 2,
                               lambda q: (q - np.pi) - 2 * np.sin(q),
                               [[-2.5, 2.5], [np.pi - 2.5, np.pi + 2.5]],
                               {"p^2", "cos(q)", "q^2", "q"}), -0.5, 0.05,
                    [("many", "add2"), ("few", "add2")]),
    "harmonics": (one_degree("harmonics", lambda q: -np.cos(q) - np.cos(2 * q) / 2,
                             lambda q: np.sin(q) + np.sin(2 * q), [[-3, 3], [-np.pi, np.pi]],
                             {"p^2", "cos(q)", "cos(2 q)"}), 0.3, 0.05,
                  [("many", "add2"), ("few", "add2"), ("many", "mult2")]),
    "offset": (one_degree("offset", lambda q: (q - 2) ** 2 / 2 + (q - 2) ** 4 / 4,
                          lambda q: (q - 2) + (q - 2) ** 3, [[-1.5, 1.5], [0.5, 3.5]],
                          {"p^2", "q", "q^2", "q^3", "q^4"}), 0.8, 0.05,
               [("many", "add2"), ("few", "add2"), ("two", "add2"), ("four", "add2"),
                ("many", "mult2"), ("one", "add2")]),
    "stiff": (stiff(), 0.6, 0.01, [("many", "add2"), ("one", "add2")]),
    "separatrix": (one_degree("separatrix", lambda q: -9.8 * np.cos(q), lambda q: 9.8 * np.sin(q),
                              [[-7, 7], [-np.pi, np.pi]], {"p^2", "cos(q)"}), 14.0, 0.02,
                   [("many", "add2")]),
    "kinetic_coupling": (two_degrees(
        "kinetic_coupling",
        lambda p1, p2, q1, q2: (p1**2 + p2**2) / 2 + 0.3 * p1 * p2 + q1**2 / 2 + q2**2,
        lambda p1, p2, q1, q2: (p1 + 0.3 * p2, p2 + 0.3 * p1, q1, 2 * q2),
        {"p1^2", "p2^2", "p1*p2", "q1^2", "q2^2"}), 1.0, 0.05,
        [("many", "add2"), ("few", "add2"), ("three", "add2")]),
    "quartic_coupling": (two_degrees(
        "quartic_coupling",
        lambda p1, p2, q1, q2: (p1**2 + p2**2) / 2 + (q1**2 + q2**2) / 2 + q1**2 * q2**2 / 2,
        lambda p1, p2, q1, q2: (p1, p2, q1 + q1 * q2**2, q2 + q1**2 * q2),
        {"p1^2", "p2^2", "q1^2", "q2^2", "q1^2*q2^2"}), 1.0, 0.05,
        [("many", "add2"), ("few", "add2"), ("twenty", "mult2")]),
    "morse": (one_degree("morse", lambda q: (1 - np.exp(-q)) ** 2,
                         lambda q: 2 * (1 - np.exp(-q)) * np.exp(-q),
                         [[-1, 1], [-0.5, 1.5]], None), 0.5, 0.05,
              [("many", "add2"), ("few", "add2")]),
    "exponential": ((exponential(), None), 10.0, 0.05, [("many", "add2"), ("few", "add2")]),
}


def states_below(system, energy, n, rng):
    """``n`` uniform states of the system's box below ``energy``."""
    box = np.asarray(system.domain, dtype=float)
    found = []
    while len(found) < n:
        x = rng.uniform(box[:, 0], box[:, 1], size=(256, box.shape[0]))
        found.extend(x[system.hamiltonian(x) < energy])
    return np.array(found[:n])


def records(system, energy, dt, shape, noise, seed, stamps=False, units=(1.0, 1.0)):
    """Noisy records; with ``stamps``, each at times of its own, the times in the first column.

    ``units``: the factors of the momenta and of the positions.
    """
    n, length = SHAPES[shape]
    rng = np.random.default_rng(seed)
    x0 = states_below(system, energy, n, rng)
    if stamps:
        times = np.cumsum(dt * (1 + JITTER * rng.uniform(-1, 1, (n, length))), axis=1)
        times -= times[:, :1]
        X = np.stack([system.solve(x[None], t, max_step=dt / 10)[0] for x, t in zip(x0, times)])
    else:
        X = system.solve(x0, dt * np.arange(length), max_step=dt / 10)
    kind, level = noise_of(noise)
    if kind == "mult":
        X = X * (1 + level * rng.standard_normal(X.shape))
    else:
        scale = np.sqrt(np.mean(X.reshape(-1, X.shape[-1]) ** 2, axis=0))
        X = X + level * scale * rng.standard_normal(X.shape)
    X = X * np.repeat(np.asarray(units, dtype=float), X.shape[-1] // 2)
    return np.concatenate([times[..., None], X], axis=2) if stamps else X


class InUnits:
    """A model of records in other units, simulated from and back to the scene's own."""

    def __init__(self, model, factors):
        self.model, self.factors = model, factors
        self.periodic_ = model.periodic_

    def simulate(self, x0, t, **options):
        return self.model.simulate(x0 * self.factors, t, **options) / self.factors


def fresh_error(model, system, energy):
    """The median relative state error at ``T_END`` from 50 fresh states below ``energy``.

    The model's periodic variables come out wrapped into their period: their
    differences are taken modulo ``2 pi``.
    """
    x0 = states_below(system, energy, 50, np.random.default_rng(99))
    truth = system.solve(x0, [0.0, T_END], max_step=0.01)[:, -1]
    return model_error(model, x0, truth, angles=list(np.flatnonzero(model.periodic_)))


def by_hand(system, energy, dt, X):
    """The errors of polynomials of degree 8 and 10 on finite differences."""
    errors = []
    for degree in (8, 10):
        pipe = Pipeline([("derivativetransformer", DerivativeTransformer(dt=dt)),
                         ("hamiltonianregressor", HamiltonianRegressor(degree=degree))])
        with threadpool_limits(1), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pipe.fit(X)
        errors.append(f"degree {degree} {fresh_error(pipe[-1], system, energy):.3g}")
    return ", ".join(errors)


def run(name, shape, noise, seed, hand=False, split=None, stamps=False, units=(1.0, 1.0),
        dt=None):
    """Search one case and print its row; returns the kept terms."""
    (system, law), energy, scene_dt, _ = SCENES[name]
    dt = scene_dt if dt is None else dt
    X = records(system, energy, dt, shape, noise, seed, stamps, units)
    cv = 5 if split is None else KFold(5, shuffle=True, random_state=split)
    start = time.process_time()
    with threadpool_limits(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        search = HamiltonianSearchCV(dt=None if stamps else dt, cv=cv).fit(X)
    seconds = time.process_time() - start
    model = search.best_estimator_[-1]
    kept = {term.text for term in hamiltonian_terms(model)}
    exact = "-" if law is None else str(kept == law)
    judgement = search.judgement_
    verdict = "-" if judgement is None else (
        f"{judgement['kind']}, best {judgement['best']}"
        + (f", pruned {judgement['pruned']}" if judgement.get("pruned") else ""))
    folds = ("" if split is None else f"split {split}  ") + ("stamped  " if stamps else "")
    if dt != scene_dt:
        folds += f"dt {dt:g}  "
    if tuple(units) != (1.0, 1.0):
        factor = search.preparation_.get("momentum_scale", 1.0)  # 1.0 before it existed
        folds += f"units p*{units[0]:g} q*{units[1]:g} (momenta x {factor:.3g})  "
    factors = np.repeat(np.asarray(units, dtype=float), X.shape[-1] // 2 if not stamps
                        else (X.shape[-1] - 1) // 2)
    print(f"{name:12s} {shape:5s} {noise:6s} seed {seed:3d}  {folds}cpu {seconds:5.1f} s  "
          f"exact {exact:5s}  error {fresh_error(InUnits(model, factors), system, energy):.3g}  "
          f"[{verdict}]  {format_hamiltonian(model)}", flush=True)
    if hand and law is None and not stamps:
        print(f"{'':12s} by hand: {by_hand(system, energy, dt, X)}", flush=True)
    return kept


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--seeds", nargs="+", type=int, default=[11, 12, 13, 14])
    parser.add_argument("--by-hand", action="store_true",
                        help="also polynomials of degree 8 and 10 where no space holds the law")
    parser.add_argument("--splits", type=int, default=0,
                        help="also search each case under this many shuffled 5-fold splits")
    parser.add_argument("--stamps", action="store_true",
                        help="records sampled at jittered times of their own (dt=None)")
    parser.add_argument("--units", nargs=2, type=float, default=(1.0, 1.0), metavar=("P", "Q"),
                        help="multiply every momentum by P and every position by Q")
    parser.add_argument("--dt", type=float, default=None,
                        help="sample every record every DT instead of the scene's step")
    args = parser.parse_args()
    for name in args.scenes:
        for shape, noise in SCENES[name][3]:
            for seed in args.seeds:
                laws = [run(name, shape, noise, seed, hand=args.by_hand, stamps=args.stamps,
                            units=args.units, dt=args.dt)]
                laws += [run(name, shape, noise, seed, split=r, stamps=args.stamps,
                             units=args.units, dt=args.dt)
                         for r in range(1, args.splits + 1)]
                if args.splits:
                    same = all(kept == laws[0] for kept in laws)
                    print(f"{name:12s} {shape:5s} {noise:6s} seed {seed:3d}  "
                          f"the same terms under all {len(laws)} fold splits: {same}", flush=True)


if __name__ == "__main__":
    main()
