"""Where the manipulated block is: its colour in the camera image, taken back onto the plane of its centre.

An approach ends at the object it reaches for, and a manipulation starts there. The arm's first frames
say little about which way it goes, and particles that have agreed on a wrong goal are not drawn back by
the arm's contour alone; the block itself is in view. :class:`ObjectLocator` finds it (the largest blob
of its colour) and returns its centre in the scene frame, for the tracker to draw goals around
(a proposal from the image, as ICONDENSATION draws particles from a detector).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.body_model import Projector
from hoap_actions.vision.edges import check_image

__all__ = ["ObjectLocator", "TopFace"]

# The demonstration block (demo_object.urdf, RGB 0.85 0.25 0.20) in OpenCV's HSV (hue 0-180): rendered at hue
# 0-6 and saturation 190-200; the skin of the hands and head is at hue 12, saturation 85, the wooden table at
# hue 16, saturation 106 (demonstration camera, validation recording).
# (low, high); red wraps round hue 0
BLOCK_HSV_RANGES = (((0, 150, 60), (8, 255, 255)), ((172, 150, 60), (180, 255, 255)))
# The block's top face is lit from above: value 200 in HSV where its sides are at 128 (demonstration camera,
# validation episodes of Imitate-v0); the pixels at or over this value are taken as the top face.
TOP_FACE_MIN_VALUE = 170
MIN_TOP_FACE_PX = 12  # a top face seen by fewer pixels (the hand over the block) gives no footprint
MIN_BLOB_PX = 6  # a 5 cm block is about 190 px at 320 x 240; fewer than this is noise or a sliver behind the hand
# A blob showing less than this share of the smallest outline a cube can have where it lies is partly hidden
# (the hand over it), and its centroid is centimetres off: on validation frames (paper 341, every 6th) blobs
# at 0.9 of it or more lay a median 0.5 mm from the block, those below 1.6-4.9 cm.
MIN_SHOWN_SHARE = 0.9
OUTLINE_YAWS = np.radians([0.0, 22.5, 45.0])  # the cube's turns over which its smallest outline is taken
PLANE_GRID_M = 0.5  # m, half-size of the square of plane points the homography is fitted on


@dataclass(frozen=True)
class TopFace:
    """The block's top face seen in an image: its ``centre`` (3,) m on the locator's plane and its turn
    about the vertical, ``yaw`` rad in [-pi/4, pi/4) (a square face shows its turn modulo a quarter)."""

    centre: np.ndarray
    yaw: float


def _turned_corners(half_size: float) -> np.ndarray:
    """The 8 corners ``(len(OUTLINE_YAWS), 8, 3)`` of a cube of ``half_size`` about its centre, at each turn."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * half_size
    c, s = np.cos(OUTLINE_YAWS), np.sin(OUTLINE_YAWS)
    turns = np.zeros((len(OUTLINE_YAWS), 3, 3))
    turns[:, 0, 0], turns[:, 0, 1], turns[:, 1, 0], turns[:, 1, 1], turns[:, 2, 2] = c, s, -s, c, 1.0
    return np.einsum("ck,tkj->tcj", corners, turns)


class ObjectLocator:
    """The block's centre (m, scene frame) from one camera image, or None when it is not seen.

    Parameters
    ----------
    camera
        the camera the images come from.
    plane_z
        height (m) of the block's centre; the blob's centroid is taken onto this plane (a
        homography: exact for a pinhole camera).
    hsv_ranges
        (low, high) OpenCV HSV bounds of the block's colour, any of which counts.
    cube_half_size_m
        the block is a cube of this half size (``plane_z`` its centre's height): :meth:`sighting` then tells a
        wholly shown block from one partly hidden (a hand over it leaves a sliver whose centroid is
        centimetres off). None (the default): the block's shape is not known.
    """

    def __init__(self, camera: Projector, plane_z: float,
                 hsv_ranges: tuple[tuple[tuple[int, int, int], tuple[int, int, int]], ...] = BLOCK_HSV_RANGES,
                 cube_half_size_m: float | None = None) -> None:
        if not np.isfinite(plane_z):
            raise InvalidInputError(f"plane_z must be a finite height in m; got {plane_z!r}")
        if cube_half_size_m is not None and not (np.isfinite(cube_half_size_m) and cube_half_size_m > 0):
            raise InvalidInputError(f"cube_half_size_m must be > 0 (m) or None; got {cube_half_size_m!r}")
        self.camera, self.plane_z = camera, float(plane_z)
        self.cube_half_size_m = None if cube_half_size_m is None else float(cube_half_size_m)
        self._turned_corners = None if cube_half_size_m is None else _turned_corners(self.cube_half_size_m)
        self.hsv_ranges = [(np.array(low, np.uint8), np.array(high, np.uint8)) for low, high in hsv_ranges]
        grid = np.linspace(-PLANE_GRID_M, PLANE_GRID_M, 5)
        plane = np.array([[x, y, self.plane_z] for x in grid for y in grid])
        pixels = np.asarray(camera.pixels(plane), float)
        seen = np.isfinite(pixels).all(axis=1)
        if seen.sum() < 4:
            raise InvalidInputError(f"the camera does not see the plane z = {plane_z} m")
        self._to_plane, _ = cv2.findHomography(pixels[seen], plane[seen, :2])

    def __call__(self, image: np.ndarray) -> np.ndarray | None:
        found = self._blob(image)
        if found is None:
            return None
        _, _, _, centroid = found
        return self.to_plane(centroid[None])[0]

    def sighting(self, image: np.ndarray) -> tuple[np.ndarray | None, bool]:
        """The blob's centre (as :meth:`__call__`) and whether the whole block shows: its blob covers at least
        :data:`MIN_SHOWN_SHARE` of the smallest outline the cube can have there (needs ``cube_half_size_m``)."""
        if self.cube_half_size_m is None:
            raise InvalidInputError("a sighting needs the block's size: make the locator with cube_half_size_m")
        found = self._blob(image)
        if found is None:
            return None, False
        labels, biggest, _, centroid = found
        centre = self.to_plane(centroid[None])[0]
        return centre, bool(np.count_nonzero(labels == biggest) >= MIN_SHOWN_SHARE * self.smallest_outline_px(centre))

    def smallest_outline_px(self, centre: np.ndarray) -> float:
        """The fewest pixels (the convex outline's area) the cube can cover in the image with its centre at
        ``centre`` (3,), over its turns about the vertical (:data:`OUTLINE_YAWS`)."""
        corners = self._turned_corners
        pixels = np.asarray(self.camera.pixels((centre + corners).reshape(-1, 3)), np.float32)
        pixels = pixels.reshape(len(corners), -1, 2)
        return float(min(cv2.contourArea(cv2.convexHull(outline)) for outline in pixels))

    def top_face(self, image: np.ndarray) -> TopFace | None:
        """The block's top face (the brightest pixels of its blob, lit from above) taken onto the plane
        z = ``plane_z`` (make the locator at the top face's height), its centre and turn from the smallest
        rectangle round it; None when fewer than :data:`MIN_TOP_FACE_PX` of it are seen."""
        found = self._blob(image)
        if found is None:
            return None
        labels, biggest, hsv, _ = found
        v, u = np.nonzero((labels == biggest) & (hsv[..., 2] >= TOP_FACE_MIN_VALUE))
        if len(u) < MIN_TOP_FACE_PX:
            return None
        points = self.to_plane(np.column_stack([u, v]).astype(float))
        (x, y), _, angle = cv2.minAreaRect(points[:, :2].astype(np.float32))
        yaw = (np.radians(angle) + np.pi / 4) % (np.pi / 2) - np.pi / 4
        return TopFace(np.array([x, y, self.plane_z]), float(yaw))

    def _blob(self, image: np.ndarray) -> tuple[np.ndarray, int, np.ndarray, np.ndarray] | None:
        """The largest blob of the block's colour: the components' labels (H, W), its label, the image in
        HSV and its centroid (u, v); None when no blob of :data:`MIN_BLOB_PX` is seen."""
        arr = check_image(image)
        if arr.ndim != 3 or arr.shape[:2] != (self.camera.height, self.camera.width):
            raise InvalidInputError(f"a colour image ({self.camera.height}, {self.camera.width}, 3) is needed; "
                                    f"got {arr.shape}")
        if arr.dtype != np.uint8:
            arr = np.rint(np.clip(arr, 0.0, 1.0) * 255.0).astype(np.uint8)
        hsv = cv2.cvtColor(np.ascontiguousarray(arr[..., :3]), cv2.COLOR_RGB2HSV)
        mask = np.zeros(hsv.shape[:2], np.uint8)
        for low, high in self.hsv_ranges:
            mask |= cv2.inRange(hsv, low, high)
        count, labels, stats, centroids = cv2.connectedComponentsWithStats(mask)
        if count < 2:
            return None
        biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        if stats[biggest, cv2.CC_STAT_AREA] < MIN_BLOB_PX:
            return None
        return labels, biggest, hsv, centroids[biggest]

    def to_plane(self, pixels: np.ndarray) -> np.ndarray:
        """The points (N, 3) of the plane z = ``plane_z`` that the camera sees at ``pixels`` (N, 2) (u, v)."""
        xy = cv2.perspectiveTransform(np.asarray(pixels, np.float64).reshape(-1, 1, 2), self._to_plane).reshape(-1, 2)
        return np.column_stack([xy, np.full(len(xy), self.plane_z)])
