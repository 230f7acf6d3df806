"""What a parametric HMM's EM works on: sequences padded once with their effects, checked training
effects, and the equal-parts start of a left-right chain."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import IdentifiabilityError, InvalidInputError
from hoap_actions.primitives.hmm.hmm_math import pad_sequences, second_moments

__all__ = ["SequenceBatch", "check_train_phi", "equal_parts", "is_int", "is_real"]


@dataclass
class SequenceBatch:
    """Sequences padded once: frames (S, T, D) centred on ``offset``, their second moments, effects (S, p)."""

    X: np.ndarray
    moments: np.ndarray
    lengths: np.ndarray
    offset: np.ndarray
    phi: np.ndarray

    @classmethod
    def build(cls, X: np.ndarray, lengths: np.ndarray, phi: np.ndarray, offset: np.ndarray,
              covariance_type: str) -> SequenceBatch:
        padded = pad_sequences(X - offset, lengths)
        return cls(padded, second_moments(padded, covariance_type), lengths, offset, phi)


def is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) \
        and bool(np.isfinite(value))


def check_train_phi(train_phi, n_sequences: int) -> np.ndarray:
    """Training effects as float (S, p), affinely spanning R^p so each W_j is identifiable."""
    try:
        phi = np.asarray(train_phi, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"phi must be a numeric array of shape (n_sequences, p); got {exc}") from exc
    if phi.ndim != 2 or phi.shape[0] != n_sequences:
        raise InvalidInputError(f"phi must have shape (n_sequences, p) = ({n_sequences}, p), one effect per "
                                f"sequence; got shape {phi.shape} (use phi.reshape(-1, 1) for a scalar effect)")
    if not np.all(np.isfinite(phi)):
        raise InvalidInputError("phi must be finite; found NaN or inf")
    p = phi.shape[1]
    if p and np.linalg.matrix_rank(phi - phi.mean(axis=0)) < p:
        raise IdentifiabilityError(
            f"the {n_sequences} training effects do not affinely span R^{p} (rank "
            f"{np.linalg.matrix_rank(phi - phi.mean(axis=0))} < {p} after centring), so W is not identifiable; "
            f"give at least {p + 1} sequences whose effects do not all lie on one hyperplane (e.g. not collinear)"
        )
    return phi


def equal_parts(lengths: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Hard posteriors (S, T, K) cutting each sequence into K equal parts, and their transition counts."""
    s, t_max = lengths.size, int(lengths.max())
    t = np.arange(t_max)
    state = np.minimum((t[None, :] * k) // lengths[:, None], k - 1)
    valid = t[None, :] < lengths[:, None]
    gamma = np.zeros((s, t_max, k))
    gamma[valid, state[valid]] = 1.0
    xi = np.zeros((k, k))
    pair = valid[:, 1:]
    np.add.at(xi, (state[:, :-1][pair], state[:, 1:][pair]), 1.0)
    return gamma, xi
