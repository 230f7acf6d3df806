"""How well each particle's posed body explains one camera's images: the terms of the tracker's likelihood.

* **Contour** (eq. 8): the mean of ``(1 - G(c))^2`` over the body's contour points ``c`` on the edge image
  ``G``; points below the table top are not seen, points off the image count as 1.
* **Silhouette**: the share of the limbs' axis points off the person's foreground mask, plus the share of the
  person (outside the trunk) the body leaves uncovered.
* **Depth**: the mean squared difference, truncated, between a depth image and the limbs' near surface along
  their axes.

Each is a misfit per particle, 0 for a body that matches; :class:`~hoap_actions.tracking.ActionTracker`
divides each by twice its sigma squared and sums them over the views.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.body_model import BodyModel, ProjectedBodies, Projector

__all__ = ["DEPTH_TRUNCATION_M", "contour_misfit", "depth_misfit", "depths_or_holes", "image_log_likelihoods",
           "per_camera", "sample", "silhouette_misfit", "within_unit_range"]

DEPTH_TRUNCATION_M = 0.05  # a depth residual counts at most this much: an occluded or mismeasured point is not a pose
FOREGROUND_STRIDE_PX = 4  # the foreground is read on this pixel grid (a limb is 6-15 px wide at 320 x 240)
FOREGROUND_SAMPLES = 200  # at most this many foreground pixels per view are checked for cover


def per_camera(images: np.ndarray | Sequence[np.ndarray], cameras: Sequence[Projector], what: str,
               problem: Callable[[np.ndarray], str | None]) -> list[np.ndarray]:
    """One checked image per camera: the camera's size, and values that ``problem`` finds nothing wrong with
    (it says what is accepted otherwise)."""
    images = [images] if isinstance(images, np.ndarray) else list(images)
    if len(images) != len(cameras):
        raise InvalidInputError(f"give one {what} per camera ({len(cameras)}); got {len(images)}")
    for image, camera in zip(images, cameras):
        if np.shape(image) != (camera.height, camera.width):
            raise InvalidInputError(f"a {what} must be ({camera.height}, {camera.width}) for its camera; "
                                    f"got {np.shape(image)}")
        wrong = problem(np.asarray(image))
        if wrong:
            raise InvalidInputError(f"a {what} must hold {wrong}")
    return images


def visible_mean(values: np.ndarray) -> np.ndarray:
    """Row means over the finite entries (NaN: hidden points); 1 for a row with none (nothing seen)."""
    seen = np.isfinite(values)
    count = seen.sum(axis=1)
    return np.where(count > 0, np.where(seen, values, 0.0).sum(axis=1) / np.maximum(count, 1), 1.0)


def sample(image: np.ndarray, pixels: np.ndarray, camera: Projector, outside: float = 0.0) -> np.ndarray:
    """``image`` at the nearest pixel of each of ``pixels`` (..., 2): ``outside`` off the image, NaN for NaN
    (hidden) pixels."""
    hidden = ~np.isfinite(pixels).all(axis=-1)
    u = np.rint(np.where(hidden, -1.0, pixels[..., 0])).astype(np.int64)
    v = np.rint(np.where(hidden, -1.0, pixels[..., 1])).astype(np.int64)
    inside = (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    values = np.full(u.shape, float(outside))
    values[inside] = image[v[inside], u[inside]]
    values[hidden] = np.nan
    return values


def contour_misfit(body: BodyModel, bodies: ProjectedBodies, edges: np.ndarray, camera: Projector) -> np.ndarray:
    """Per particle: eq. (8)'s mean ``(1 - G(c))^2`` over the visible contour points on the edge image."""
    return visible_mean((1.0 - sample(edges, body.contour(bodies), camera)) ** 2)


def silhouette_misfit(body: BodyModel, bodies: ProjectedBodies, mean_pose: np.ndarray, mask: np.ndarray,
                      camera: Projector) -> np.ndarray:
    """Per particle: the share of its visible limb axis points off the foreground, plus the share of the
    foreground (sampled on a grid, outside the trunk of ``mean_pose`` (M, 3), the particles' mean) its body
    leaves uncovered; 0 for a pose that matches the silhouette."""
    off_person = visible_mean(1.0 - sample(mask, body.interior(bodies), camera))
    v, u = np.nonzero(mask[::FOREGROUND_STRIDE_PX, ::FOREGROUND_STRIDE_PX] > 0.5)
    pixels = np.stack([u, v], axis=1) * FOREGROUND_STRIDE_PX
    pixels = pixels[~body.covers(body.project(mean_pose[None], camera), pixels, body.trunk)[0]]
    if not len(pixels):  # no one beside the trunk: nothing for an arm to cover
        return off_person
    keep = np.unique(np.linspace(0, len(pixels) - 1, min(len(pixels), FOREGROUND_SAMPLES)).astype(int))
    return off_person + 1.0 - np.mean(body.covers(bodies, pixels[keep]), axis=1)


def depth_misfit(body: BodyModel, bodies: ProjectedBodies, depth: np.ndarray, camera: Projector) -> np.ndarray:
    """Per particle (m^2): the mean squared difference, each truncated at :data:`DEPTH_TRUNCATION_M`, between
    the measured depth at its limbs' axis points and its limbs' near surface there; points hidden by the
    table, off the image or where the sensor measured nothing are left out (none left: 0)."""
    measured = sample(depth, body.interior(bodies), camera, outside=np.nan)
    residual = np.minimum(np.square(measured - body.surface_depths(bodies)), DEPTH_TRUNCATION_M**2)
    seen = np.isfinite(residual)
    return np.where(seen, residual, 0.0).sum(axis=1) / np.maximum(seen.sum(axis=1), 1)


def image_log_likelihoods(body: BodyModel, cameras: list[Projector], markers: np.ndarray, images: list[np.ndarray],
                          masks: list[np.ndarray] | None, depths: list[np.ndarray] | None, mean_pose: np.ndarray | None,
                          sigmas: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray | None]:
    """Per particle of poses ``markers`` (n, M, 3), the log-likelihood of the colour terms (edges, and silhouettes
    with ``masks``; ``mean_pose`` the particles' weighted mean) and of the depth terms (None without ``depths``),
    summed over the views, each misfit over twice its sigma squared (``sigmas``: edges, silhouette, depth); each
    body projected once."""
    edge_sigma, silhouette_sigma, depth_sigma = sigmas
    colour = np.zeros(len(markers))
    depth = None if depths is None else np.zeros(len(markers))
    for k, (image, camera) in enumerate(zip(images, cameras)):
        bodies = body.project(markers, camera)
        colour -= contour_misfit(body, bodies, image, camera) / (2.0 * edge_sigma**2)
        if masks is not None:
            colour -= silhouette_misfit(body, bodies, mean_pose, masks[k], camera) / (2.0 * silhouette_sigma**2)
        if depths is not None:
            depth -= depth_misfit(body, bodies, depths[k], camera) / (2.0 * depth_sigma**2)
    return colour, depth


def within_unit_range(image: np.ndarray) -> str | None:
    """What is wrong with an edge image or foreground mask, None if nothing (values in [0, 1])."""
    low, high = np.min(image), np.max(image)  # a NaN makes both NaN: the comparisons then fail
    return None if low >= 0.0 and high <= 1.0 else "finite values in [0, 1]"


def depths_or_holes(image: np.ndarray) -> str | None:
    """What is wrong with a depth image, None if nothing (depths > 0 m, NaN where none was measured)."""
    wrong = np.any(image <= 0.0) or np.any(np.isinf(image))
    return "depths > 0 (m) or NaN where none was measured" if wrong else None
