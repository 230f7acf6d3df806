"""Reach-v1 draws its targets where the hand fits: never low over a peg or the board."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs import scene
from hoap_actions.envs.tasks.reach import HAND_DEPTH, HAND_REACH, hand_fits

LAYOUT = scene.DEFAULT_LAYOUT  # board centred at (0.03, 0), unrotated; pegs at x = -0.03


@pytest.mark.parametrize("target, fits", [
    ((-0.03, 0.0, 0.04), False),                                         # inside the middle peg
    ((-0.03, 0.0, scene.PEG_LENGTH + HAND_DEPTH + 0.001), True),         # just above its top with the hand
    ((-0.03, 0.0, scene.PEG_LENGTH + HAND_DEPTH - 0.001), False),
    ((-0.03 - scene.PEG_RADIUS - HAND_REACH - 0.001, 0.0, 0.03), True),  # beside it, clear of every outline
    ((0.03, 0.0, 0.04), False),                                          # low over the board
    ((0.03, 0.0, scene.BOARD_SIZE[2] + HAND_DEPTH + 0.001), True),
    # the hand would be over the board's edge
    ((0.03 - scene.BOARD_SIZE[0] / 2 - HAND_REACH + 0.001, 0.03, 0.04), False),
])
def test_known_targets(target, fits):
    assert hand_fits(np.array(target), LAYOUT) is fits


def _board_distance(xy: np.ndarray, holes: np.ndarray) -> float:
    """Distance from ``xy`` to the board's outline, the board placed from its observed hole row alone."""
    row = holes[-1, :2] - holes[0, :2]
    along = row / np.linalg.norm(row)
    local = xy - holes[:, :2].mean(axis=0)
    local = np.array([local @ np.array([along[1], -along[0]]), local @ along])  # across the row, along it
    outside = np.maximum(np.abs(local) - np.array(scene.BOARD_SIZE[:2]) / 2, 0.0)
    return float(np.hypot(*outside))


def test_every_drawn_target_fits_its_layout_and_low_targets_still_occur():
    env = gymnasium.make("hoap_actions/Reach-v1")
    heights = []
    for seed in range(40):
        obs, _ = env.reset(seed=seed)
        fields = env.unwrapped.parse_observation(obs)
        target = fields["target"]
        for peg in fields["peg_positions"]:
            if np.hypot(*(target[:2] - peg[:2])) < scene.PEG_RADIUS + HAND_REACH:
                assert target[2] >= scene.PEG_LENGTH + HAND_DEPTH
        if _board_distance(target[:2], fields["hole_positions"]) < HAND_REACH:
            assert target[2] >= scene.BOARD_SIZE[2] + HAND_DEPTH
        heights.append(target[2])
    env.close()
    assert min(heights) < 0.05 < max(heights)  # the 3-10 cm range is still drawn from, not only its top


def test_reach_v0_is_gone_with_a_pointer_to_v1():
    with pytest.raises(gymnasium.error.DeprecatedEnv, match="Reach-v1"):
        gymnasium.make("hoap_actions/Reach-v0")


def test_the_board_placed_from_its_holes_is_the_layouts_board():
    holes = np.array([[*xy, 0.0] for xy in scene.HOLE_LOCAL_XY + np.array(LAYOUT.board_xy)])  # yaw 0
    for xy in ((0.03, 0.0), (0.06, 0.0), (0.03, 0.09), (-0.01, -0.07)):
        assert _board_distance(np.array(xy), holes) == pytest.approx(
            scene.distance_to_board(np.array(xy), np.array(LAYOUT.board_xy), LAYOUT.board_yaw), abs=1e-12)
