"""Hand paths from the learned models: the rescaling onto endpoints, the scene map, the retiming."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.controllers.hand_control import HAND_LIMITS
from hoap_actions.envs import scene, world
from hoap_actions.models.shipped import load_default_models
from hoap_actions.policies.phmm_paths import PHMMPaths, SceneMap, carry_action, over_the_table, warp
from hoap_actions.primitives.discovery.estimator import MANIPULATION


@pytest.fixture(scope="module")
def models():
    return load_default_models()


@pytest.fixture(scope="module")
def paths(models):
    return PHMMPaths(models)


def test_warp_hits_both_endpoints_and_leaves_them_in_the_paths_own_direction():
    t = np.linspace(0.0, 1.0, 201)
    path = np.c_[t, np.sin(np.pi * t) * 0.2, np.zeros_like(t)]
    start, end = np.array([0.1, -0.05, 0.02]), np.array([0.8, 0.1, -0.03])
    moved = warp(path, start, end)
    np.testing.assert_allclose(moved[0], start, atol=1e-12)
    np.testing.assert_allclose(moved[-1], end, atol=1e-12)
    # zero-slope blend: the first and last steps are the original path's steps (to second order)
    np.testing.assert_allclose(moved[1] - moved[0], path[1] - path[0], atol=1e-6)
    np.testing.assert_allclose(moved[-1] - moved[-2], path[-1] - path[-2], atol=1e-6)
    # a path already on its endpoints is left alone
    np.testing.assert_allclose(warp(path, path[0], path[-1]), path, atol=1e-15)


def test_scene_map_is_the_worlds_map_across_the_table_and_inverts(models):
    scene_map = SceneMap.for_models(models)
    assert scene_map.scale[0] == scene_map.scale[1] == world.HUMAN_TO_ROBOT_SCALE
    points = np.random.default_rng(0).normal(size=(10, 3))
    np.testing.assert_allclose(scene_map.to_human(scene_map.to_robot(points)), points, atol=1e-12)
    # the carry's learned lift becomes the lift over the board plus the clearance
    lift = models.action_lifts_[carry_action(models)]
    assert scene_map.scale[2] * lift == pytest.approx(scene.BOARD_SIZE[2] + 0.01)


def test_the_carry_is_the_manipulation_that_lifts_highest(models):
    carry = carry_action(models)
    assert models.actions_[carry].kind == MANIPULATION
    others = [models.action_lifts_[a] for a, m in models.actions_.items() if m.kind == MANIPULATION and a != carry]
    assert models.action_lifts_[carry] > max(others)


def test_over_the_table_cuts_the_part_under_the_table_top():
    z = np.array([-0.3, -0.1, 0.05, 0.2, 0.1, -0.05, -0.2])
    path = np.c_[np.zeros(7), np.zeros(7), z]
    np.testing.assert_array_equal(over_the_table(path, first=True)[:, 2], z[2:])
    np.testing.assert_array_equal(over_the_table(path, first=False)[:, 2], z[:5])
    high = path + [0, 0, 1.0]
    assert over_the_table(high, first=True) is high


def test_primitives_start_and_end_exactly_where_asked(paths):
    start, grasp = np.array([-0.077, -0.069, 0.043]), np.array([0.0, -0.03, 0.038])
    end = np.array([0.03, 0.05, 0.055])
    for path, a, b in ((paths.approach(start, grasp), start, grasp),
                       (paths.move(grasp, end, grasp - [0, 0, 0.013], end - [0, 0, 0.03]), grasp, end),
                       (paths.remove(end, start), end, start)):
        np.testing.assert_allclose(path[0], a, atol=1e-12)
        np.testing.assert_allclose(path[-1], b, atol=1e-12)


def test_the_move_lifts_the_peg_over_the_board(paths):
    grasp, end = np.array([0.0, -0.03, 0.038]), np.array([0.03, 0.05, 0.055])
    path = paths.move(grasp, end, grasp, end)
    assert path[:, 2].max() - grasp[2] > scene.BOARD_SIZE[2]


def test_timed_paths_keep_the_hand_limits(paths):
    path = paths.approach(np.array([-0.077, -0.069, 0.043]), np.array([0.0, -0.03, 0.038]))
    timed = paths.timed(path)
    np.testing.assert_allclose(timed[0], path[0], atol=1e-9)
    np.testing.assert_allclose(timed[-1], path[-1], atol=1e-9)
    speed = np.abs(np.diff(timed, axis=0)) / paths.dt  # per axis, as the limits are
    assert speed.max() <= HAND_LIMITS.velocity * 1.001
