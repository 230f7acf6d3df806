"""Where the robot's block is and how it is turned, from one overhead rgb-d image.

The block of ``Imitate-v0`` is a yellow cube on the robot's table; the pegs are red, green and blue and
the board, table and robot dull, so its colour alone finds it. Its top face is the part of that blob
whose depth puts it at the cube's height: each such pixel's ray is taken to the plane of the top face,
the face's centre is their mean and its turn about the vertical the angle of their smallest enclosing
rectangle (OpenCV's ``minAreaRect``). A cube looks the same turned by a quarter turn, so the yaw is
given modulo 90 degrees, in [-45, 45). A hand over the block hides part of its top: the detection
says whether the whole face was seen (its rectangle a cube's face in size).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from hoap_actions.envs.camera import PIXEL_SAMPLE_UV, Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.perception import backproject, rays_to_plane

__all__ = ["BLOCK_HSV_RANGE", "BlockDetection", "locate_block"]

BLOCK_HSV_RANGE = ((15, 120, 80), (35, 255, 255))
"""OpenCV HSV (hue 0-180) bounds of the block's yellow (rendered at hue 25, saturation 229 from the
overhead camera); the pegs' hues are 0, 60 and 120, the table's 16 at saturation 106."""
TOP_TOLERANCE = 0.003  # m, a pixel's point this near the top face's height belongs to it
MIN_TOP_PIXELS = 12  # fewer top-face pixels than this is not a block seen (a full face is ~280 at 320 x 240)
FACE_SIZE_TOLERANCE = 0.003  # m, a seen top face at most this short of the cube's edge on either side counts as whole


@dataclass(frozen=True)
class BlockDetection:
    """A located block: its centre ``position_m`` (3,) (m, world), its ``yaw_rad`` about the vertical
    modulo a quarter turn, in [-pi/4, pi/4), the ``top_pixels`` its top face covers and whether that face
    was seen ``whole`` (else a hand hid part of it and the centre and yaw are less sure)."""

    position_m: np.ndarray
    yaw_rad: float
    top_pixels: int
    whole: bool


def _wrap_quarter(angle: float) -> float:
    """An angle (rad) taken into [-pi/4, pi/4) modulo pi/2."""
    return float((angle + np.pi / 4) % (np.pi / 2) - np.pi / 4)


def locate_block(rgb: np.ndarray, depth: np.ndarray, camera: Camera, size: float = 0.02,
                 hsv_range: tuple[tuple[int, int, int], tuple[int, int, int]] = BLOCK_HSV_RANGE
                 ) -> BlockDetection | None:
    """The block in an rgb (H, W, 3) uint8 and depth (H, W, m along the view axis) image of ``camera``,
    a cube of edge ``size`` (m) resting on the table (z = 0); None when no top face of it is seen."""
    if not isinstance(camera, Camera):
        raise InvalidInputError(f"camera must be a hoap_actions.envs.camera.Camera; got {type(camera).__name__}")
    shape = (camera.height, camera.width)
    if not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8 or rgb.shape[:2] != shape or rgb.ndim != 3:
        raise InvalidInputError(f"rgb must be a uint8 array of shape {(*shape, 3)}; got "
                                f"{getattr(rgb, 'dtype', type(rgb).__name__)} {getattr(rgb, 'shape', '')}")
    if not isinstance(depth, np.ndarray) or depth.shape != shape:
        raise InvalidInputError(f"depth must be an array of shape {shape} in metres; got "
                                f"{getattr(depth, 'shape', type(depth).__name__)}")
    if not (np.isfinite(size) and size > 0.0):
        raise InvalidInputError(f"size must be the cube's edge in metres (> 0); got {size!r}")
    hsv = cv2.cvtColor(np.ascontiguousarray(rgb[..., :3]), cv2.COLOR_RGB2HSV)
    v, u = np.nonzero(cv2.inRange(hsv, *(np.array(bound, np.uint8) for bound in hsv_range)))
    if len(u) < MIN_TOP_PIXELS:
        return None
    su, sv = PIXEL_SAMPLE_UV  # where in a pixel the renderer samples (perception's measured convention)
    points = backproject(camera, u + su, v + sv, depth[v, u])
    top = np.abs(points[:, 2] - size) <= TOP_TOLERANCE
    if top.sum() < MIN_TOP_PIXELS:
        return None
    u, v = u[top], v[top]
    # keep the largest 8-connected piece of the top face: a stray yellow speck does not pull the centre
    mask = np.zeros(shape, np.uint8)
    mask[v, u] = 1
    count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    keep = labels[v, u] == biggest
    if keep.sum() < MIN_TOP_PIXELS:
        return None
    u, v = u[keep], v[keep]
    # each pixel's footprint on the face's plane: its sample point and its corners, so the rectangle spans the face
    corners = np.array([[0.0, 0.0], [-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5], [0.5, 0.5]]) + [su, sv]
    on_face = rays_to_plane(camera, u[None] + corners[:, :1], v[None] + corners[:, 1:], size)  # (5, N, 3)
    centre_xy = on_face[0, :, :2].mean(axis=0)
    (_, _), (width, height), angle = cv2.minAreaRect(on_face[1:, :, :2].reshape(-1, 2).astype(np.float32))
    yaw = _wrap_quarter(np.radians(angle))
    whole = bool(min(width, height) >= size - FACE_SIZE_TOLERANCE)  # a hidden part of the face shortens a side
    return BlockDetection(position_m=np.array([*centre_xy, size / 2.0]), yaw_rad=yaw, top_pixels=int(len(u)),
                          whole=whole)
