"""What a policy may ask an env: named observation fields, camera images, the hand controller's state."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.errors import InvalidInputError


@pytest.fixture(scope="module")
def peg_env():
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    yield env
    env.close()


def test_parse_observation_names_what_the_simulator_holds(peg_env):
    obs, _ = peg_env.reset(seed=3)
    base = peg_env.unwrapped
    fields = peg_env.get_wrapper_attr("parse_observation")(obs)
    for i in range(base.scene.n_pegs):
        position, quaternion = base.scene.peg_pose(i)
        np.testing.assert_allclose(fields["peg_positions"][i], position, atol=1e-6)
        np.testing.assert_allclose(fields["peg_quaternions"][i], quaternion, atol=1e-6)
    np.testing.assert_allclose(fields["hole_positions"], base.scene.hole_positions(), atol=1e-6)
    assert (fields["target_peg"], fields["target_hole"]) == (base.task.peg, base.task.hole)
    np.testing.assert_allclose(fields["tcp_position"], base.robot.frame_pose("r_tcp")[0], atol=1e-6)
    np.testing.assert_allclose(fields["joint_positions"], base.robot.joint_positions(), atol=1e-6)
    np.testing.assert_allclose(fields["achieved_goal"], obs["achieved_goal"])


def test_parse_observation_refuses_another_envs_observation(peg_env):
    obs, _ = peg_env.reset(seed=3)
    parse = peg_env.get_wrapper_attr("parse_observation")
    with pytest.raises(InvalidInputError, match="shape"):
        parse(obs | {"observation": obs["observation"][:-1]})
    with pytest.raises(InvalidInputError, match="keys"):
        parse({"observation": obs["observation"]})


def test_reach_task_fields():
    env = gymnasium.make("hoap_actions/Reach-v1")
    try:
        obs, _ = env.reset(seed=1)
        fields = env.get_wrapper_attr("parse_observation")(obs)
        np.testing.assert_allclose(fields["target"], obs["desired_goal"], atol=1e-6)
        scene = env.unwrapped.task.scene  # the obstacles a reach must go around are in the observation
        np.testing.assert_allclose(fields["peg_positions"], [scene.peg_pose(i)[0] for i in range(scene.n_pegs)],
                                   atol=1e-6)
        np.testing.assert_allclose(fields["hole_positions"], scene.hole_positions(), atol=1e-6)
        np.testing.assert_allclose(np.linalg.norm(fields["peg_quaternions"], axis=1), 1.0, atol=1e-6)
        other, _ = env.reset(seed=2)
        assert not np.allclose(env.get_wrapper_attr("parse_observation")(other)["peg_positions"],
                               fields["peg_positions"])
    finally:
        env.close()


def test_capture_gives_rgb_depth_and_camera_but_no_segmentation(peg_env):
    peg_env.reset(seed=3)
    view = peg_env.get_wrapper_attr("capture")("overhead", 160, 120)
    assert view.rgb.shape == (120, 160, 3) and view.rgb.dtype == np.uint8
    assert view.depth.shape == (120, 160)
    assert (view.camera.width, view.camera.height) == (160, 120)
    assert not hasattr(view, "segmentation")
    # the overhead camera is 0.75 m above the table: the table is ~0.75 m away, nothing is nearer than the robot's head
    assert 0.3 < float(np.median(view.depth)) < 0.8
    with pytest.raises(InvalidInputError, match="accepted"):
        peg_env.get_wrapper_attr("capture")("ceiling")


def test_hand_status_follows_the_controller(peg_env):
    peg_env.reset(seed=3)
    status = peg_env.get_wrapper_attr("hand_status")
    np.testing.assert_allclose(status.reference, peg_env.unwrapped.controller.hand.reference)
    assert not status.unreachable
    joint_env = gymnasium.make("hoap_actions/Reach-v1")
    try:
        with pytest.raises(InvalidInputError, match="ee_delta"):
            joint_env.get_wrapper_attr("hand_status")
    finally:
        joint_env.close()
