"""How precise the fitted parameters are: their information, and their covariance.

With the initial states of the trajectories profiled out, the information
about the parameters is the Schur complement of the Gauss-Newton normal
matrix (:func:`information`); its inverse is the covariance where the noise
model is right. The sandwich (:func:`sandwich_covariance`) adds each
cluster's scores, and stays right where the noise model is wrong, as long as
the clusters (trajectories) are independent. The sandwich is estimated from
the scores themselves, so with a few hundred clusters and several parameters
it scatters and runs low for some of them (measured: 80-82 % coverage of
nominal 90 % on three of Henon-Heiles' six terms, while the model-based
variance covers them); :func:`parameter_covariance` takes, parameter by
parameter, the larger of the two.
"""

import numpy as np


def information(model, groups, runs):
    """The parameters' information matrix and each trajectory's score, initial states profiled out.

    With ``A_k = d r_k / d x0_k`` and ``B_k = d r_k / d theta`` (weighted),
    the information about ``theta`` once every initial state is fitted is
    the Schur complement ``S = sum_k B_k^T B_k - B_k^T A_k (A_k^T A_k)^-1
    A_k^T B_k``, and trajectory ``k``'s score is ``B_k^T r_k - B_k^T A_k
    (A_k^T A_k)^-1 A_k^T r_k``. ``S^-1`` is the Gauss-Newton covariance where
    the noise model is right; ``S^-1 (sum_c g_c g_c^T) S^-1`` over clusters
    ``c`` of scores is the sandwich, right where it is not.
    """
    k = runs[0][2].shape[-1]
    S, scores = np.zeros((k, k)), []
    for g, (X, SX, ST) in zip(groups, runs):
        n, n_times, d = g.Y.shape
        r = g.residuals(model, X).reshape(n, n_times * d)
        A = (SX * g.W[..., None]).reshape(n, n_times * d, d)
        B = (ST * g.W[..., None]).reshape(n, n_times * d, k)
        AA = np.einsum("nri,nrj->nij", A, A)
        AB = np.einsum("nri,nrj->nij", A, B)
        try:
            AA_inv_AB = np.linalg.solve(AA, AB)
        except np.linalg.LinAlgError:
            # A candidate whose flow explodes along a trajectory (sensitivities of
            # 1e13, their block singular to round-off) is judged, not fitted on:
            # its information is the pseudo-inverse's, and its misfit loses.
            AA_inv_AB = np.linalg.pinv(AA) @ AB
        S += np.einsum("nri,nrj->ij", B, B) - np.einsum("nji,njk->ik", AB, AA_inv_AB)
        scores.append(np.einsum("nri,nr->ni", B, r)
                      - np.einsum("nji,nj->ni", AA_inv_AB, np.einsum("nri,nr->ni", A, r)))
    return S, scores


def equilibrated_inverse(information):
    """The pseudo-inverse of ``information`` scaled to a unit diagonal first.

    Coefficients in the user's units can differ by twenty orders of magnitude
    (the spring's ``p^2`` 500 beside its ``q^4`` 2.5e-10 with positions in
    thousandths), and so do the diagonal entries of their information: a
    plain pseudo-inverse cuts the small ones' directions off as round-off,
    and reports a variance of zero there. Scaled, it sees their correlations
    only, which do not depend on the units.
    """
    scale = unit_diagonal_scale(information)
    outer = np.outer(scale, scale)
    return np.linalg.pinv(information * outer) * outer


def unit_diagonal_scale(matrix):
    """``1 / sqrt(diag(matrix))`` (1 where the diagonal is not positive).

    ``D matrix D``, with ``D`` this diagonal, has a unit diagonal: solved or
    inverted so, a symmetric matrix whose entries span many orders of
    magnitude keeps its small directions.
    """
    diagonal = np.diag(matrix)
    return 1 / np.sqrt(np.where(diagonal > 0, diagonal, 1.0))


def sandwich_covariance(information, scores, clusters):
    """The covariance of the parameters from their information and scores, clustered.

    Parameters
    ----------
    information : ndarray of shape (n_params, n_params)
    scores : ndarray of shape (n_segments, n_params)
    clusters : ndarray of int of shape (n_segments,)
        Segments that may share more than the noise (the pieces of one
        record) share a cluster.

    Returns
    -------
    covariance : ndarray of shape (n_params, n_params)
        ``S^-1 (C / (C - 1)) (sum_c g_c g_c^T) S^-1``, with ``C`` clusters.
    """
    labels, index = np.unique(clusters, return_inverse=True)
    summed = np.zeros((len(labels), scores.shape[1]))
    np.add.at(summed, index, scores)
    n = len(labels)
    meat = summed.T @ summed * (n / max(n - 1, 1))
    inverse = equilibrated_inverse(information)
    covariance = inverse @ meat @ inverse
    return (covariance + covariance.T) / 2


def parameter_covariance(information, scores, clusters):
    """The covariance of the parameters: the sandwich, widened to the model-based variance.

    Parameters
    ----------
    information : ndarray of shape (n_params, n_params)
    scores : ndarray of shape (n_segments, n_params)
    clusters : ndarray of int of shape (n_segments,)
        As in :func:`sandwich_covariance`.

    Returns
    -------
    covariance : ndarray of shape (n_params, n_params)
        ``D Sigma D``, with ``Sigma`` the sandwich and ``D`` diagonal,
        ``D_ii = sqrt(max(1, (S^-1)_ii / Sigma_ii))``: each parameter's
        variance is the larger of the sandwich's and the model-based
        ``S^-1``'s, and the sandwich's correlations are kept (so the matrix
        stays positive semi-definite). A wrong noise model that makes the
        data scatter more than it says still widens the intervals through
        the sandwich; the sandwich's own scatter cannot make them narrower
        than the noise model's.
    """
    sandwich = sandwich_covariance(information, scores, clusters)
    model_based = np.diag(equilibrated_inverse(information))
    variance = np.diag(sandwich)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(variance > 0, model_based / variance, 1.0)
    scale = np.sqrt(np.maximum(ratio, 1.0))
    return sandwich * scale[:, None] * scale[None, :]
