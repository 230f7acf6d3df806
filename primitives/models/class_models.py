"""What the action models are made of and answer with: one class's PHMM with its effect map, the
model input of a movement, and the results of recognising and decoding."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM

__all__ = ["DISPLACEMENT_WINDOW_S", "EFFECT_DIM", "PHI_NAMES", "ClassModel", "DecodedSegment", "SegmentRecognition",
           "lookup_model", "marker_features"]

DISPLACEMENT_WINDOW_S = 0.1  # s, the marker displacement appended to the positions
EFFECT_DIM = 6  # phi = initial xyz, final xyz (m)
PHI_NAMES = ("initial x", "initial y", "initial z", "final x", "final y", "final z")


def marker_features(H: np.ndarray, fps: float, velocity: bool = True) -> np.ndarray:
    """Model input of one movement: markers ``(T, 18)`` (or ``(T, M, 3)``) in metres, with each
    marker's displacement over :data:`DISPLACEMENT_WINDOW_S` appended when ``velocity``: ``(T, 36)``."""
    X = np.asarray(H, dtype=float).reshape(len(H), -1)
    if not velocity:
        return X
    displacement = np.gradient(X, axis=0) * (fps * DISPLACEMENT_WINDOW_S) if len(X) > 1 else np.zeros_like(X)
    return np.hstack([X, displacement])


@dataclass(frozen=True)
class ClassModel:
    """One class's PHMM and the affine map between its reduced effect and the full phi (6,)."""

    class_id: int
    kind: str
    phmm: ParametricHMM
    centre: np.ndarray  # (6,) mean training effect
    basis: np.ndarray  # (6, r) principal directions the PHMM's reduced phi runs along
    exit_probability: float  # per frame, of leaving the chain's last state (connected recognition)

    def full_phi(self, reduced: np.ndarray) -> np.ndarray:
        return self.centre + self.basis @ reduced

    def reduced_phi(self, phi: np.ndarray) -> np.ndarray:
        return (np.asarray(phi, float) - self.centre) @ self.basis


@dataclass(frozen=True)
class SegmentRecognition:
    """A recognised movement: the best class, its phi (6,), every class's log-likelihood (its chain's
    best path over its training effects, on the displacements) and the candidate classes' phi.

    Classes whose chain is longer than the movement score ``-inf``; classes that are not candidates have no phi.
    """

    class_id: int
    phi: np.ndarray
    log_likelihoods: Mapping[int, float]
    phis: Mapping[int, np.ndarray]


@dataclass(frozen=True)
class DecodedSegment:
    """A piece of a decoded movement: frames ``[start, end)`` perform class ``class_id`` with effect ``phi`` (6,)."""

    class_id: int
    start: int
    end: int
    phi: np.ndarray


def lookup_model(models: Mapping[int, ClassModel], model_id: object, what: str, plural: str) -> ClassModel:
    """``models[model_id]``, or an error listing the ids there are."""
    try:
        return models[int(model_id)]
    except (KeyError, TypeError, ValueError):
        raise InvalidInputError(f"no {what} {model_id!r}; {plural}: {sorted(models)}") from None
