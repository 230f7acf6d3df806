"""Fixed-lag smoothing of a particle filter by its lineage: the estimate of frame ``t`` read at frame ``t + lag``.

A filter's estimate of frame ``t`` uses the images up to ``t``; when a demonstration is recorded (the robot
watches it before it acts), the frames after ``t`` say which of the particles of frame ``t`` were on the right
track. Each particle keeps the poses and classes its ancestors had over the last ``lag`` frames (resampling
copies a particle's past with it); frame ``t``'s smoothed estimate is those ancestral poses weighted by the
weights of frame ``t + lag`` (Kitagawa's fixed-lag smoother). A long lag leaves few distinct ancestors (the
lineages coalesce), so it is a trade: chosen on validation, ``docs/experiments/tracking.md``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["MAX_LAG", "ParticleLineage", "SmoothedFrame", "tilted"]

MAX_LAG = 1000  # frames (10 s at 100 Hz); each kept frame holds every particle's pose


@dataclass(frozen=True, eq=False)
class SmoothedFrame:
    """The estimate of frame ``frame`` (counted from the tracker's reset) given the frames up to ``frame + lag``:
    ``markers`` (M, 3) the weighted mean pose, ``class_probabilities`` P(a)."""

    frame: int
    markers: np.ndarray
    class_probabilities: Mapping[int, float]

    @property
    def class_id(self) -> int:
        """The most probable class."""
        return max(self.class_probabilities, key=self.class_probabilities.get)


class ParticleLineage:
    """The last ``lag`` frames of every particle's ancestry: poses ``(n, M, 3)``, class ids ``(n,)`` and each pose's
    tilt ``(n,)`` (log factor, or None) that the pose estimate (not the class posterior) multiplies its weight by."""

    def __init__(self, lag: int) -> None:
        self.lag = lag
        self._past: deque[tuple[int, np.ndarray, np.ndarray, np.ndarray | None]] = deque()

    def push(self, frame: int, markers: np.ndarray, class_ids: np.ndarray, weights: np.ndarray,
             tilt: np.ndarray | None = None) -> list[SmoothedFrame]:
        """Record frame ``frame``'s particles (before resampling) and return the frame whose lag has passed, read
        with this frame's ``weights`` (none while fewer than ``lag`` frames followed it)."""
        self._past.append((frame, markers, class_ids.copy(), None if tilt is None else tilt.copy()))
        return [self._estimate(*self._past.popleft(), weights)] if len(self._past) > self.lag else []

    def resampled(self, ancestors: np.ndarray) -> None:
        """Particle ``i`` is now a copy of particle ``ancestors[i]``: its past goes with it."""
        for k, (frame, markers, class_ids, tilt) in enumerate(self._past):
            self._past[k] = (frame, markers[ancestors], class_ids[ancestors], None if tilt is None else tilt[ancestors])

    def flush(self, weights: np.ndarray) -> list[SmoothedFrame]:
        """Every frame still held, read with ``weights`` (the last frame's), and forget them."""
        out = [self._estimate(*past, weights) for past in self._past]
        self._past.clear()
        return out

    @staticmethod
    def _estimate(frame: int, markers: np.ndarray, class_ids: np.ndarray, tilt: np.ndarray | None,
                  weights: np.ndarray) -> SmoothedFrame:
        classes, of_class = np.unique(class_ids, return_inverse=True)
        return SmoothedFrame(frame, np.einsum("n,nmk->mk", tilted(weights, tilt), markers),
                             dict(zip(classes.tolist(), np.bincount(of_class, weights).tolist())))


def tilted(weights: np.ndarray, tilt: np.ndarray | None) -> np.ndarray:
    """``weights`` (n,) times ``exp(tilt)`` (log factors, n), normalised; ``weights`` as they are for no tilt, or
    when the tilt leaves no weight (every weighted particle's tilt -inf)."""
    if tilt is None:
        return weights
    with np.errstate(divide="ignore"):
        log_weights = np.log(weights) + tilt
    top = np.max(log_weights)
    if not np.isfinite(top):
        return weights
    out = np.exp(log_weights - top)
    return out / out.sum()
