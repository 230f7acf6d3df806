"""The pose refiner: a local search of the pose estimate against the frame's images."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.envs.camera import Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.tracking.refinement import PoseRefiner
from hoap_actions.vision.body_model import BodyModel
from hoap_actions.vision.edges import edge_image
from hoap_actions.vision.fingertip import FingertipDetector
from hoap_actions.vision.silhouette import BackgroundSubtractor

MARKERS = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")
TORSO_BASE = np.array([-0.47, 0.25, -0.10])  # the demonstration scene's lumbar joint
FRONT = Camera(eye=(0.3, -0.8, 0.45), target=(-0.25, 0.05, 0.05), fov_deg=55, width=320, height=240)
SIDE = Camera(eye=(0.3, 0.9, 0.5), target=(-0.2, 0.0, 0.05), fov_deg=55, width=320, height=240)
# an arm reaching over the table (m, the demonstration scene's frame)
ARM = np.array([[-0.42, 0.02, 0.42], [-0.30, -0.10, 0.22], [-0.12, -0.06, 0.10],
                [-0.02, -0.04, 0.07], [-0.06, -0.05, 0.09], [-0.06, -0.09, 0.08]])


def _evidence(body, pose, cameras):
    """Each camera's edge image and foreground mask of the filled body ``pose`` against an empty grey table."""
    edges, masks = [], []
    for camera in cameras:
        empty = np.full((camera.height, camera.width, 3), 90, np.uint8)
        picture = body.draw(empty, pose, camera, (220, 180, 150), filled=True)
        edges.append(edge_image(picture))
        masks.append(BackgroundSubtractor(empty)(picture))
    return edges, masks


def _hand_error(pose, truth):
    return float(np.linalg.norm(pose[3] - truth[3]))


def test_the_refined_hand_is_nearer_the_true_one_than_the_estimate_it_starts_from():
    """Two views of an arm; the estimate's hand 3 cm off (three directions): each refined index tip is nearer the
    truth, on average within half the start's error; an estimate that starts on the truth stays within 1.5 cm
    (the image terms' own best pose lies about a centimetre off the drawn one)."""
    body = BodyModel(MARKERS, TORSO_BASE)
    cameras = (FRONT, SIDE)
    refiner = PoseRefiner(body, cameras)
    edges, masks = _evidence(body, ARM, cameras)
    errors = []
    for seed in range(3):
        direction = np.random.default_rng(seed).normal(size=3)
        off = refiner.posed(ARM, np.r_[0.03 * direction / np.linalg.norm(direction), 0.0, 0.0, 0.0, 0.0])[0]
        refined, theta = refiner.refine(off, edges, masks, None, np.random.default_rng(seed))
        errors.append(_hand_error(refined, ARM))
        assert errors[-1] < _hand_error(off, ARM) and theta.shape == (7,)
    assert np.mean(errors) < 0.015
    kept, _ = refiner.refine(ARM, edges, masks, None, np.random.default_rng(0))
    assert _hand_error(kept, ARM) < 0.015


def test_posed_moves_the_hand_rigidly_and_the_elbow_by_half_the_hand_s_shift():
    body = BodyModel(MARKERS, TORSO_BASE)
    refiner = PoseRefiner(body, (FRONT,))
    shift = np.array([0.02, -0.01, 0.03])
    moved = refiner.posed(ARM, np.r_[shift, 0.0, 0.0, 0.0, 0.0])[0]
    np.testing.assert_allclose(moved[2:] - ARM[2:], np.tile(shift, (4, 1)))
    np.testing.assert_allclose(moved[1] - ARM[1], shift / 2)
    np.testing.assert_allclose(moved[0], ARM[0])
    turned = refiner.posed(ARM, np.r_[0.0, 0.0, 0.0, np.pi / 2, 0.0, 0.0, 0.0])[0]
    reach = ARM[3] - ARM[2]
    np.testing.assert_allclose(turned[3] - turned[2], [-reach[1], reach[0], reach[2]], atol=1e-12)  # a quarter turn


def test_the_refiner_with_nothing_to_see_stays_near_the_estimate():
    """Blank images carry no evidence: the prior keeps the pose within a few millimetres of where it started."""
    body = BodyModel(MARKERS, TORSO_BASE)
    refiner = PoseRefiner(body, (FRONT,))
    blank = [np.zeros((FRONT.height, FRONT.width))]
    refined, _ = refiner.refine(ARM, blank, None, None, np.random.default_rng(0))
    assert np.abs(refined - ARM).max() < 0.02


def test_refiner_bad_settings():
    body = BodyModel(MARKERS, TORSO_BASE)
    with pytest.raises(InvalidInputError, match="prior_sd"):
        PoseRefiner(body, (FRONT,), prior_sd=(0.03, -1.0, 0.02))
    with pytest.raises(InvalidInputError, match="sigmas"):
        PoseRefiner(body, (FRONT,), sigmas=(0.3, 0.6))
    with pytest.raises(InvalidInputError, match="prior_sd"):
        PoseRefiner(body, (FRONT,), prior_sd="abc")
    with pytest.raises(InvalidInputError, match="samples"):
        PoseRefiner(body, (FRONT,), samples=8, elite=0.1)


def test_found_fingertips_hold_the_refined_index_tip_where_the_views_show_it():
    """With blank images only the fingertip term and the prior speak: the fingertip found at the true tip's pixels
    in two views pulls a tip 3 cm off to within a centimetre of the truth (the prior keeps a little of the offset);
    with no fingertip found the pose stays put."""
    body = BodyModel(MARKERS, TORSO_BASE)
    cameras = (FRONT, SIDE)
    refiner = PoseRefiner(body, cameras, fingertip=_DetectorStub(), fingertip_sd_px=1.0)
    blank = [np.zeros((c.height, c.width)) for c in cameras]
    off = refiner.posed(ARM, np.r_[0.03, -0.01, 0.01, 0.0, 0.0, 0.0, 0.0])[0]
    tips = np.stack([c.pixels(ARM[3][None])[0] for c in cameras])
    refined, _ = refiner.refine(off, blank, None, None, np.random.default_rng(0), tips=tips)
    assert _hand_error(refined, ARM) < 0.01 < _hand_error(off, ARM)
    unseen = np.full((2, 2), np.nan)
    stayed, _ = refiner.refine(off, blank, None, None, np.random.default_rng(0), tips=unseen)
    assert np.abs(stayed - off).max() < 0.02


def test_detect_searches_about_the_pose_s_tip_in_each_view_and_skips_views_that_miss_it():
    body = BodyModel(MARKERS, TORSO_BASE)
    far = Camera(eye=(0.3, -0.8, 0.45), target=(2.0, -3.0, 0.05), fov_deg=20, width=320, height=240)  # looks away
    refiner = PoseRefiner(body, (FRONT, far), fingertip=_DetectorStub())
    images = [np.zeros((240, 320, 3), np.uint8)] * 2
    found = refiner.detect(ARM, images)
    np.testing.assert_allclose(found[0], np.rint(FRONT.pixels(ARM[3][None])[0]) + _DetectorStub.OFFSET)
    assert np.all(np.isnan(found[1]))
    assert PoseRefiner(body, (FRONT,)).detect(ARM, images[:1]) is None
    with pytest.raises(InvalidInputError, match="fingertip"):
        PoseRefiner(body, (FRONT,), fingertip="detector")
    with pytest.raises(InvalidInputError, match="fingertip_sd_px"):
        PoseRefiner(body, (FRONT,), fingertip_sd_px=0.0)


class _DetectorStub(FingertipDetector):
    """A detector that finds the fingertip a fixed offset from wherever it looks."""

    OFFSET = np.array([2.0, -1.0])

    def predict(self, crops):
        return np.tile(self.OFFSET, (len(crops), 1))
