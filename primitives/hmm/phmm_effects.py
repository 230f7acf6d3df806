"""The effect phi that explains a movement: the M-step on phi of :meth:`ParametricHMM.estimate_phi
<hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM.estimate_phi>`, closed form for linear means
and a damped Gauss-Newton step for bending ones."""

from __future__ import annotations

from typing import Any

import numpy as np

from hoap_actions.errors import IdentifiabilityError
from hoap_actions.primitives.hmm.hmm_math import inverse_deviations, precision_cholesky
from hoap_actions.primitives.hmm.phmm_batch import SequenceBatch

__all__ = ["phi_gauss_newton", "phi_update"]

# Gauss-Newton steps inside EM, each halved until the expected log-likelihood does not fall (a
# generalised EM step); after this many halvings phi stays where it was.
_MAX_STEP_HALVINGS = 20


def phi_update(model: Any, batch: SequenceBatch, gamma: np.ndarray) -> np.ndarray:
    """A phi per sequence that raises the expected complete log-likelihood: its maximiser (linear
    means) or a damped Gauss-Newton step towards it (bending means)."""
    if model.V_.shape[2]:
        return phi_gauss_newton(model, batch, gamma)
    occ = gamma.sum(axis=1)                                                # (S, K)
    occ_x = np.matmul(gamma.transpose(0, 2, 1), batch.X)                   # (S, K, D)
    if model.covariance_type == "diag":  # P_j is diagonal: the same products, elementwise
        inv_sd = inverse_deviations(model.covars_)
        pw = inv_sd[:, :, None] * model.W_
        pm = inv_sd * (model.mean_bar_ - batch.offset)
        white_x = inv_sd * occ_x
    else:
        prec, _ = precision_cholesky(model.covars_, model.covariance_type)
        pw = np.matmul(prec, model.W_)                                      # (K, D, p): P_j W_j
        pm = np.einsum("kij,kj->ki", prec, model.mean_bar_ - batch.offset)  # (K, D):    P_j mu_bar_j
        white_x = np.einsum("kij,skj->ski", prec, occ_x)                    # (S, K, D): P_j sum_t g x_t
    gram = np.einsum("kdp,kdq->kpq", pw, pw)                               # (K, p, p): W_j^T S_j^-1 W_j
    lhs = np.einsum("sk,kpq->spq", occ, gram)
    resid = white_x - occ[:, :, None] * pm[None]
    rhs = np.einsum("kdp,skd->sp", pw, resid)
    try:
        return np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError as exc:
        raise IdentifiabilityError("phi is not identifiable from this sequence under this model "
                                   "(sum_j W_j^T S_j^-1 W_j is singular)") from exc

def phi_gauss_newton(model: Any, batch: SequenceBatch, gamma: np.ndarray) -> np.ndarray:
    """One Gauss-Newton step on ``Q(phi) = sum_tj g_tj log N(x_t; mu_j(phi), S_j)`` per sequence, halved
    (per sequence) until Q does not fall; whitened by ``P_j`` with ``P_j^T P_j = S_j^-1``."""
    prec, _ = precision_cholesky(model.covars_, model.covariance_type)
    occ = gamma.sum(axis=1)                                                # (S, K)
    white_x = np.einsum("kij,skj->ski", prec, np.matmul(gamma.transpose(0, 2, 1), batch.X))  # P_j sum_t g x_t

    def white_means(phi: np.ndarray) -> np.ndarray:
        return np.einsum("kij,skj->ski", prec, model._means_at(phi, batch.offset))

    def expected(white_mu: np.ndarray) -> np.ndarray:
        return np.einsum("skd,skd->s", white_mu, white_x - 0.5 * occ[:, :, None] * white_mu)

    phi = batch.phi
    jac = model.W_[None] + np.einsum("kdm,smp->skdp", model.V_, model.effect_features_.jacobian(phi))
    white_jac = np.einsum("kij,skjp->skip", prec, jac)                     # (S, K, D, p)
    white_mu = white_means(phi)
    lhs = np.einsum("sk,skdp,skdq->spq", occ, white_jac, white_jac)
    rhs = np.einsum("skdp,skd->sp", white_jac, white_x - occ[:, :, None] * white_mu)
    try:
        step = np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError as exc:
        raise IdentifiabilityError("phi is not identifiable from this sequence under this model (the "
                                   "Gauss-Newton matrix sum_j J_j^T S_j^-1 J_j is singular)") from exc
    before, share = expected(white_mu), np.ones(phi.shape[0])
    for _ in range(_MAX_STEP_HALVINGS):
        worse = expected(white_means(phi + share[:, None] * step)) < before
        if not worse.any():
            break
        share = np.where(worse, 0.5 * share, share)
    else:
        share = np.where(expected(white_means(phi + share[:, None] * step)) < before, 0.0, share)
    return phi + share[:, None] * step
