"""Pinhole cameras fixed in the world and the images they give: view and projection matrices (OpenGL
convention), world points to pixels, and the image sizes the renderer accepts."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["MAX_IMAGE_SIDE", "PIXEL_SAMPLE_UV", "Camera", "CameraImage", "check_image_size"]

MAX_IMAGE_SIDE = 4096  # px, largest camera width or height: TinyRenderer allocates the whole frame up front
# Where in the continuous image of Camera.project TinyRenderer samples pixel (row r, column c):
# at (c + 0, r + 1), not at the pixel's centre (c + 0.5, r + 0.5); measured on the robot's pegs and holes
# (seeds 0-49: centre sampling put every one 0.6 mm, half a pixel, off along both axes) and on the
# demonstration's block (paper 300: its top face one row above where project() puts it).
PIXEL_SAMPLE_UV = (0.0, 1.0)


BYTES_PER_PIXEL = 64
"""Memory one rendered pixel takes at its peak: TinyRenderer's colour, depth and segmentation
buffers, PyBullet's Python lists of them and the arrays made from those (measured: 62 bytes at
2048 x 1536)."""


def check_image_size(width: object, height: object, what: str = "camera") -> None:
    """Image sides must be whole pixels in 1..:data:`MAX_IMAGE_SIDE` (PyBullet aborts the process on
    negative sizes), and a frame must fit in the memory this machine has free (a render the machine
    cannot hold would end in the kernel's out-of-memory kill, not an error)."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= MAX_IMAGE_SIDE:
            raise InvalidInputError(f"{what} {name} must be an integer number of pixels in 1..{MAX_IMAGE_SIDE}; got "
                                    f"{value!r}")
    needed, free = int(width) * int(height) * BYTES_PER_PIXEL, _free_memory()
    if free is not None and needed > free:
        raise InvalidInputError(f"a {width} x {height} {what} image needs about {needed / 2**20:.0f} MiB to render; "
                                f"this machine has {free / 2**20:.0f} MiB free: choose a smaller size")


def _free_memory() -> int | None:
    """Bytes of memory available now (free and reclaimable), or None where the system does not say."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


@dataclass(frozen=True)
class Camera:
    """A pinhole camera fixed in the world: eye and target points (m), vertical field of view (deg)."""

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fov_deg: float = 60.0
    near: float = 0.02
    far: float = 3.0
    width: int = 320
    height: int = 240

    def __post_init__(self) -> None:
        check_image_size(self.width, self.height)
        eye, target, up = (np.asarray(v, float) for v in (self.eye, self.target, self.up))
        if any(v.shape != (3,) or not np.all(np.isfinite(v)) for v in (eye, target, up)):
            raise InvalidInputError("camera eye, target and up must be finite 3-vectors (m)")
        if np.linalg.norm(target - eye) < 1e-9 or np.linalg.norm(np.cross(target - eye, up)) < 1e-9:
            raise InvalidInputError("camera eye and target must differ, and up must not be parallel to the view "
                                    "direction")
        if not 0.0 < self.fov_deg < 180.0:
            raise InvalidInputError(f"camera fov_deg must be in (0, 180) degrees; got {self.fov_deg!r}")
        if not 0.0 < self.near < self.far < np.inf:
            raise InvalidInputError(f"camera needs 0 < near < far (m); got near={self.near!r}, far={self.far!r}")

    def view_matrix(self) -> np.ndarray:
        """4x4 world-to-camera matrix (OpenGL convention, camera looks down its -z)."""
        eye, target, up = (np.asarray(v, float) for v in (self.eye, self.target, self.up))
        forward = target - eye
        forward /= np.linalg.norm(forward)
        side = np.cross(forward, up)
        side /= np.linalg.norm(side)
        true_up = np.cross(side, forward)
        view = np.eye(4)
        view[0, :3], view[1, :3], view[2, :3] = side, true_up, -forward
        view[:3, 3] = -view[:3, :3] @ eye
        return view

    def projection_matrix(self) -> np.ndarray:
        """4x4 OpenGL perspective projection for this camera's aspect ratio."""
        aspect = self.width / self.height
        f = 1.0 / np.tan(np.radians(self.fov_deg) / 2.0)
        n, fa = self.near, self.far
        return np.array(
            [
                [f / aspect, 0.0, 0.0, 0.0],
                [0.0, f, 0.0, 0.0],
                [0.0, 0.0, (fa + n) / (n - fa), 2.0 * fa * n / (n - fa)],
                [0.0, 0.0, -1.0, 0.0],
            ]
        )

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates (u right, v down) of world points ``(N, 3)``; returns ``(N, 2)``."""
        pts = np.atleast_2d(np.asarray(points, float))
        homogeneous = np.c_[pts, np.ones(len(pts))] @ (self.projection_matrix() @ self.view_matrix()).T
        ndc = homogeneous[:, :2] / homogeneous[:, 3:4]
        u = (ndc[:, 0] + 1.0) * 0.5 * self.width
        v = (1.0 - ndc[:, 1]) * 0.5 * self.height
        return np.c_[u, v]

    def pixels(self, points: np.ndarray) -> np.ndarray:
        """Where world points ``(N, 3)`` show in the rendered image, as (column, row) coordinates ``(N, 2)``
        whose rounding is the pixel's index: :meth:`project` less :data:`PIXEL_SAMPLE_UV`."""
        return self.project(points) - np.asarray(PIXEL_SAMPLE_UV)


@dataclass(frozen=True)
class CameraImage:
    """One rendered view: ``rgb`` (H, W, 3) uint8, ``depth`` (H, W) metres, ``segmentation`` (H, W) body ids."""

    rgb: np.ndarray
    depth: np.ndarray
    segmentation: np.ndarray
