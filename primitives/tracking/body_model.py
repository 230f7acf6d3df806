"""The demonstrator's body as capsules posed from the six arm markers, and its contour in a camera.

Each capsule joins two points (a marker, or the torso's base) with a radius. Its silhouette in a
pinhole camera is, to first order, the projected axis offset on both sides by the projected radius
(the radius divided by depth, through the camera's focal length) plus a cap at each end; the contour
is sampled there for every body of a batch at once (numpy, no rendering).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["ARM_CAPSULES", "BodyModel", "Capsule", "Projector"]


class Projector(Protocol):
    """A pinhole camera (:class:`hoap_actions.envs.sim.Camera` is one): its image size, world points
    (N, 3) to pixels (N, 2) (u right, v down), and its 4x4 world-to-camera matrix."""

    width: int
    height: int

    def project(self, points: np.ndarray) -> np.ndarray: ...

    def view_matrix(self) -> np.ndarray: ...


@dataclass(frozen=True)
class Capsule:
    """A segment between two named points (a marker, ``"torso_base"``, or a point placed from the shoulder
    marker: ``"neck"``, ``"head_low"``, ``"head_high"``) fleshed out to ``radius`` (m)."""

    start: str
    end: str
    radius: float


# Sizes of the demonstration world's body (human_arm.urdf): the thorax a 32 x 20 cm box seen as a 14 cm
# capsule, the head a 10 cm sphere, upper arm 4.5 cm, forearm 3.5 cm, the palm an 8.5 x 3 cm box seen
# as a 3.5 cm capsule, index finger and thumb 9 mm.
ARM_CAPSULES = (
    Capsule("torso_base", "neck", 0.14),
    Capsule("head_low", "head_high", 0.095),
    Capsule("shoulder", "elbow", 0.045),
    Capsule("elbow", "wrist", 0.035),
    Capsule("wrist", "index_knuckle", 0.035),
    Capsule("index_knuckle", "index_tip", 0.009),
    Capsule("wrist", "thumb_tip", 0.0095),
)
# m, points of the trunk placed from the right shoulder marker (measured on the demonstrator at rest and
# mid-reach, within 1.5 cm): the capsule end below the thorax's top (its cap reaches the top), and the
# head's axis. The trunk's base is the lumbar joint, which stays put (``torso_base``).
FROM_SHOULDER = {
    "neck": np.array([0.0, 0.227, 0.026 - 0.14]),
    "head_low": np.array([0.01, 0.227, 0.216 - 0.03]),
    "head_high": np.array([0.01, 0.227, 0.216 + 0.03]),
}


class BodyModel:
    """Capsules over the markers ``marker_names`` (plus the trunk's fixed base ``torso_base``, the lumbar
    joint, m, scene frame).

    :meth:`contour` gives ``(N, P, 2)`` pixels for ``N`` bodies of markers ``(N, M, 3)``.
    """

    def __init__(self, marker_names: tuple[str, ...], torso_base: np.ndarray,
                 capsules: tuple[Capsule, ...] = ARM_CAPSULES, points_per_side: int = 8) -> None:
        self.marker_names = tuple(marker_names)
        known = set(self.marker_names) | {"torso_base"} | set(FROM_SHOULDER)
        missing = sorted({name for c in capsules for name in (c.start, c.end)} - known)
        if missing:
            raise InvalidInputError(f"the body model needs markers {missing}, which these models do not have "
                                    f"(their markers: {list(self.marker_names)})")
        if set(FROM_SHOULDER) & {n for c in capsules for n in (c.start, c.end)} and "shoulder" not in self.marker_names:
            raise InvalidInputError("the trunk is placed from the 'shoulder' marker, which these models lack")
        self.torso_base = np.asarray(torso_base, dtype=float)
        self.capsules = capsules
        self.points_per_side = int(points_per_side)
        self._radius = np.array([c.radius for c in capsules])

    @property
    def n_points(self) -> int:
        """Contour points per body: both sides of every capsule and its two caps."""
        return len(self.capsules) * (2 * self.points_per_side + 2)

    def _point(self, name: str, markers: np.ndarray) -> np.ndarray:
        if name == "torso_base":
            return np.broadcast_to(self.torso_base, markers.shape[:1] + (3,))
        if name in FROM_SHOULDER:
            return markers[:, self.marker_names.index("shoulder")] + FROM_SHOULDER[name]
        return markers[:, self.marker_names.index(name)]

    def contour(self, markers: np.ndarray, camera: Projector) -> np.ndarray:
        """Pixels ``(N, P, 2)`` of the bodies' silhouettes for markers ``(N, M, 3)`` (m, scene frame)."""
        markers = np.asarray(markers, dtype=float)
        n = markers.shape[0]
        starts = np.stack([self._point(c.start, markers) for c in self.capsules], axis=1)  # (N, C, 3)
        ends = np.stack([self._point(c.end, markers) for c in self.capsules], axis=1)
        side = camera.view_matrix()[0, :3]  # the camera's right axis in the world: a radius across the view
        radius = self._radius[None, :, None]
        points = np.concatenate([starts, ends, starts + radius * side, ends + radius * side], axis=1)
        pixels = camera.project(points.reshape(-1, 3)).reshape(n, 4, len(self.capsules), 2)
        a, b = pixels[:, 0], pixels[:, 1]                                     # (N, C, 2)
        rho_a = np.linalg.norm(pixels[:, 2] - a, axis=2)                      # projected radii (px)
        rho_b = np.linalg.norm(pixels[:, 3] - b, axis=2)
        axis = b - a
        length = np.linalg.norm(axis, axis=2, keepdims=True)
        direction = np.where(length > 1e-9, axis / np.maximum(length, 1e-9), np.array([1.0, 0.0]))
        normal = np.stack([-direction[..., 1], direction[..., 0]], axis=2)
        t = np.linspace(0.0, 1.0, self.points_per_side)[None, None, :, None]  # (1, 1, K, 1)
        centre = a[:, :, None] + t * axis[:, :, None]
        rho = (1.0 - t) * rho_a[:, :, None, None] + t * rho_b[:, :, None, None]
        left = centre + rho * normal[:, :, None]
        right = centre - rho * normal[:, :, None]
        caps = np.stack([a - rho_a[..., None] * direction, b + rho_b[..., None] * direction], axis=2)
        return np.concatenate([left, right, caps], axis=2).reshape(n, -1, 2)

    def draw(self, image: np.ndarray, markers: np.ndarray, camera: Projector, color: tuple[int, int, int],
             filled: bool = False, thickness: int = 1) -> np.ndarray:
        """``image`` (H, W, 3) uint8 with one body (markers ``(M, 3)``) drawn on it: each capsule's outline
        (or, ``filled``, its silhouette, nearest capsule last)."""
        out = np.ascontiguousarray(image).copy()
        k = self.points_per_side
        outline = self.contour(np.asarray(markers, float)[None], camera)[0].reshape(len(self.capsules), -1, 2)
        for capsule in outline:
            left, right, caps = capsule[:k], capsule[k:2 * k], capsule[2 * k:]
            polygon = np.vstack([caps[:1], left, caps[1:], right[::-1]])
            if not np.all(np.isfinite(polygon)) or np.abs(polygon).max() > 1e5:
                continue
            points = np.rint(polygon).astype(np.int32)
            if filled:
                cv2.fillPoly(out, [points], color, lineType=cv2.LINE_AA)
            else:
                cv2.polylines(out, [points], True, color, thickness, lineType=cv2.LINE_AA)
        return out
