"""The Fig. 9 picture: its scale bar measures what it says on the table top, and every mark is drawn."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.envs.scene import CAMERAS
from hoap_actions.policies.figures import SCALE, SCALE_BAR_M, draw_episode, scale_bar_ends
from hoap_actions.vision.perception import Detections, rays_to_plane


@pytest.mark.parametrize("name", sorted(CAMERAS))
def test_the_scale_bar_spans_its_length_on_the_table(name):
    """Taken back through the camera onto the table plane, the bar's ends are SCALE_BAR_M apart (within
    the rounding of one enlarged pixel)."""
    camera = CAMERAS[name]
    ends = scale_bar_ends(camera) / SCALE
    on_table = rays_to_plane(camera, ends[:, 0], ends[:, 1], 0.0)
    metres_per_pixel = np.linalg.norm(on_table[1] - on_table[0]) / np.linalg.norm(ends[1] - ends[0])
    assert np.linalg.norm(on_table[1] - on_table[0]) == pytest.approx(SCALE_BAR_M, abs=metres_per_pixel)
    assert np.all((ends >= 0) & (ends <= [camera.width, camera.height]))


def test_the_picture_is_the_enlarged_image_with_marks_on_it():
    camera = CAMERAS["overhead"]
    rgb = np.zeros((camera.height, camera.width, 3), np.uint8)
    image = draw_episode(rgb, camera, Detections(pegs=(), holes=()), {"approach": np.zeros((2, 3))})
    assert image.shape == (SCALE * camera.height, SCALE * camera.width, 3)
    (u0, v0), (u1, _) = scale_bar_ends(camera)
    assert image[v0, (u0 + u1) // 2].min() == 255  # the bar is white on the black image
    assert image[:150, :300].max() > 0  # the legend
