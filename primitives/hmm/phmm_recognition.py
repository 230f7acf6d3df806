"""Recognition with several parametric HMMs: which class's model explains a movement best, at which effect."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.hmm.hmm_math import validate_sequences
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM

__all__ = ["Recognition", "recognize"]


@dataclass(frozen=True, eq=False)
class Recognition:
    """Result of :func:`recognize`: the best class id, its effect estimate, and every class's log-likelihood."""

    label: int
    phi: np.ndarray
    log_likelihoods: Mapping[int, float]
    phis: Mapping[int, np.ndarray] = field(default_factory=dict)



def recognize(X, models: Mapping[int, ParametricHMM], n_restarts: int = 5) -> Recognition:
    """Classify one movement ``X`` (T, D): estimate phi under each class's model, pick the most likely class.

    ``models`` maps class ids (the discovery's ``primitive_id``) to fitted models.

    A chain that cannot reach its last state in ``X``'s frames (:attr:`ParametricHMM.min_frames`) cannot
    explain it and scores ``-inf``.
    """
    if not models:
        raise InvalidInputError("models must map at least one class id to a fitted ParametricHMM")
    X, _ = validate_sequences(X)
    scores: dict[int, float] = {}
    phis: dict[int, np.ndarray] = {}
    for label, model in models.items():
        check_is_fitted(model)
        if X.shape[0] < model.min_frames:
            scores[label], phis[label] = -np.inf, np.full(model.phi_dim_, np.nan)
            continue
        phis[label], scores[label] = model._estimate(X, n_restarts=n_restarts)
    best = max(scores, key=scores.__getitem__)
    if not np.isfinite(scores[best]):
        raise InvalidInputError(f"no model can explain a {X.shape[0]}-frame sequence (every log-likelihood is -inf)")
    return Recognition(label=best, phi=phis[best], log_likelihoods=scores, phis=phis)
