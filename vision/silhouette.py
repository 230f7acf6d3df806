"""The person's silhouette by background subtraction: each image against a picture of the empty scene.

Edges alone cannot place an arm in front of a trunk of the same colour (neither has an edge there), and
they reward any contour that lies on the table's clutter. The silhouette says where the person is: a
body pose should lie on the foreground, and the foreground should be covered by it (both directions, as
silhouette likelihoods in human tracking do). ``F`` is 1 where the image differs from the background by
more than ``threshold`` (max over colour channels, after a light blur that keeps image noise below it),
opened to drop specks, then softened so that F reads as "how surely the person is here".
"""

from __future__ import annotations

import cv2
import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.edges import check_image

__all__ = ["BackgroundSubtractor"]

THRESHOLD = 0.06  # share of full intensity: 5 sigma of the difference of two lightly blurred images with 3 % noise
DENOISE_SIGMA_PX = 1.0  # blur of both images before the difference (image noise is per pixel)
SOFTEN_SIGMA_PX = 1.0  # blur of the thresholded mask: a sample a pixel off the outline half counts


class BackgroundSubtractor:
    """Foreground masks against one picture of the empty scene (``background``, from the same camera)."""

    def __init__(self, background: np.ndarray, threshold: float = THRESHOLD) -> None:
        if not (0.0 < threshold < 1.0):
            raise InvalidInputError(f"threshold must be in (0, 1) (share of full intensity); got {threshold!r}")
        self.threshold = float(threshold)
        self._background = self._denoised(background)

    @staticmethod
    def _denoised(image: np.ndarray) -> np.ndarray:
        """The image blurred, as uint8 (0-255: cheaper to blur and subtract than floats)."""
        arr = check_image(image)
        if arr.dtype != np.uint8:
            arr = np.rint(np.clip(arr, 0.0, 1.0) * 255.0).astype(np.uint8)
        if arr.ndim == 3:
            arr = np.ascontiguousarray(arr[..., :3])
        return cv2.GaussianBlur(arr, (0, 0), DENOISE_SIGMA_PX)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        """F (H, W) float32 in [0, 1] for a camera image the background's size."""
        now = self._denoised(image)
        if now.shape != self._background.shape:
            raise InvalidInputError(f"an image must have the background's size and channels "
                                    f"{self._background.shape}; got {now.shape}")
        difference = cv2.absdiff(now, self._background)
        if difference.ndim == 3:  # the largest channel (cv2: numpy's max over 3 channels is slow)
            red, green, blue = cv2.split(difference)
            difference = cv2.max(cv2.max(red, green), blue)
        mask = (difference > 255.0 * self.threshold).astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        return cv2.GaussianBlur(mask.astype(np.float32), (0, 0), SOFTEN_SIGMA_PX)
