"""The edge image G of the paper's observation model: 1 - G(c) reads as a pixel's distance to an edge.

A normalised gradient image (Sobel), values above ``threshold`` set to 1, smoothed with a Gaussian mask
and normalised again: 0 far from any edge, 1 on a strong one, falling off over ``blur_sigma_px``.
"""

from __future__ import annotations

import cv2
import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["as_float_image", "check_image", "edge_image"]

THRESHOLD = 0.25  # share of the strongest gradient above which a pixel counts as a full edge
BLUR_SIGMA_PX = 2.0  # how far (px) an edge's pull reaches: a contour a few pixels off still scores


def check_image(image: np.ndarray) -> np.ndarray:
    """``image`` as an array once checked: (H, W) grey or (H, W, 3|4) colour, H, W >= 8, uint8 or finite float."""
    arr = np.asarray(image)
    if arr.ndim not in (2, 3) or (arr.ndim == 3 and arr.shape[2] not in (3, 4)) or min(arr.shape[:2]) < 8:
        raise InvalidInputError(f"an image must be (H, W) grey or (H, W, 3|4) colour with H, W >= 8; "
                                f"got shape {arr.shape}")
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError("a float image must be finite (no NaN or inf)")
    elif arr.dtype != np.uint8:
        raise InvalidInputError(f"an image must be uint8 (0-255) or float (0-1); got dtype {arr.dtype}")
    return arr


def as_float_image(image: np.ndarray) -> np.ndarray:
    """A float32 grey image (H, W) in [0, 1] from uint8 or float RGB(A) / grey input, checked."""
    arr = check_image(image)
    scale = np.float32(1.0 / 255.0 if arr.dtype == np.uint8 else 1.0)
    if arr.ndim == 3:  # the channels' mean in one pass (numpy's mean over 3 is slow)
        return cv2.transform(np.ascontiguousarray(arr[..., :3], dtype=np.float32), np.full((1, 3), scale / 3.0))
    return arr.astype(np.float32) * scale


def edge_image(image: np.ndarray, threshold: float = THRESHOLD, blur_sigma_px: float = BLUR_SIGMA_PX) -> np.ndarray:
    """G (H, W) float32 in [0, 1] for a camera image; an image without any gradient raises InvalidInputError."""
    if not (0.0 < threshold <= 1.0) or not (blur_sigma_px > 0.0 and np.isfinite(blur_sigma_px)):
        raise InvalidInputError(f"threshold must be in (0, 1] and blur_sigma_px > 0; "
                                f"got {threshold!r}, {blur_sigma_px!r}")
    gray = as_float_image(image)
    # the magnitude by numpy: cv2.magnitude's first call in a process rounds differently from later ones
    gradient = np.hypot(cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3))
    peak = float(gradient.max())
    if peak <= 1e-6:
        raise InvalidInputError("the image has no edges (it is uniform, e.g. all black): nothing to track")
    normalised = gradient / peak
    normalised[normalised >= threshold] = 1.0
    smoothed = cv2.GaussianBlur(normalised, (0, 0), blur_sigma_px)
    return smoothed / float(smoothed.max())
