"""The demonstrator's body as capsules posed from the six arm markers, and its contour in a camera.

Each capsule joins two points (a marker, or the torso's base) with a radius. Its silhouette in a
pinhole camera is, to first order, the projected axis offset on both sides by the projected radius
(the radius divided by depth, through the camera's focal length) plus a cap at each end; the contour
is sampled there for every body of a batch at once (numpy, no rendering).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from hoap_actions.envs.camera import PIXEL_SAMPLE_UV
from hoap_actions.errors import InvalidInputError

__all__ = ["ARM_CAPSULES", "BodyModel", "Capsule", "ProjectedBodies", "Projector"]


class Projector(Protocol):
    """A pinhole camera (:class:`hoap_actions.envs.camera.Camera` is one): its image size, world points
    (N, 3) to the pixels (N, 2) (column right, row down) where its images show them, and its 4x4
    world-to-camera matrix."""

    width: int
    height: int

    def pixels(self, points: np.ndarray) -> np.ndarray: ...

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
COVER_MARGIN_PX = 1.0  # px: the denoising blur and the low threshold spread a mask past the outline (validation)
LIMB_MIN_RADIUS_M = 0.02  # fingers (1 cm) are 1-3 px wide at 320 x 240: a softened mask barely holds them
# m, points of the trunk placed from the right shoulder marker (measured on the demonstrator at rest and
# mid-reach, within 1.5 cm): the capsule end below the thorax's top (its cap reaches the top), and the
# head's axis. The trunk's base is the lumbar joint, which stays put (``torso_base``).
FROM_SHOULDER = {
    "neck": np.array([0.0, 0.227, 0.026 - 0.14]),
    "head_low": np.array([0.01, 0.227, 0.216 - 0.03]),
    "head_high": np.array([0.01, 0.227, 0.216 + 0.03]),
}


@dataclass(frozen=True)
class ProjectedBodies:
    """``N`` bodies' capsules in one image: end points ``a``, ``b`` (N, C, 2) and radii ``rho_a``, ``rho_b``
    (N, C) in pixels, the end points' heights ``z_a``, ``z_b`` (N, C, m) and their depths along the
    camera's view axis ``depth_a``, ``depth_b`` (N, C, m). Computed once per frame and shared by every
    part of the likelihood."""

    a: np.ndarray
    b: np.ndarray
    rho_a: np.ndarray
    rho_b: np.ndarray
    z_a: np.ndarray
    z_b: np.ndarray
    depth_a: np.ndarray
    depth_b: np.ndarray


class BodyModel:
    """Capsules over the markers ``marker_names`` (plus the trunk's fixed base ``torso_base``, the lumbar
    joint, m, scene frame).

    :meth:`project` puts ``N`` bodies of markers ``(N, M, 3)`` into an image; :meth:`contour` gives their
    outlines ``(N, P, 2)``, :meth:`interior` points on their limbs, :meth:`covers` which pixels they cover. With
    ``hidden_below_z`` (m, the table top), points of the body below that height are hidden by the table
    from a camera above it: :meth:`contour` and :meth:`interior` give them as NaN, so that a hand
    hanging below the table is neither rewarded nor punished by what the image shows there.
    """

    def __init__(self, marker_names: tuple[str, ...], torso_base: np.ndarray,
                 capsules: tuple[Capsule, ...] = ARM_CAPSULES, points_per_side: int = 8,
                 hidden_below_z: float | None = None) -> None:
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
        self.hidden_below_z = hidden_below_z
        self._cameras: dict = {}
        trunk_points = {"torso_base", *FROM_SHOULDER}
        self.trunk = np.array([k for k, c in enumerate(capsules) if {c.start, c.end} <= trunk_points], dtype=int)
        """Indices of the capsules placed from the trunk alone (torso, head)."""
        self.limbs = np.setdiff1d(np.flatnonzero(self._radius >= LIMB_MIN_RADIUS_M), self.trunk)
        """Indices of the capsules that move with the arm and are wide enough (``LIMB_MIN_RADIUS_M``) for
        their axis to lie surely on the person in a foreground mask."""

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

    def project(self, markers: np.ndarray, camera: Projector) -> ProjectedBodies:
        """The capsules of the bodies with markers ``(N, M, 3)`` (m, scene frame) in ``camera``'s image."""
        markers = np.asarray(markers, dtype=float)
        n = markers.shape[0]
        starts = np.stack([self._point(c.start, markers) for c in self.capsules], axis=1)  # (N, C, 3)
        ends = np.stack([self._point(c.end, markers) for c in self.capsules], axis=1)
        view, project = self._camera(camera)
        side, radius = view[0, :3], self._radius[None, :, None]
        points = np.concatenate([starts, ends, starts + radius * side, ends + radius * side], axis=1)
        pixels = project(points.reshape(-1, 3)).reshape(n, 4, len(self.capsules), 2)
        a, b = pixels[:, 0], pixels[:, 1]
        depth_a, depth_b = (-(ends_ @ view[2, :3] + view[2, 3]) for ends_ in (starts, ends))  # OpenGL: looks down -z
        return ProjectedBodies(a, b, np.linalg.norm(pixels[:, 2] - a, axis=2), np.linalg.norm(pixels[:, 3] - b, axis=2),
                               starts[..., 2], ends[..., 2], depth_a, depth_b)

    def _camera(self, camera: Projector) -> tuple[np.ndarray, Callable[[np.ndarray], np.ndarray]]:
        """``camera``'s view matrix (its first row: the right axis in the world, a radius across the view;
        its third: the view axis) and its projection, the matrices
        made once per camera (a tracker projects every particle in every frame): the same arithmetic as
        :meth:`Camera.pixels`. Projectors without ``projection_matrix`` project themselves."""
        try:
            return self._cameras[camera]
        except (KeyError, TypeError):  # TypeError: an unhashable projector, never cached
            pass
        view = camera.view_matrix()
        if not hasattr(camera, "projection_matrix"):
            return view, camera.pixels
        matrix = (camera.projection_matrix() @ view).T
        width, height = camera.width, camera.height
        sample_u, sample_v = PIXEL_SAMPLE_UV

        def project(points: np.ndarray) -> np.ndarray:
            homogeneous = np.c_[points, np.ones(len(points))] @ matrix
            ndc = homogeneous[:, :2] / homogeneous[:, 3:4]
            return np.c_[(ndc[:, 0] + 1.0) * 0.5 * width - sample_u, (1.0 - ndc[:, 1]) * 0.5 * height - sample_v]

        try:
            self._cameras[camera] = (view, project)
        except TypeError:
            pass
        return view, project

    def _hide(self, pixels: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``pixels`` (..., 2) with the points whose height ``z`` (...) is below :attr:`hidden_below_z` set to NaN."""
        if self.hidden_below_z is None:
            return pixels
        return np.where((z < self.hidden_below_z)[..., None], np.nan, pixels)

    def contour(self, bodies: ProjectedBodies, hide: bool = True) -> np.ndarray:
        """Pixels ``(N, P, 2)`` of the bodies' silhouettes; NaN where hidden by the table (``hide`` and
        :attr:`hidden_below_z`)."""
        a, b, rho_a, rho_b, z_a, z_b = bodies.a, bodies.b, bodies.rho_a, bodies.rho_b, bodies.z_a, bodies.z_b
        n = a.shape[0]
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
        pixels = np.concatenate([left, right, caps], axis=2).reshape(n, -1, 2)
        if not hide or self.hidden_below_z is None:
            return pixels
        z_side = z_a[:, :, None] + t[..., 0] * (z_b - z_a)[:, :, None]
        z = np.concatenate([z_side, z_side, np.stack([z_a, z_b], axis=2)], axis=2).reshape(n, -1)
        return self._hide(pixels, z)

    def interior(self, bodies: ProjectedBodies) -> np.ndarray:
        """Pixels ``(N, L * K, 2)`` along the projected axes of the limbs (:attr:`limbs`): where the body
        surely is, whatever the capsule's width in the image (NaN where hidden by the table)."""
        a, b, z_a, z_b = bodies.a, bodies.b, bodies.z_a, bodies.z_b
        limbs = self.limbs
        t = np.linspace(0.0, 1.0, self.points_per_side)[None, None, :, None]
        points = a[:, limbs, None] + t * (b - a)[:, limbs, None]
        z = z_a[:, limbs, None] + t[..., 0] * (z_b - z_a)[:, limbs, None]
        return self._hide(points.reshape(a.shape[0], -1, 2), z.reshape(a.shape[0], -1))

    def surface_depths(self, bodies: ProjectedBodies) -> np.ndarray:
        """``(N, L * K)`` m: how far along the camera's view axis the limbs' near surface lies at the points
        of :meth:`interior` (the axis's depth, linear along it, less the capsule's radius), for a depth
        image to be compared with."""
        limbs = self.limbs
        t = np.linspace(0.0, 1.0, self.points_per_side)[None, None, :]
        depth_a, depth_b = bodies.depth_a[:, limbs, None], bodies.depth_b[:, limbs, None]
        depth = depth_a + t * (depth_b - depth_a) - self._radius[limbs][None, :, None]
        return depth.reshape(depth.shape[0], -1)

    def covers(self, bodies: ProjectedBodies, pixels: np.ndarray, capsules: np.ndarray | None = None) -> np.ndarray:
        """``(N, P)``: whether each of ``pixels`` (P, 2) lies inside body ``n``'s silhouette (the union of
        its projected capsules, or of those indexed by ``capsules``: within the interpolated radius of the
        nearest axis point, plus ``COVER_MARGIN_PX``)."""
        a, b, rho_a, rho_b = (x.astype(np.float32) for x in (bodies.a, bodies.b, bodies.rho_a, bodies.rho_b))
        px, py = (np.asarray(pixels, np.float32)[None, :, k] for k in (0, 1))
        inside = np.zeros((a.shape[0], px.shape[1]), dtype=bool)
        for c in range(len(self.capsules)) if capsules is None else capsules:
            ux, uy = (b[:, c, k:k + 1] - a[:, c, k:k + 1] for k in (0, 1))
            dx, dy = px - a[:, c, 0:1], py - a[:, c, 1:2]
            t = np.clip((dx * ux + dy * uy) / np.maximum(ux * ux + uy * uy, 1e-6), 0.0, 1.0)
            rho = rho_a[:, c:c + 1] + t * (rho_b[:, c:c + 1] - rho_a[:, c:c + 1]) + COVER_MARGIN_PX
            inside |= (dx - t * ux) ** 2 + (dy - t * uy) ** 2 <= rho * rho
        return inside

    def draw(self, image: np.ndarray, markers: np.ndarray, camera: Projector, color: tuple[int, int, int],
             filled: bool = False, thickness: int = 1) -> np.ndarray:
        """``image`` (H, W, 3) uint8 with one body (markers ``(M, 3)``) drawn on it: each capsule's outline
        (or, ``filled``, its silhouette, nearest capsule last)."""
        out = np.ascontiguousarray(image).copy()
        k = self.points_per_side
        bodies = self.project(np.asarray(markers, float)[None], camera)
        outline = self.contour(bodies, hide=False)[0].reshape(len(self.capsules), -1, 2)
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
