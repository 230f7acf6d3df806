"""What the seen object says about each particle's class: its motion and, optionally, its place.

* **Motion** (discovery's own definition of the classes): a manipulation moves the object, approach and
  remove leave it still. The object's displacement over the last :data:`OBJECT_MOTION_FRAMES` frames is
  scored by a half-normal of the moving or the still scale, mixed with a share uniform over
  :data:`OBJECT_MOTION_RANGE_M` (a mislocated block).
* **Place** (``place_m``): where a particle's class puts the object: where it was when the class began,
  moved along a manipulation's learned displacement as far as the class's hand has come along it (its mean
  path at the class's centre effect). Manipulations are pieces of a push or a carry a few centimetres apart
  (each learned within 1-3 mm), so the place tells them apart where the arm's pose barely does. It needs
  the object's true place: motion capture's is exact, while the camera's block locator is centimetres off
  once the hand covers the block, and the term then cost the tracker accuracy (validation,
  ``docs/experiments/tracking.md``).
"""

from __future__ import annotations

import numpy as np

from hoap_actions.primitives.discovery.estimator import MANIPULATION
from hoap_actions.tracking.poses import mean_poses
from hoap_actions.tracking.tracking_models import TrackingModels

__all__ = ["OBJECT_MOTION_FRAMES", "OBJECT_MOVING_M", "OBJECT_PLACE_M", "OBJECT_STILL_M", "ObjectEvidence"]

# m, half-normal scale of a pushed block's displacement over OBJECT_MOTION_FRAMES (about 1 cm: validation)
OBJECT_MOVING_M = 0.01
# m, the same for a block at rest: the locator's jitter (median 0, 90 % below 3-4 mm on validation)
OBJECT_STILL_M = 0.003
OBJECT_MOTION_FRAMES = 5  # frames over which the object's seen displacement is measured
# share of that displacement's density uniform over OBJECT_MOTION_RANGE_M (a mislocated block)
OBJECT_OUTLIER_SHARE = 0.1
OBJECT_MOTION_RANGE_M = 0.3  # m, the uniform's range: about the table region the block moves in
# m, scale of the place term with motion capture's object (validation: 0.01 / 0.02 / 0.04 m gave classes
# 94.2 / 93.5 / 92.3 % against 89.2 % without, all markers 3.27 / 3.21 / 3.07 cm against 3.01)
OBJECT_PLACE_M = 0.04
OBJECT_PLACE_CAP_M = 0.05  # m, a place misfit counts at most this much: a mislocated object is not a class


class ObjectEvidence:
    """The object seen over the last frames, and the log-likelihood terms it gives each particle.

    ``still_m`` None turns the motion term off; ``place_m`` None (the default) the place term.
    """

    def __init__(self, models: TrackingModels, still_m: float | None = OBJECT_STILL_M,
                 moving_m: float = OBJECT_MOVING_M, place_m: float | None = None) -> None:
        self.still_m, self.moving_m, self.place_m = still_m, moving_m, place_m
        self.manipulations = np.array([cid for cid, c in models.classes.items() if c.kind == MANIPULATION])
        self.displacement: dict[int, np.ndarray] = {}
        self._progress: dict[int, np.ndarray] = {}
        for cid, model in models.classes.items():
            effects = model.centre + np.einsum("np,kp->nk", model.phmm.train_phi_, model.basis)
            shift = np.mean(effects[:, 3:] - effects[:, :3], axis=0) * (model.kind == MANIPULATION)
            self.displacement[cid] = shift
            if place_m is None:  # the hand's progress serves the place term only
                continue
            k = model.phmm.n_states
            hand = mean_poses(model, np.arange(k, dtype=float), np.tile(model.centre, (k, 1)),
                              len(models.marker_names)).reshape(k, -1, 3)[:, models.hand_marker, :2]
            along = shift[:2] @ shift[:2]
            self._progress[cid] = (np.clip((hand - hand[0]) @ shift[:2] / along, 0.0, 1.0) if along > 1e-8
                                   else np.linspace(0.0, 1.0, k))
        self.reset()

    def reset(self) -> None:
        """Forget what was seen."""
        self.track: list[np.ndarray | None] = []

    def see(self, position: np.ndarray | None) -> None:
        """Remember this frame's (checked) object position, None when not seen."""
        self.track = [*self.track[-OBJECT_MOTION_FRAMES:], position]

    @property
    def now(self) -> np.ndarray | None:
        """Where the object is seen this frame (None: not seen)."""
        return self.track[-1] if self.track else None

    def moved(self, class_ids: np.ndarray) -> np.ndarray:
        """The learned displacement ``(n, 3)`` (m) of each class in ``class_ids`` (0 but for manipulations)."""
        return np.array([self.displacement[int(c)] for c in class_ids]).reshape(-1, 3)

    def motion_log_likelihood(self, class_ids: np.ndarray, resting: np.ndarray) -> np.ndarray:
        """Per particle, how well its class explains the object's displacement over the window, divided by
        the window's length (the windows overlap, so each frame's motion is seen that many times). 0 when the
        object was not seen at both ends of a full window or the term is off."""
        now, before = self.now, self.track[0] if self.track else None
        if self.still_m is None or now is None or before is None or len(self.track) <= OBJECT_MOTION_FRAMES:
            return np.zeros(len(class_ids))
        moved = float(np.linalg.norm(now - before))

        def density(scale: float) -> float:
            half_normal = np.sqrt(2.0 / np.pi) / scale * np.exp(-0.5 * (moved / scale) ** 2)
            return np.log((1.0 - OBJECT_OUTLIER_SHARE) * half_normal + OBJECT_OUTLIER_SHARE / OBJECT_MOTION_RANGE_M)

        moving = np.isin(class_ids, self.manipulations) & ~resting
        return np.where(moving, density(self.moving_m), density(self.still_m)) / OBJECT_MOTION_FRAMES

    def place_log_likelihood(self, class_ids: np.ndarray, states: np.ndarray, resting: np.ndarray,
                             began_at: np.ndarray) -> np.ndarray:
        """Per particle, ``-min(d^2, cap^2) / (2 place_m^2)`` with d the distance on the table (x, y) between the
        object seen now and where the particle's class puts it, from ``began_at`` (n, 3), where the object was
        when the class began. 0 when the object is not seen or the term is off."""
        now = self.now
        if self.place_m is None or now is None:
            return np.zeros(len(class_ids))
        place = began_at[:, :2].copy()
        for cid in np.unique(class_ids[np.isin(class_ids, self.manipulations)]):
            rows = np.flatnonzero(class_ids == cid)
            profile = self._progress[int(cid)]
            progress = np.where(resting[rows], 1.0, np.interp(states[rows], np.arange(profile.size), profile))
            place[rows] += progress[:, None] * self.displacement[int(cid)][:2]
        squared = np.sum((place - now[:2]) ** 2, axis=1)
        return -np.minimum(squared, OBJECT_PLACE_CAP_M**2) / (2.0 * self.place_m**2)
