"""The object's trajectory estimated from the hand: known answers on a rigidly carried object, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.models.object_estimate import fit_grasp_offset, hand_frames, object_poses

NAMES = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")
# marker positions in the hand's own frame (m): wrist at the origin, knuckle along x, thumb in the xy plane
HAND_TEMPLATE = np.array([[-0.30, 0.05, 0.20], [-0.25, 0.0, 0.0], [0.0, 0.0, 0.0], [0.14, 0.01, -0.02],
                          [0.09, 0.0, 0.0], [0.06, 0.05, 0.0]])
OFFSET = np.array([0.07, 0.03, -0.04])  # the object's centre in the hand's frame (m)


def carried(T=120, seed=0):
    """Markers of a hand that turns and travels, and the poses of an object fixed to it at OFFSET."""
    rng = np.random.default_rng(seed)
    angles = np.cumsum(rng.normal(0, 0.02, (T, 3)), axis=0) + rng.uniform(-1, 1, 3)
    rotations = Rotation.from_rotvec(angles)
    origins = np.cumsum(rng.normal(0, 0.003, (T, 3)), axis=0) + [0.1, -0.2, 0.15]
    H = np.stack([rotations.apply(m) for m in HAND_TEMPLATE], axis=1) + origins[:, None, :]
    O = np.hstack([origins + rotations.apply(OFFSET), rotations.as_rotvec()])
    return H, O, rotations


def test_the_hand_frame_is_the_rotation_and_wrist_the_markers_were_made_with():
    H, _, rotations = carried()
    rotation, origin = hand_frames(H, NAMES)
    np.testing.assert_allclose(rotation, rotations.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(origin, H[:, 2], atol=0)


def test_the_grasp_offset_of_a_rigidly_carried_object_is_found_exactly():
    movements = [carried(seed=s)[:2] for s in range(3)]
    np.testing.assert_allclose(fit_grasp_offset(movements, NAMES), OFFSET, atol=1e-12)


def test_the_estimated_object_follows_the_hand_and_rests_outside_the_manipulation():
    H, O, rotations = carried()
    start, end = 20, 90
    poses = object_poses(H, NAMES, start, end, OFFSET)
    np.testing.assert_allclose(poses[start:end, :3], O[start:end, :3], atol=1e-12)
    relative = (rotations[start:end] * rotations[start].inv()).as_rotvec()  # turned since the hand took it
    np.testing.assert_allclose(poses[start:end, 3:], relative, atol=1e-9)
    np.testing.assert_array_equal(poses[:start], np.tile(poses[start] * [1, 1, 1, 0, 0, 0], (start, 1)))
    np.testing.assert_array_equal(poses[end:], np.tile(poses[end - 1], (len(H) - end, 1)))


@pytest.mark.parametrize("call, message", [
    (lambda H: hand_frames(H, NAMES[:5] + ("thumb",)), "thumb_tip"),
    (lambda H: hand_frames(H[:, :5], NAMES), r"\(T, 6, 3\)"),
    (lambda H: hand_frames(np.zeros_like(H), NAMES), "span no hand frame"),
    (lambda H: hand_frames(np.where(np.arange(len(H))[:, None, None] == 7, np.nan, H), NAMES), "finite"),
    (lambda H: object_poses(H, NAMES, 0, 10, [0.1, np.nan, 0.0]), "offset must be 3 finite"),
    (lambda H: object_poses(H, NAMES, 0, 10, [0.1, 0.0]), "offset must be 3 finite"),
    (lambda H: object_poses(H, NAMES, 50, 50, OFFSET), "start < end"),
    (lambda H: object_poses(H, NAMES, 0, len(H) + 1, OFFSET), "within the 120 frames"),
    (lambda H: fit_grasp_offset([], NAMES), "no manipulation frames"),
], ids=["marker-missing", "wrong-shape", "degenerate-hand", "nan-marker", "nan-offset", "short-offset", "empty-span",
        "span-too-long", "no-frames"])
def test_bad_input_is_refused_with_what_is_accepted(call, message):
    with pytest.raises(InvalidInputError, match=message):
        call(carried()[0])
