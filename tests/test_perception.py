"""Perception: back-projection, accuracy on a few layouts, and bad inputs (the full figures are in
benchmarks/perception_accuracy.py)."""

from __future__ import annotations

import math
from dataclasses import replace

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401 - registers the envs
from hoap_actions.envs import scene as scene_module
from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.perception import backproject, locate

PEG_BOUND = 0.002  # m, the max centre error
HOLE_BOUND = 0.002  # m
LAYOUT_SEEDS = (0, 3, 7)  # tuning seeds whose pegs stand clear of the robot's arms


@pytest.fixture(scope="module")
def env():
    environment = gymnasium.make("hoap_actions/PegInsert-v0")
    yield environment.unwrapped
    environment.close()


def overhead(env):
    camera = env.sim.cameras["overhead"]
    return camera, env.sim.render(camera)


def test_backproject_inverts_project(env):
    camera = env.sim.cameras["overhead"]
    rng = np.random.default_rng(0)
    u, v = rng.uniform(0, camera.width, 50), rng.uniform(0, camera.height, 50)
    depth = rng.uniform(camera.near, camera.far, 50)
    points = backproject(camera, u, v, depth)
    np.testing.assert_allclose(camera.project(points), np.c_[u, v], atol=1e-9)
    eye_z = (np.c_[points, np.ones(50)] @ camera.view_matrix().T)[:, 2]
    np.testing.assert_allclose(-eye_z, depth, rtol=1e-12)


@pytest.mark.parametrize("seed", LAYOUT_SEEDS)
def test_layouts_within_bounds(env, seed):
    env.reset(seed=seed)
    camera, image = overhead(env)
    found = locate(image.rgb, image.depth, camera)
    assert found.complete and not found.missing_colours
    for i, name in enumerate(env.scene.peg_names):
        peg = found.peg(name.removeprefix("peg_"))
        assert peg.standing and np.linalg.norm(peg.position_m - env.scene.peg_pose(i)[0]) <= PEG_BOUND
    true_holes = env.scene.hole_positions()
    assert len(found.holes) == len(true_holes)
    for hole in found.holes:
        assert np.min(np.linalg.norm(true_holes - hole.position_m, axis=1)) <= HOLE_BOUND


def test_lying_peg(env):
    env.reset(seed=0)
    true = env.scene.peg_pose(1)[0] * np.array([1.0, 1.0, 0.0]) + np.array([0.0, 0.0, scene_module.PEG_RADIUS])
    lying = (math.sin(math.pi / 4), 0.0, 0.0, math.cos(math.pi / 4))  # (x, y, z, w): axis along world y
    env.sim.set_base_pose(env.scene.peg_names[1], tuple(true), lying)
    camera, image = overhead(env)
    peg = locate(image.rgb, image.depth, camera, colours=("green",)).peg("green")
    assert not peg.standing and np.linalg.norm(peg.position_m - true) <= PEG_BOUND


def test_absent_colour_is_flagged_not_made_up(env):
    env.reset(seed=0)
    env.sim.set_base_pose(env.scene.peg_names[2], (1.0, 1.0, 0.025), (0.0, 0.0, 0.0, 1.0))  # out of view
    camera, image = overhead(env)
    found = locate(image.rgb, image.depth, camera, colours=("blue", "red"))
    assert found.missing_colours == ("blue",) and found.peg("blue") is None and not found.complete
    assert found.peg("red") is not None


def test_all_black_image_finds_no_peg(env):
    env.reset(seed=0)
    camera, image = overhead(env)
    found = locate(np.zeros_like(image.rgb), image.depth, camera)
    assert found.pegs == () and set(found.missing_colours) == set(scene_module.PEG_COLOURS)


def test_empty_table_has_no_board(env):
    camera = env.sim.cameras["overhead"]
    flat = np.full((camera.height, camera.width), camera.eye[2], dtype=np.float32)  # depth of the table top
    found = locate(np.zeros((camera.height, camera.width, 3), np.uint8), flat, camera)
    assert not found.board_found and found.holes == ()


def test_bad_inputs_raise(env):
    env.reset(seed=0)
    camera, image = overhead(env)
    with pytest.raises(InvalidInputError, match="uint8"):
        locate(image.rgb.astype(np.float32), image.depth, camera)
    with pytest.raises(InvalidInputError, match="shape"):
        locate(image.rgb[:-1], image.depth, camera)
    with pytest.raises(InvalidInputError, match="depth"):
        locate(image.rgb, image.depth[:, :-1], camera)
    with pytest.raises(InvalidInputError, match="colour"):
        locate(image.rgb, image.depth, camera, colours=("purple",))
    sideways = replace(camera, target=(0.02, 1.0, 0.75), up=(0.0, 0.0, 1.0))
    with pytest.raises(InvalidInputError, match="does not see"):
        locate(image.rgb, image.depth, sideways)
