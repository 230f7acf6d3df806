"""Gaussians of the discovery's HMM states: the KL divergence of eq. (1) and the merge of eqs. (2)-(3).

Batched over leading axes so the discovery compares every joint state with every new one at once;
covariances are inverted through Cholesky factors, stabler than ``inv`` for the small variances of
short pieces.
"""

from __future__ import annotations

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["OMEGA", "gaussian_kl", "merge_gaussians", "spd_inverse", "symmetric_kl_matrix"]

OMEGA = 0.5  # the paper's weight of the joint state in the merge


def gaussian_kl(mean_q: np.ndarray, cov_q: np.ndarray, mean_p: np.ndarray, cov_p: np.ndarray) -> np.ndarray:
    """Eq. (1): D_KL(Q||P) of Q = N(mean_q, cov_q) from P = N(mean_p, cov_p), in nats.

    Broadcasts over leading axes: means ``(..., n)``, covariances ``(..., n, n)`` SPD.
    """
    mean_q, mean_p = np.asarray(mean_q, float), np.asarray(mean_p, float)
    cov_q, cov_p = np.asarray(cov_q, float), np.asarray(cov_p, float)
    n = mean_q.shape[-1]
    diff = (mean_p - mean_q)[..., None]
    trace = np.trace(np.linalg.solve(cov_p, cov_q), axis1=-2, axis2=-1)
    mahalanobis = (np.swapaxes(diff, -1, -2) @ np.linalg.solve(cov_p, diff))[..., 0, 0]
    logdet_ratio = np.linalg.slogdet(cov_p)[1] - np.linalg.slogdet(cov_q)[1]
    return 0.5 * (logdet_ratio + trace + mahalanobis - n)


def symmetric_kl_matrix(
    means_a: np.ndarray, covs_a: np.ndarray, means_b: np.ndarray, covs_b: np.ndarray
) -> np.ndarray:
    """``(D_KL(a_k||b_m) + D_KL(b_m||a_k)) / 2`` for all pairs, shape ``(K, M)``, vectorised.

    The log-determinants cancel, leaving traces and a Mahalanobis term with the summed precisions.
    """
    prec_a, prec_b = spd_inverse(covs_a), spd_inverse(covs_b)
    n = means_a.shape[1]
    traces = np.einsum("mij,kji->km", prec_b, covs_a) + np.einsum("kij,mji->km", prec_a, covs_b)
    diff = means_a[:, None, :] - means_b[None, :, :]
    mahalanobis = np.einsum("kmi,kij,kmj->km", diff, prec_a, diff) + np.einsum("kmi,mij,kmj->km", diff, prec_b, diff)
    return 0.25 * (traces + mahalanobis) - 0.5 * n


def merge_gaussians(
    mean0: np.ndarray, cov0: np.ndarray, mean1: np.ndarray, cov1: np.ndarray, omega: float = OMEGA
) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. (2)-(3): precision-weighted merge of two Gaussians; broadcasts over leading axes.

    ``Sigma^-1 = omega Sigma0^-1 + (1 - omega) Sigma1^-1``,
    ``mu = Sigma (omega Sigma0^-1 mu0 + (1 - omega) Sigma1^-1 mu1)``.
    """
    if not 0.0 <= omega <= 1.0:
        raise InvalidInputError(f"omega must be in [0, 1], got {omega}")
    prec0, prec1 = spd_inverse(np.asarray(cov0, float)), spd_inverse(np.asarray(cov1, float))
    prec = omega * prec0 + (1.0 - omega) * prec1
    cov = spd_inverse(prec)
    weighted = omega * (prec0 @ np.asarray(mean0, float)[..., None]) + (1.0 - omega) * (
        prec1 @ np.asarray(mean1, float)[..., None]
    )
    return (cov @ weighted)[..., 0], cov


def spd_inverse(cov: np.ndarray) -> np.ndarray:
    """Inverse of SPD matrices via Cholesky, symmetrised (stabler than ``inv`` for small variances)."""
    chol_inv = np.linalg.inv(np.linalg.cholesky(cov))
    return np.swapaxes(chol_inv, -1, -2) @ chol_inv
