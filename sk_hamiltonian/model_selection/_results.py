"""The search's candidates in scikit-learn's words: pipeline parameters and ``cv_results_``."""

import numpy as np


def transformer_params(denoise):
    """Parameters of :class:`~sk_hamiltonian.DerivativeTransformer` for a derivative layout."""
    if denoise == "finite_difference":
        return {"method": "finite_difference"}
    return {"method": "polynomial", "degree": int(denoise)}


def describe_layout(denoise):
    """A derivative layout in a few words."""
    return "finite differences" if denoise == "finite_difference" else f"Q={denoise}"


def pipeline_params(denoise, fit_on, space, degree, threshold, damping, domain=None):
    """Parameters of ``make_pipeline(DerivativeTransformer(), HamiltonianRegressor())``."""
    params = {f"derivativetransformer__{key}": value
              for key, value in transformer_params(denoise).items()}
    for key, value in space.items():
        params[f"hamiltonianregressor__{key}"] = value
    params["hamiltonianregressor__degree"] = int(degree)
    params["hamiltonianregressor__threshold"] = float(threshold)
    params["hamiltonianregressor__fit_on"] = fit_on
    if damping:
        params["hamiltonianregressor__damping"] = True
    if domain is not None:
        params["hamiltonianregressor__domain"] = domain
    return params


def cv_results(records, spaces, n_folds, damping, domain):
    """``cv_results_`` from the candidates' records."""
    params = [
        pipeline_params(r["denoise"], r["fit_on"], spaces[r["space"]], r["degree"],
                        r["threshold"], damping, domain)
        for r in records
    ]
    results = {"params": params}
    for name in sorted({key for p in params for key in p}):
        column = np.ma.MaskedArray(np.empty(len(params), dtype=object), mask=True)
        for i, p in enumerate(params):
            if name in p:
                column[i] = p[name]
        results[f"param_{name}"] = column
    scores = np.array([r["scores"] for r in records])
    errors = np.array([r["errors"] for r in records])
    for k in range(n_folds):
        results[f"split{k}_test_score"] = scores[:, k]
    finite = np.isfinite(scores).all(axis=1)
    mean = np.where(finite, scores.mean(axis=1), np.nan)
    results["mean_test_score"] = mean
    results["std_test_score"] = np.where(finite, scores.std(axis=1), np.nan)
    order = np.argsort(-np.where(finite, mean, -np.inf), kind="stable")
    rank = np.empty(len(records), dtype=np.int32)
    rank[order] = np.arange(1, len(records) + 1)
    results["rank_test_score"] = rank
    for k in range(n_folds):
        results[f"split{k}_equation_error"] = errors[:, k]
    results["mean_equation_error"] = errors.mean(axis=1)
    results["std_equation_error"] = errors.std(axis=1)
    results["mean_fit_time"] = np.array([r["fit_time"] for r in records])
    results["mean_score_time"] = np.array([r["score_time"] for r in records])
    results["n_terms"] = np.array([r["n_terms"] for r in records])
    results["stage"] = np.array([r["stage"] for r in records])
    results["tied"] = np.array([r["tied"] for r in records])
    return results
