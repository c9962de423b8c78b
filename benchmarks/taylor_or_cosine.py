"""Can long records of the coupled pendula tell their cosine law from its Taylor series?

From few (5 x 801) or one (1 x 4001) long record at 2 % additive noise, the
default search kept a 7-term Taylor polynomial of the coupled pendula
(``robustness_study.py``'s ``coupled_pendula`` scene, record shapes ``few``
and ``one``) until its stage 3 offered the cosine law itself (since
2026-12-07). This script, the measurement behind that offer, asks whether the
data can tell the exact law (as many terms) from the Taylor series with an
oracle's terms, outside the search: for each record shape and seed,

1. whether the mixed space at polynomial degree 2, thresholded on the noisy
   records (de-noising degree 5 or 8, derivatives or weak form, threshold
   0.01 or 0.03), keeps exactly the true terms;
2. the default search's choice (``HamiltonianSearchCV(dt=0.05)``; the Taylor
   series before the offer, the cosine law on most runs since);
3. the exact law's terms, found as an oracle: the mixed space at polynomial
   degree 2 thresholded on the *noise-free* records (the first threshold of
   0.01 ... 0.1 that keeps exactly the true terms; none on some seeds);
4. both sets of terms fitted to the raw trajectories and weighed by the
   search's own judgement of finalists
   (:func:`sk_hamiltonian.model_selection._finalists.judge_supports`: output
   error under the data's noise model, then BIC), and each refined as the
   search refines its choice, with its T = 20 error (the study's).

Run::

    python benchmarks/taylor_or_cosine.py            # few and one, seeds 0-2
    python benchmarks/taylor_or_cosine.py --supports-only   # step 1 alone, a minute
"""

import argparse
import copy
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from sklearn.pipeline import make_pipeline

from sk_hamiltonian import DerivativeTransformer, HamiltonianRegressor
from sk_hamiltonian.inspection import format_hamiltonian, hamiltonian_terms
from sk_hamiltonian.model_selection import HamiltonianSearchCV
from sk_hamiltonian.model_selection._judgement import judge_supports
from sk_hamiltonian.model_selection._refine import refine_on_trajectories

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness_study import SCENES, model_error, scene_data

NAME = "coupled_pendula"
DT = SCENES[NAME]["dt"]


def mixed_fit(X, threshold, denoise=5, fit_on="derivatives"):
    """The mixed space at polynomial degree 2, thresholded, fitted to records ``X``."""
    return make_pipeline(
        DerivativeTransformer(dt=DT, degree=denoise),
        HamiltonianRegressor(degree=2, mixed=[False, False, True, True], momentum_degree=2,
                             threshold=threshold, fit_on=fit_on),
    ).fit(list(X))[-1]


def keeps_exact_terms(model):
    return {term.text for term in hamiltonian_terms(model)} == SCENES[NAME]["terms"]


def exact_terms_model(clean):
    """The exact law's terms fitted to noise-free records, or None if no threshold finds them."""
    for threshold in (0.01, 0.02, 0.05, 0.1):
        model = mixed_fit(clean, threshold)
        if keeps_exact_terms(model):
            return model
    return None


def noisy_supports(X):
    """Which thresholded fits of the mixed space at degree 2 keep the exact terms on noisy data."""
    return [f"Q={denoise} {fit_on} {threshold}"
            for denoise in (5, 8) for fit_on in ("derivatives", "weak")
            for threshold in (0.01, 0.03)
            if keeps_exact_terms(mixed_fit(X, threshold, denoise, fit_on))]


def run(shape, seed, supports_only=False):
    _, _, X = scene_data(NAME, shape, "add2", seed)
    found = noisy_supports(X)
    print(f"{shape} seed {seed}: the mixed space at degree 2 keeps the exact terms of the noisy "
          f"records in {len(found)} of 8 settings" + (f" ({', '.join(found)})" if found else ""))
    if supports_only:
        return
    _, _, clean = scene_data(NAME, shape, "0", seed)
    start = time.process_time()
    search = HamiltonianSearchCV(dt=DT).fit(X)
    seconds = time.process_time() - start
    chosen = search.best_estimator_[-1]
    print(f"{shape} seed {seed}: search ({seconds:.0f} CPU s), T = 20 error "
          f"{model_error(chosen, NAME, True):.3g}: {format_hamiltonian(chosen)}")
    exact = exact_terms_model(clean)
    if exact is None:
        print("   the exact terms: no threshold of the oracle keeps them; not judged")
        return
    trajectories = [np.asarray(x) for x in X]
    # The search's own noise model and judgement, the chosen terms against the exact ones.
    verdict = judge_supports([chosen, exact], trajectories, DT, search.preparation_["noise"])
    for label, model, rss in zip(("chosen", "exact"), (chosen, exact), verdict["rss"]):
        model = copy.deepcopy(model)
        refine_on_trajectories(model, trajectories, DT)
        print(f"   {label}: weighted RSS {rss:.0f} of {verdict['n_observations']} "
              f"observations; refined, T = 20 error {model_error(model, NAME, True):.3g}: "
              f"{format_hamiltonian(model)}")
    print(f"   judgement: {('chosen', 'exact')[verdict['best']]}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--shapes", nargs="+", default=["few", "one"], choices=["few", "one"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--supports-only", action="store_true",
                        help="only the thresholded fits of the noisy records (no search)")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    for shape in args.shapes:
        for seed in args.seeds:
            run(shape, seed, args.supports_only)


if __name__ == "__main__":
    main()
