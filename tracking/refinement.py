"""The pose estimate refined against the frame's images: a local search beyond the particles' own poses.

The filter's estimate is a weighted mean of its particles' poses, so it can only be as near the arm as the
particles are; their poses come from the class means, and a phase or class confused for a few frames
leaves the hand centimetres off even where two views or a depth image show it plainly. The refiner moves
the estimate itself: the hand shifted as a whole and turned about the vertical through the wrist, the elbow
following half the hand's shift plus its own shift, scored by the same terms as the filter (edges,
silhouettes, depth; :mod:`~hoap_actions.tracking.image_evidence`) with a sharper edge sigma, and a Gaussian
prior that keeps it near the estimate where the images say little. The search is the cross-entropy method
(samples around a mean, the best share refits the mean and spread, a few rounds: the annealing of an
annealed particle filter, on one pose). The class posterior and the filter are untouched. Given where a
:class:`~hoap_actions.vision.fingertip.FingertipDetector` finds the fingertip in each view, the score also holds
the pose's index tip to those pixels (a Gaussian of ``fingertip_sd_px``): the outline's terms place the hand, the
detector the fingertip within it.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.tracking.image_evidence import image_log_likelihoods
from hoap_actions.tracking.poses import turn_about_vertical
from hoap_actions.vision.body_model import BodyModel, Projector
from hoap_actions.vision.fingertip import FingertipDetector

__all__ = ["PoseRefiner", "RefinedEstimates"]

ELBOW, WRIST, INDEX_TIP = 1, 2, 3  # marker rows (shoulder, elbow, wrist, index tip, index knuckle, thumb tip)
HAND_ROWS = slice(2, 6)
PARAMETERS = 7  # hand shift x, y, z (m), hand turn (rad), elbow shift x, y, z (m)


@dataclass(frozen=True)
class PoseRefiner:
    """Refine one pose ``(M, 3)`` against one frame's images (see the module docstring).

    ``prior_sd``: the Gaussian prior's standard deviations of the hand's shift (m), its turn (rad) and the
    elbow's own shift (m); ``sigmas``: the edge, silhouette and depth sigmas of the score; ``samples`` per
    round, ``rounds``, ``elite``: the share of samples that refits the search; ``fingertip``: a detector whose
    findings (:meth:`detect`) hold the index tip, ``fingertip_sd_px`` their spread.
    """

    body: BodyModel
    cameras: tuple[Projector, ...]
    prior_sd: tuple[float, float, float] = (0.03, 0.3, 0.02)
    sigmas: tuple[float, float, float] = (0.2, 0.6, 0.01)
    samples: int = 64
    rounds: int = 5
    elite: float = 0.2
    fingertip: FingertipDetector | None = None
    fingertip_sd_px: float = 3.0

    def __post_init__(self) -> None:
        if not _three_positive(self.prior_sd):
            raise InvalidInputError(f"prior_sd takes three standard deviations > 0 (m, rad, m); got {self.prior_sd!r}")
        if not _three_positive(self.sigmas):
            raise InvalidInputError(f"sigmas takes three sigmas > 0 (edges, silhouette, depth m); got {self.sigmas!r}")
        if not (isinstance(self.samples, int) and self.samples >= 4 and isinstance(self.rounds, int)
                and self.rounds >= 1 and 0 < self.elite <= 0.5 and self.elite * self.samples >= 2):
            raise InvalidInputError(f"a refiner needs samples >= 4, rounds >= 1 and an elite share in (0, 0.5] of at "
                                    f"least 2 samples; got {self.samples!r}, {self.rounds!r}, {self.elite!r}")
        if self.fingertip is not None and not isinstance(self.fingertip, FingertipDetector):
            raise InvalidInputError(f"fingertip takes a FingertipDetector or None; got {type(self.fingertip).__name__}")
        if not (isinstance(self.fingertip_sd_px, (int, float)) and np.isfinite(self.fingertip_sd_px)
                and self.fingertip_sd_px > 0):
            raise InvalidInputError(f"fingertip_sd_px takes a spread > 0 (px); got {self.fingertip_sd_px!r}")

    @classmethod
    def from_settings(cls, body: BodyModel, cameras: tuple[Projector, ...],
                      settings: Mapping[str, object] | None) -> PoseRefiner | None:
        """The refiner ``settings`` ask for (None: none), or an error naming the settings it takes."""
        if settings is None:
            return None
        known = {f.name for f in dataclasses.fields(cls)} - {"body", "cameras"}
        if not isinstance(settings, Mapping) or set(settings) - known:
            raise InvalidInputError(f"refine takes a mapping of {sorted(known)} (or None); got {settings!r}")
        return cls(body, cameras, **settings)

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

    def detect(self, markers: np.ndarray, images: Sequence[np.ndarray]) -> np.ndarray | None:
        """Where the detector finds the fingertip in each camera's image ``(V, 2)`` px, searched about the pose
        ``markers``' index tip (NaN in a view that does not show it); None without a detector."""
        if self.fingertip is None:
            return None
        tip = np.asarray(markers, float)[INDEX_TIP][None]
        found = np.full((len(self.cameras), 2), np.nan)
        for k, (camera, image) in enumerate(zip(self.cameras, images)):
            guess = camera.pixels(tip)
            if np.all(np.isfinite(guess)) and 0 <= guess[0, 0] < camera.width and 0 <= guess[0, 1] < camera.height:
                found[k] = self.fingertip.locate(image, guess)[0]
        return found

    def refine(self, markers: np.ndarray, edges: Sequence[np.ndarray], masks: Sequence[np.ndarray] | None,
               depths: Sequence[np.ndarray] | None, rng: np.random.Generator,
               start: np.ndarray | None = None, tips: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The refined pose ``(M, 3)`` and its parameters (7,); ``start``: parameters to search from (e.g. the
        previous frame's), zeros by default; ``tips``: :meth:`detect`'s findings."""
        markers = np.asarray(markers, dtype=float)
        prior = self._prior
        mean = np.zeros(PARAMETERS) if start is None else np.asarray(start, float)
        spread = prior.copy()
        keep = max(2, int(round(self.elite * self.samples)))
        for _ in range(self.rounds):
            theta = np.vstack([mean, mean + rng.normal(0.0, 1.0, (self.samples - 1, PARAMETERS)) * spread])
            score = self.score(markers, theta, edges, masks, depths, tips)
            best = theta[np.argsort(-score)[:keep]]
            mean, spread = best.mean(axis=0), np.maximum(best.std(axis=0), 0.05 * prior)
        return self.posed(markers, mean)[0], mean

    def score(self, markers: np.ndarray, theta: np.ndarray, edges: Sequence[np.ndarray],
              masks: Sequence[np.ndarray] | None, depths: Sequence[np.ndarray] | None,
              tips: np.ndarray | None = None) -> np.ndarray:
        """Log score (n,) of parameters ``theta`` (n, 7): the images' terms plus the prior's (and the fingertip's,
        given ``tips``)."""
        poses = self.posed(markers, theta)
        colour, depth = image_log_likelihoods(self.body, list(self.cameras), poses, list(edges),
                                              None if masks is None else list(masks),
                                              None if depths is None else list(depths), markers, self.sigmas)
        prior = -0.5 * np.sum((theta / self._prior) ** 2, axis=1)
        return colour + prior + (0.0 if depth is None else depth) + self._fingertip_term(poses, tips)

    def _fingertip_term(self, poses: np.ndarray, tips: np.ndarray | None) -> np.ndarray | float:
        """Log of the Gaussian holding each pose's index tip to the views' found fingertips (0 where none)."""
        if tips is None:
            return 0.0
        term = np.zeros(len(poses))
        for camera, tip in zip(self.cameras, tips):
            if np.all(np.isfinite(tip)):
                term -= 0.5 * np.sum((camera.pixels(poses[:, INDEX_TIP]) - tip) ** 2, axis=1) / self.fingertip_sd_px**2
        return term


class RefinedEstimates:
    """Each frame's images kept until its estimate is out (``lag`` frames later), then the estimate refined
    against them (:class:`PoseRefiner`; without one, nothing is kept or refined), searching from the previous
    frame's parameters: ``refined`` the refined estimates (frames with their markers refined) in frame order,
    ``spent`` their wall time (s)."""

    def __init__(self, refiner: PoseRefiner | None, seed: int, episode: int) -> None:
        self.refiner, self.rng = refiner, np.random.default_rng([seed, episode, 2])
        self._images: deque[tuple] = deque()
        self._last: np.ndarray | None = None
        self.refined: list = []
        self.spent = 0.0

    def keep(self, images: list[np.ndarray], edges: list[np.ndarray], masks: list[np.ndarray] | None,
             depths: list[np.ndarray] | None) -> None:
        """Keep one frame's camera images (for the fingertip detector), edge images, masks and depth images."""
        if self.refiner is not None:
            self._images.append((images if self.refiner.fingertip is not None else None, edges, masks, depths))

    def read(self, estimates: list) -> None:
        """Refine the estimates of ``estimates`` (every estimate so far, in frame order: frames with ``markers``)
        not refined yet."""
        if self.refiner is None:
            return
        started = time.perf_counter()
        for frame in estimates[len(self.refined):]:
            images, edges, masks, depths = self._images.popleft()
            tips = None if images is None else self.refiner.detect(frame.markers, images)
            markers, self._last = self.refiner.refine(frame.markers, edges, masks, depths, self.rng, self._last, tips)
            self.refined.append(replace(frame, markers=markers))
        self.spent += time.perf_counter() - started


def _three_positive(values: object) -> bool:
    """Whether ``values`` are three finite numbers > 0."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        return False
    return array.shape == (3,) and bool(np.all(np.isfinite(array) & (array > 0)))
