"""A structured-light depth camera's errors, put on a rendered depth image: what an RGB-D sensor beside
the demonstration camera would deliver.

The renderer's depth is exact. A Kinect-class sensor measures disparity, so its depth is quantised in
steps that grow with the square of the distance, its noise grows the same way (Nguyen, Izadi and Lovell,
"Modeling Kinect sensor noise for improved 3D reconstruction and tracking", 3DIMPVT 2012: axial
sigma(z) = 0.0012 + 0.0019 (z - 0.4)^2 m), and it returns no depth (a hole) where the projected pattern
is lost: at depth edges, where one surface shadows another, outside its range and at scattered pixels.
Holes are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["DepthSensor"]


@dataclass(frozen=True)
class DepthSensor:
    """Errors of a structured-light depth camera (defaults: a Kinect-class sensor).

    ``noise_m`` (a, b, c): axial standard deviation ``a + b (z - c)^2`` (m); ``focal_baseline`` (px m, the
    focal length times the projector's baseline: 580 px x 7.5 cm) and ``disparity_step_px`` (1/8 px): depth
    is measured as a disparity ``focal_baseline / z`` rounded to that step, so the depth steps are about
    ``z^2 disparity_step_px / focal_baseline`` (2.9 mm at 1 m, 11 mm at 2 m; 0: not quantised); ``edge_jump_m``: a
    pixel whose depth differs from a 4-neighbour's by more than this is a hole; ``dropout``: share of other
    pixels lost at random; ``range_m``: nearest and farthest depths measured.
    """

    noise_m: tuple[float, float, float] = (0.0012, 0.0019, 0.4)
    focal_baseline: float = 43.5
    disparity_step_px: float = 0.125
    edge_jump_m: float = 0.03
    dropout: float = 0.01
    range_m: tuple[float, float] = (0.4, 4.0)

    def __post_init__(self) -> None:
        a, b, _ = self.noise_m
        near, far = self.range_m
        if not (a >= 0 and b >= 0 and self.focal_baseline > 0 and self.disparity_step_px >= 0
                and self.edge_jump_m > 0 and 0 <= self.dropout < 1 and 0 < near < far):
            raise InvalidInputError(f"a depth sensor needs noise terms >= 0, a focal baseline > 0, a disparity step "
                                    f">= 0, an edge jump > 0, a dropout in [0, 1) and 0 < near < far; got {self}")

    def measure(self, depth: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The sensor's reading (H, W) of the true depth image ``depth`` (H, W, m along the view axis):
        quantised, noisy, with holes (NaN) at depth edges, out of range and at random."""
        z = np.asarray(depth, dtype=float)
        if z.ndim != 2:
            raise InvalidInputError(f"a depth image is (H, W) metres; got shape {z.shape}")
        a, b, c = self.noise_m
        reading = z + rng.normal(0.0, 1.0, z.shape) * (a + b * (z - c) ** 2)
        if self.disparity_step_px > 0:
            with np.errstate(divide="ignore", invalid="ignore"):  # out of range: a hole below
                disparity = np.round(self.focal_baseline / reading / self.disparity_step_px) * self.disparity_step_px
                reading = self.focal_baseline / disparity
        jump = np.zeros(z.shape, dtype=bool)
        vertical = np.abs(np.diff(z, axis=0)) > self.edge_jump_m
        horizontal = np.abs(np.diff(z, axis=1)) > self.edge_jump_m
        jump[1:] |= vertical
        jump[:-1] |= vertical
        jump[:, 1:] |= horizontal
        jump[:, :-1] |= horizontal
        near, far = self.range_m
        lost = jump | (z < near) | (z > far) | ~np.isfinite(z) | (rng.random(z.shape) < self.dropout)
        return np.where(lost, np.nan, reading)
