"""The pose estimate refined against the frame's images: a local search beyond the particles' own poses.

The filter's estimate is a weighted mean of its particles' poses, so it can only be as near the arm as the
particles are; their poses come from the class means, and a phase or class confused for a few frames
leaves the hand centimetres off even where two views or a depth image show it plainly. The refiner moves
the estimate itself: the hand shifted as a whole and turned about the vertical through the wrist, the elbow
following half the hand's shift plus its own shift, scored by the same terms as the filter (edges,
silhouettes, depth; :mod:`~hoap_actions.tracking.image_evidence`) with a sharper edge sigma, and a Gaussian
prior that keeps it near the estimate where the images say little. The search is the cross-entropy method
(samples around a mean, the best share refits the mean and spread, a few rounds: the annealing of an
annealed particle filter, on one pose). The class posterior and the filter are untouched.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.tracking.image_evidence import image_log_likelihoods
from hoap_actions.tracking.poses import turn_about_vertical
from hoap_actions.vision.body_model import BodyModel, Projector

__all__ = ["PoseRefiner"]

ELBOW, WRIST = 1, 2  # marker rows (shoulder, elbow, wrist, index tip, index knuckle, thumb tip)
HAND_ROWS = slice(2, 6)
PARAMETERS = 7  # hand shift x, y, z (m), hand turn (rad), elbow shift x, y, z (m)


@dataclass(frozen=True)
class PoseRefiner:
    """Refine one pose ``(M, 3)`` against one frame's images (see the module docstring).

    ``prior_sd``: the Gaussian prior's standard deviations of the hand's shift (m), its turn (rad) and the
    elbow's own shift (m); ``sigmas``: the edge, silhouette and depth sigmas of the score; ``samples`` per
    round, ``rounds``, ``elite``: the share of samples that refits the search.
    """

    body: BodyModel
    cameras: tuple[Projector, ...]
    prior_sd: tuple[float, float, float] = (0.03, 0.3, 0.02)
    sigmas: tuple[float, float, float] = (0.2, 0.6, 0.01)
    samples: int = 64
    rounds: int = 5
    elite: float = 0.2

    def __post_init__(self) -> None:
        if not _three_positive(self.prior_sd):
            raise InvalidInputError(f"prior_sd takes three standard deviations > 0 (m, rad, m); got {self.prior_sd!r}")
        if not _three_positive(self.sigmas):
            raise InvalidInputError(f"sigmas takes three sigmas > 0 (edges, silhouette, depth m); got {self.sigmas!r}")
        if not (isinstance(self.samples, int) and self.samples >= 4 and isinstance(self.rounds, int)
                and self.rounds >= 1 and 0 < self.elite <= 0.5 and self.elite * self.samples >= 2):
            raise InvalidInputError(f"a refiner needs samples >= 4, rounds >= 1 and an elite share in (0, 0.5] of at "
                                    f"least 2 samples; got {self.samples!r}, {self.rounds!r}, {self.elite!r}")

    @property
    def _prior(self) -> np.ndarray:
        hand, turn, elbow = self.prior_sd
        return np.array([hand, hand, hand, turn, elbow, elbow, elbow])

    def posed(self, markers: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Poses ``(n, M, 3)`` of ``markers`` (M, 3) moved by parameters ``theta`` (n, 7): the fingers turned about
        the vertical through the wrist; the hand shifted; the elbow moved by half the hand's shift and its own."""
        theta = np.atleast_2d(theta)
        out = np.repeat(np.asarray(markers, float)[None], len(theta), axis=0)
        fingers = turn_about_vertical(out[:, WRIST], list(out[:, WRIST + 1:HAND_ROWS.stop].transpose(1, 0, 2)),
                                      theta[:, 3])
        out[:, WRIST + 1:HAND_ROWS.stop] = np.stack(fingers, axis=1)
        out[:, HAND_ROWS] += theta[:, None, 0:3]
        out[:, ELBOW] += 0.5 * theta[:, 0:3] + theta[:, 4:7]
        return out

    def refine(self, markers: np.ndarray, edges: Sequence[np.ndarray], masks: Sequence[np.ndarray] | None,
               depths: Sequence[np.ndarray] | None, rng: np.random.Generator,
               start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The refined pose ``(M, 3)`` and its parameters (7,); ``start``: parameters to search from (e.g. the
        previous frame's), zeros by default."""
        markers = np.asarray(markers, dtype=float)
        prior = self._prior
        mean = np.zeros(PARAMETERS) if start is None else np.asarray(start, float)
        spread = prior.copy()
        keep = max(2, int(round(self.elite * self.samples)))
        for _ in range(self.rounds):
            theta = np.vstack([mean, mean + rng.normal(0.0, 1.0, (self.samples - 1, PARAMETERS)) * spread])
            score = self.score(markers, theta, edges, masks, depths)
            best = theta[np.argsort(-score)[:keep]]
            mean, spread = best.mean(axis=0), np.maximum(best.std(axis=0), 0.05 * prior)
        return self.posed(markers, mean)[0], mean

    def score(self, markers: np.ndarray, theta: np.ndarray, edges: Sequence[np.ndarray],
              masks: Sequence[np.ndarray] | None, depths: Sequence[np.ndarray] | None) -> np.ndarray:
        """Log score (n,) of parameters ``theta`` (n, 7): the images' terms plus the prior's."""
        poses = self.posed(markers, theta)
        colour, depth = image_log_likelihoods(self.body, list(self.cameras), poses, list(edges),
                                              None if masks is None else list(masks),
                                              None if depths is None else list(depths), markers, self.sigmas)
        prior = -0.5 * np.sum((theta / self._prior) ** 2, axis=1)
        return colour + prior + (0.0 if depth is None else depth)


def _three_positive(values: object) -> bool:
    """Whether ``values`` are three finite numbers > 0."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        return False
    return array.shape == (3,) and bool(np.all(np.isfinite(array) & (array > 0)))
