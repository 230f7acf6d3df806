"""Perception's fast paths give what the plain computations give: cached pixel rays, components found
in a mask's bounding box, the hue lookup table, a peg fitted in its blob's window, and the board fit's
exact residuals and Jacobian, including the retry from the other orientation."""

from __future__ import annotations

import math

import cv2
import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401 - registers the envs
from hoap_actions.envs import scene
from hoap_actions.envs.camera import Camera
from hoap_actions.vision import perception

BOARD_POSE = (0.25, 0.03, math.radians(20.0))  # x, y (m), yaw (rad) of the synthetic board
GRID_STEP = 0.0012  # m, spacing of the synthetic board's seen points: about a pixel of the overhead camera


@pytest.fixture(scope="module")
def view():
    """The overhead camera, its image of seed 0's layout and the image's world points."""
    env = gymnasium.make("hoap_actions/PegInsert-v0").unwrapped
    env.reset(seed=0)
    camera = env.sim.cameras["overhead"]
    image = env.sim.render(camera)
    env.close()
    return camera, image, perception._pixel_points(camera, image.depth)


def _board_view(seen_half_length: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Seen top-surface and nearby non-top points (world x-y) of a board at ``BOARD_POSE`` on a grid;
    with ``seen_half_length`` only its middle band |local y| <= that is seen (the rest is hidden)."""
    x0, y0, yaw = BOARD_POSE
    grid = np.arange(-0.08, 0.08, GRID_STEP)
    gx, gy = np.meshgrid(grid + x0, grid + y0)
    c, s = math.cos(yaw), math.sin(yaw)
    px, py = (gx - x0) * c + (gy - y0) * s, (gy - y0) * c - (gx - x0) * s
    half_opening = perception._opening_side() / 2
    top = (np.abs(px) <= scene.BOARD_SIZE[0] / 2) & (np.abs(py) <= scene.BOARD_SIZE[1] / 2)
    for hole_x, hole_y in scene.HOLE_LOCAL_XY:
        top &= ~((np.abs(px - hole_x) < half_opening) & (np.abs(py - hole_y) < half_opening))
    seen = np.ones_like(top) if seen_half_length is None else np.abs(py) <= seen_half_length
    near = cv2.dilate((top & seen).astype(np.uint8), np.ones((3, 3), np.uint8), iterations=4) > 0
    inside, outside = top & seen, near & ~top & seen
    return np.c_[gx[inside], gy[inside]], np.c_[gx[outside], gy[outside]]


def _plain_residuals(pose: np.ndarray, inside_xy: np.ndarray, outside_xy: np.ndarray) -> np.ndarray:
    """The board fit's residuals written over all holes at once (no gradients, no shortcuts)."""
    half_board = np.array(scene.BOARD_SIZE[:2]) / 2
    half_opening = perception._opening_side() / 2
    c, s = math.cos(pose[2]), math.sin(pose[2])
    p_in, p_out = ((xy - pose[:2]) @ np.array([[c, -s], [s, c]]) for xy in (inside_xy, outside_xy))
    rel = np.abs(p_in[:, None, :] - scene.HOLE_LOCAL_XY[None])
    depth = np.max(np.min(half_opening - rel, axis=2), axis=1).clip(min=0.0)
    beyond = np.linalg.norm(np.maximum(np.abs(p_in) - half_board, 0.0), axis=1)
    within = np.min(half_board - np.abs(p_out), axis=1).clip(min=0.0)
    rel = np.abs(p_out[:, None, :] - scene.HOLE_LOCAL_XY[None])
    to_opening = np.min(np.linalg.norm(np.maximum(rel - half_opening, 0.0), axis=2), axis=1)
    return np.concatenate([beyond + depth, np.minimum(within, to_opening)])


def _perturbed_poses(count: int) -> np.ndarray:
    rng = np.random.default_rng(3)
    return np.array(BOARD_POSE) + rng.uniform(-1, 1, (count, 3)) * [0.003, 0.003, math.radians(5.0)]


def test_pixel_points_match_backproject(view):
    camera, image, points = view
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    uv = perception.PIXEL_SAMPLE_UV
    plain = perception.backproject(camera, u + uv[0], v + uv[1], image.depth)
    np.testing.assert_allclose(points, plain, rtol=0.0, atol=1e-12)


def test_a_camera_given_with_lists_shares_the_cache_of_its_tuples(view):
    camera, image, points = view
    listed = Camera(eye=list(camera.eye), target=list(camera.target), up=list(camera.up), fov_deg=camera.fov_deg,
                    near=camera.near, far=camera.far, width=camera.width, height=camera.height)
    assert perception._camera_key(listed) == perception._camera_key(camera)
    np.testing.assert_array_equal(perception._pixel_points(listed, image.depth), points)


@pytest.mark.parametrize("density", [0.0, 0.002, 0.3, 1.0])
def test_components_in_the_bounding_box_match_the_whole_image(density):
    mask = np.random.default_rng(1).random((240, 320)) < density
    labels, stats = perception._components(mask)
    _, whole_labels, whole_stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    np.testing.assert_array_equal(labels, whole_labels)
    np.testing.assert_array_equal(stats[1:], whole_stats[1:])


def test_the_hue_lookup_matches_the_hue_distances():
    hue = np.arange(256, dtype=np.uint8)[None]
    rgb = cv2.cvtColor(np.dstack([hue, np.full_like(hue, 255), np.full_like(hue, 255)]), cv2.COLOR_HSV2RGB_FULL)
    hsv_hue = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL)[..., 0]
    distances = np.stack([perception._hue_distance_deg(hsv_hue, c) for c in perception.PEG_COLOURS_RGB.values()])
    nearest = np.argmin(distances, axis=0)
    masks = perception._colour_masks(rgb, tuple(perception.PEG_COLOURS_RGB))
    for index, name in enumerate(perception.PEG_COLOURS_RGB):
        expected = (nearest == index) & (distances[index] <= perception.MAX_HUE_DISTANCE_DEG)
        np.testing.assert_array_equal(masks[name], expected, err_msg=name)


def _whole_image_peg(colour: str, plausible: np.ndarray, points: np.ndarray) -> perception.PegDetection | None:
    """The largest blob's peg fitted on the whole image, without the window."""
    _, labels, stats, _ = cv2.connectedComponentsWithStats(plausible.astype(np.uint8), connectivity=8)
    blob = labels == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return perception._standing_peg(colour, blob, points, float(points[..., 2][blob].max()))


@pytest.mark.parametrize("finger", [False, True])
def test_a_peg_fitted_in_its_window_matches_the_whole_image(view, monkeypatch, finger):
    camera, image, points = view
    red = perception._colour_masks(image.rgb, ("red",))["red"]
    plausible = red & perception._peg_height_points(points, perception._on_table(points))
    if finger:  # raise the pixels left of the top face 1 cm: the face's rim is fitted by a circle
        points = points.copy()
        z = points[..., 2]
        face = plausible & (z >= z[plausible].max() - perception.HEIGHT_TOLERANCE)
        rows, cols = np.nonzero(face)
        left = cols == np.array([cols[rows == r].min() for r in rows])
        points[rows[left], cols[left] - 1, 2] += 0.01
        plausible = red & perception._peg_height_points(points, perception._on_table(points))
    circle_fits = []
    fit_circle = perception._fit_circle
    monkeypatch.setattr(perception, "_fit_circle", lambda *a: circle_fits.append(1) or fit_circle(*a))
    windowed = perception._locate_peg("red", plausible, points)
    whole = _whole_image_peg("red", plausible, points)
    assert bool(circle_fits) == finger
    np.testing.assert_array_equal(windowed.position_m, whole.position_m)
    assert windowed.confidence == whole.confidence


def test_board_residuals_match_the_plain_formula():
    inside, outside = _board_view()
    model = perception._BoardModel(inside, outside)
    for pose in _perturbed_poses(20):
        np.testing.assert_allclose(model.residuals(pose), _plain_residuals(pose, inside, outside), rtol=0, atol=1e-15)


def test_board_jacobian_matches_finite_differences():
    inside, outside = _board_view()
    model = perception._BoardModel(inside, outside)
    steps = np.array([1e-7, 1e-7, 1e-6])
    for pose in _perturbed_poses(10):
        residuals, jacobian = model.residuals(pose).copy(), model.jacobian(pose)
        forward = np.column_stack([(model.residuals(pose + step) - residuals) / h
                                   for step, h in zip(np.diag(steps), steps)])
        backward = np.column_stack([(residuals - model.residuals(pose - step)) / h
                                    for step, h in zip(np.diag(steps), steps)])
        smooth = np.all(np.abs(forward - backward) < 1e-4, axis=1)  # rows off the residuals' kinks
        assert smooth.mean() > 0.95
        np.testing.assert_allclose(jacobian[smooth], forward[smooth], rtol=0, atol=1e-4)


def test_a_fully_seen_board_is_fitted_from_its_rectangle_alone(monkeypatch):
    inside, outside = _board_view()
    starts = []
    fit_pose = perception._fit_pose
    monkeypatch.setattr(perception, "_fit_pose", lambda model, start: starts.append(start) or fit_pose(model, start))
    centre, yaw = perception._fit_board(inside, outside)
    assert len(starts) == 1
    assert np.linalg.norm(centre - BOARD_POSE[:2]) < 1e-4 and abs(yaw - BOARD_POSE[2]) < math.radians(0.1)


def test_a_board_seen_wider_than_long_is_fitted_from_the_other_orientation_too():
    inside, outside = _board_view(seen_half_length=0.016)  # both ends hidden: the seen part is 40 x 32 mm
    (cx, cy), (w, h), angle = cv2.minAreaRect(inside.astype(np.float32))
    rectangle_yaw = math.radians(angle) + (0.0 if h >= w else math.pi / 2)
    assert abs(math.cos(rectangle_yaw - BOARD_POSE[2])) < 0.1  # its rectangle says the board lies across
    model = perception._BoardModel(inside, outside)
    first = perception._fit_pose(model, np.array([cx, cy, rectangle_yaw]))
    assert first.cost > (len(inside) + len(outside)) * perception.BOARD_EXPLAINED_COST
    centre, yaw = perception._fit_board(inside, outside)
    assert np.linalg.norm(centre - BOARD_POSE[:2]) < 1e-4 and abs(yaw - BOARD_POSE[2]) < math.radians(0.1)


def test_locate_is_deterministic(view):
    camera, image, _ = view
    first, second = (perception.locate(image.rgb, image.depth, camera) for _ in range(2))
    for a, b in zip(first.pegs + first.holes, second.pegs + second.holes):
        np.testing.assert_array_equal(a.position_m, b.position_m)
