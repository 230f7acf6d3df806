"""The block located by its colour in the demonstration camera and taken back onto the table."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA, DemoScene
from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.objects import ObjectLocator


@pytest.fixture(scope="module")
def scene():
    scene = DemoScene()
    yield scene
    scene.close()


@pytest.mark.parametrize("xy", [(0.0, 0.0), (0.12, -0.25), (-0.1, 0.3)])
def test_the_block_is_found_where_it_stands(scene, xy):
    scene.reset(np.array(xy))
    locate = ObjectLocator(DEMONSTRATOR_CAMERA, scene.config.object_size / 2.0)
    found = locate(scene.render(DEMONSTRATOR_CAMERA).rgb)
    assert found is not None
    assert np.linalg.norm(found[:2] - xy) < 0.003  # the visible faces' centroid: 0.2-1.1 mm from the centre here
    assert found[2] == pytest.approx(scene.config.object_size / 2.0)


@pytest.mark.parametrize("xy", [(0.0, 0.0), (-0.1, 0.3)])
def test_the_renderer_shows_a_point_at_the_cameras_pixel(scene, xy):
    """Known answer of the renderer's convention: the block's lit top face centres on Camera.pixels of the
    face's centre within a fifth of a pixel (Camera.project puts it a row lower)."""
    scene.reset(np.array(xy))
    size = scene.config.object_size
    image = scene.render(DEMONSTRATOR_CAMERA).rgb
    labels, biggest, hsv, _ = ObjectLocator(DEMONSTRATOR_CAMERA, size)._blob(image)
    v, u = np.nonzero((labels == biggest) & (hsv[..., 2] >= 170))
    centre = np.array([[*xy, size]])
    np.testing.assert_allclose([u.mean(), v.mean()], DEMONSTRATOR_CAMERA.pixels(centre)[0], atol=0.2)
    assert DEMONSTRATOR_CAMERA.project(centre)[0, 1] - v.mean() > 0.7  # project() alone misses it by a row


def test_a_block_the_hand_half_hides_is_seen_but_not_whole(scene):
    """A blob with half its pixels covered is centimetres from the block's centre: a locator told the cube's
    size sights it as partly hidden, and the uncovered block as whole (its blob fills its smallest outline)."""
    scene.reset(np.array([0.05, 0.1]))
    half = scene.config.object_size / 2.0
    image = scene.render(DEMONSTRATOR_CAMERA).rgb
    cube = ObjectLocator(DEMONSTRATOR_CAMERA, half, cube_half_size_m=half)
    centre, whole = cube.sighting(image)
    assert whole and np.linalg.norm(centre[:2] - [0.05, 0.1]) < 0.003
    np.testing.assert_array_equal(centre, cube(image))
    labels, biggest, _, _ = cube._blob(image)
    assert np.count_nonzero(labels == biggest) >= 0.9 * cube.smallest_outline_px(centre)
    v, u = np.nonzero(labels == biggest)
    covered = image.copy()
    covered[v[u < np.median(u)], u[u < np.median(u)]] = (200, 160, 140)  # skin over its left half
    sliver, whole = cube.sighting(covered)
    assert not whole and np.linalg.norm(sliver[:2] - [0.05, 0.1]) > 0.01
    assert cube.sighting(scene.render_background(DEMONSTRATOR_CAMERA).rgb) == (None, False)
    with pytest.raises(InvalidInputError, match="cube_half_size_m"):
        ObjectLocator(DEMONSTRATOR_CAMERA, half, cube_half_size_m=0.0)
    with pytest.raises(InvalidInputError, match="cube_half_size_m"):
        ObjectLocator(DEMONSTRATOR_CAMERA, half).sighting(image)


def test_no_block_in_view_is_none_and_the_homography_is_exact(scene):
    locate = ObjectLocator(DEMONSTRATOR_CAMERA, 0.025)
    assert locate(scene.render_background(DEMONSTRATOR_CAMERA).rgb) is None
    points = np.array([[0.1, -0.2, 0.025], [-0.2, 0.3, 0.025]])
    np.testing.assert_allclose(locate.to_plane(DEMONSTRATOR_CAMERA.pixels(points)), points, atol=1e-6)


def test_bad_images_are_refused():
    locate = ObjectLocator(DEMONSTRATOR_CAMERA, 0.025)
    with pytest.raises(InvalidInputError, match="colour image"):
        locate(np.zeros((DEMONSTRATOR_CAMERA.height, DEMONSTRATOR_CAMERA.width), np.uint8))
    with pytest.raises(InvalidInputError, match="colour image"):
        locate(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(InvalidInputError, match="plane_z"):
        ObjectLocator(DEMONSTRATOR_CAMERA, float("nan"))


@pytest.mark.parametrize("xy, yaw_deg", [((0.0, 0.0), 0.0), ((0.12, -0.25), 20.0), ((-0.1, 0.3), -35.0),
                                         ((0.05, 0.1), 60.0)])
def test_the_top_face_gives_the_blocks_place_and_its_turn_modulo_a_quarter(scene, xy, yaw_deg):
    scene.reset(np.array(xy), np.radians(yaw_deg))
    size = scene.config.object_size
    face = ObjectLocator(DEMONSTRATOR_CAMERA, size).top_face(scene.render(DEMONSTRATOR_CAMERA).rgb)
    assert face is not None
    assert np.linalg.norm(face.centre[:2] - xy) < 0.015 and face.centre[2] == pytest.approx(size)
    quarter_error = np.angle(np.exp(4j * (face.yaw - np.radians(yaw_deg)))) / 4.0
    assert abs(np.degrees(quarter_error)) < 6.0  # a face of 40-70 pixels at 320 x 240: 1.4-5.5 degrees off here
    assert -np.pi / 4 <= face.yaw < np.pi / 4


def test_no_block_no_top_face(scene):
    assert ObjectLocator(DEMONSTRATOR_CAMERA, 0.05).top_face(scene.render_background(DEMONSTRATOR_CAMERA).rgb) is None
