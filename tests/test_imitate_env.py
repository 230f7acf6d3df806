"""``hoap_actions/Imitate-v0``: the checkers, determinism, replayed recordings, bad input, the success test."""

from __future__ import annotations

import dataclasses
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from scipy.spatial.transform import Rotation

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.demonstration.datasets import load_demonstrations, write_demonstrations
from hoap_actions.envs import world
from hoap_actions.errors import DataFileError, EnvClosedError, InvalidInputError, ResetNeededError
from hoap_actions.imitation import goals
from hoap_actions.imitation.imitate_env import BLOCK, BLOCK_SIZE, SHIFT_MIN

ENV_ID = "hoap_actions/Imitate-v0"
SMALL = (80, 60)  # px: demonstration frames small enough to render a whole episode in about a second


def make(**kwargs) -> gymnasium.Env:
    kwargs = {"robot": "fixed_legs", "demo_image_size": SMALL} | kwargs
    return gymnasium.make(ENV_ID, **kwargs)


@pytest.fixture(scope="module")
def env():
    env = make()
    yield env
    env.close()


def quaternion(yaw_deg: float) -> np.ndarray:
    return Rotation.from_euler("z", yaw_deg, degrees=True).as_quat()


def goal(position, yaw_deg=0.0, point=(0.0, 0.0), approach=False) -> np.ndarray:
    return goals.goal_vector(np.asarray(position, float), quaternion(yaw_deg), np.asarray(point, float), approach)


# ------------------------------------------------------------------ the success test, on known poses
def test_a_block_within_5_mm_and_10_degrees_counts_and_6_mm_or_11_degrees_does_not():
    target = goal([0.01, 0.02, 0.01], 30.0)
    cases = {  # achieved goal -> reached
        (0.014, 0.02, 0.01, 30.0): True,   # 4 mm
        (0.01, 0.0249, 0.01, 30.0): True,  # 4.9 mm
        (0.016, 0.02, 0.01, 30.0): False,  # 6 mm
        (0.01, 0.02, 0.01, 39.5): True,    # 9.5 degrees
        (0.01, 0.02, 0.01, 41.0): False,   # 11 degrees
        (0.01, 0.02, 0.01, 120.0): True,   # a quarter turn: the same cube
        (0.01, 0.02, 0.01, -60.0): True,
        (0.01, 0.02, 0.01, 75.0): False,   # 45 degrees: as far as a cube's yaw can be
    }
    achieved = np.array([goal(case[:3], case[3]) for case in cases])
    np.testing.assert_array_equal(goals.goal_reached(achieved, np.tile(target, (len(cases), 1))), list(cases.values()))
    assert goals.goal_reached(achieved[0], target)  # one goal as well as a batch


def test_angles_are_compared_up_to_the_cube_symmetries():
    base = Rotation.from_euler("xyz", [0.3, -0.2, 1.1])
    for symmetry in Rotation.create_group("O"):
        assert goals.block_angle((base * symmetry).as_quat(), base.as_quat()) < 1e-6
    tipped = (base * Rotation.from_euler("x", 7.0, degrees=True)).as_quat()
    assert goals.block_angle(tipped, base.as_quat()) == pytest.approx(np.radians(7.0), abs=1e-9)
    assert goals.block_angle(-tipped, base.as_quat()) == pytest.approx(np.radians(7.0), abs=1e-9)  # q and -q


def test_an_approach_needs_the_hand_over_the_target_and_the_block_still():
    target = goal([0.0, 0.0, 0.01], 0.0, point=(0.02, -0.01), approach=True)
    cases = {  # (block x shift m, hand x y) -> reached
        (0.0, 0.024, -0.01): True,     # hand 4 mm off
        (0.0, 0.026, -0.01): False,    # hand 6 mm off
        (0.0009, 0.02, -0.01): True,   # the block nudged by 0.9 mm
        (0.0015, 0.02, -0.01): False,  # moved 1.5 mm: not an approach any more
    }
    achieved = np.array([goal([shift, 0.0, 0.01], 0.0, point=(x, y), approach=True) for shift, x, y in cases])
    np.testing.assert_array_equal(goals.goal_reached(achieved, np.tile(target, (4, 1))), list(cases.values()))
    # the hand does not matter when the block has somewhere to go
    assert goals.goal_reached(goal([0, 0, 0.01], point=(0.3, 0.3)), goal([0, 0, 0.01]))


def test_the_dense_distance_weighs_a_tolerance_of_turn_as_a_tolerance_of_shift():
    target = goal([0.0, 0.0, 0.01])
    assert goals.goal_distance(goal([0.005, 0.0, 0.01]), target) == pytest.approx(0.005)
    assert goals.goal_distance(goal([0.0, 0.0, 0.01], 10.0), target) == pytest.approx(0.005)


# ------------------------------------------------------------------ the environment
def test_gymnasium_check_env_passes_with_determinism():
    env = make(control_mode="ee_delta")
    try:
        check_env(env.unwrapped, skip_render_check=True)
    finally:
        env.close()


def test_stable_baselines3_check_env_passes(env):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning either
        sb3_checker.check_env(env.unwrapped, warn=True)


def _episode(env, seed, actions):
    obs, info = env.reset(seed=seed)
    steps = [(obs, 0.0, False, False, info)]
    steps += [env.step(action) for action in actions]
    return steps, env.get_wrapper_attr("demonstration")()


def _same_episode(a, b) -> bool:
    return all(all(np.array_equal(x[0][k], y[0][k]) for k in x[0]) and x[1:4] == y[1:4] for x, y in zip(a, b))


def test_same_seed_same_demonstration_and_episode_bit_for_bit(env):
    actions = np.random.default_rng(0).uniform(-1, 1, (15, *env.action_space.shape))
    reference, shown = _episode(env, 21, actions)
    other = make()
    try:
        other.reset(seed=4)
        for _ in range(10):
            other.step(other.action_space.sample())
        again, shown_again = _episode(other, 21, actions)
    finally:
        other.close()
    assert _same_episode(reference, again)
    assert np.array_equal(shown.frames, shown_again.frames) and np.array_equal(shown.background, shown_again.background)
    assert shown.camera == shown_again.camera and shown.fps == shown_again.fps == 100.0
    different, _ = env.reset(seed=22)
    assert not np.array_equal(different["desired_goal"], reference[0][0]["desired_goal"])


def test_the_demonstration_is_frames_and_a_camera_never_markers(env):
    env.reset(seed=5)
    shown = env.get_wrapper_attr("demonstration")()
    assert {f.name for f in dataclasses.fields(shown)} == {"frames", "camera", "fps", "background"}
    assert shown.frames.dtype == np.uint8 and shown.frames.shape[1:] == (SMALL[1], SMALL[0], 3)
    assert (shown.camera.width, shown.camera.height) == SMALL
    assert shown.frames.std() > 0 and not np.array_equal(shown.frames[0], shown.frames[-1])
    assert env.get_wrapper_attr("demonstration")() is shown  # rendered once per episode
    truth = env.unwrapped.task.shown
    assert len(shown.frames) == len(truth.Q)


def test_a_fresh_env_has_no_demonstration_before_its_reset_nor_a_closed_one_after():
    env = make()
    try:
        with pytest.raises(ResetNeededError):
            env.get_wrapper_attr("demonstration")()
        env.reset(seed=0)
    finally:
        env.close()
    with pytest.raises(EnvClosedError):
        env.get_wrapper_attr("demonstration")()


def test_the_block_starts_at_the_human_start_mapped_and_its_target_is_the_human_end_mapped(env):
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        truth = env.unwrapped.task.shown
        block = env.get_wrapper_attr("parse_observation")(obs)["block_position"]
        mapped = world.human_to_robot(truth.object_start[:3])
        np.testing.assert_allclose(block[:2], mapped[:2], atol=2e-4)  # as placed, less what settling moved
        assert block[2] == pytest.approx(BLOCK_SIZE / 2, abs=2e-4)
        if truth.action != "approach":
            np.testing.assert_allclose(obs["desired_goal"][:2], world.human_to_robot(truth.object_end[:3])[:2],
                                       atol=1e-6)


@pytest.mark.parametrize("episode", [0, 2])  # the small recording's push and rotate
def test_info_carries_the_truth_only_at_the_end_of_the_episode(env, small_recording, episode):
    obs, info = env.reset(seed=1, options={"demonstration": (small_recording, episode)})
    assert "demonstration_truth" not in info
    obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
    assert not terminated and "demonstration_truth" not in info and not info["is_success"]
    task = env.unwrapped.task
    target = obs["desired_goal"]
    env.unwrapped.sim.set_base_pose(BLOCK, target[:3], target[3:7])  # the test hook: the block put on its target
    obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
    assert info["is_success"] and terminated and reward == 0.0
    truth = info["demonstration_truth"]
    assert truth["action"] == task.shown.action and truth["position_error_m"] < goals.POSITION_TOLERANCE
    assert truth["markers"].shape == (len(task.shown.Q), 6, 3)


def test_six_mm_off_the_target_is_not_a_success(env, small_recording):
    obs, _ = env.reset(seed=1, options={"demonstration": (small_recording, 1)})
    target = obs["desired_goal"]
    env.unwrapped.sim.set_base_pose(BLOCK, target[:3] + [0.006, 0.0, 0.0], target[3:7])
    obs, reward, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
    assert not info["is_success"] and reward == -1.0


def test_a_replayed_recording_shows_its_episode(env, small_recording):
    demos = load_demonstrations(small_recording)
    for k, episode in enumerate(demos):
        obs, info = env.reset(seed=0, options={"demonstration": (small_recording, k)})
        shown = env.unwrapped.task.shown
        assert shown.action == episode.ground_truth.action and shown.source.endswith(f"#{k}")
        start = env.unwrapped.task.truth()["robot_block_start"]
        np.testing.assert_allclose(start[:2], world.human_to_robot(episode.ground_truth.object_start[:3])[:2],
                                   atol=2e-4)
        assert obs["desired_goal"][9] == float(episode.ground_truth.action == "approach")
    assert len(env.get_wrapper_attr("demonstration")().frames) == demos[-1].T
    env.reset(seed=0)  # the next reset draws again
    assert env.unwrapped.task.shown.source == "drawn"


def test_the_shifted_level_moves_the_start_and_keeps_the_intent():
    mapped, shifted = make(), make(level="shifted")
    try:
        for seed in range(3):
            a, _ = mapped.reset(seed=seed)
            b, _ = shifted.reset(seed=seed)
            assert mapped.unwrapped.task.shown.source == shifted.unwrapped.task.shown.source == "drawn"
            start_a = mapped.unwrapped.task.truth()["robot_block_start"]
            start_b = shifted.unwrapped.task.truth()["robot_block_start"]
            assert np.hypot(*(start_a[:2] - start_b[:2])) >= SHIFT_MIN - 1e-3
            # the same displacement and turn from its own start (up to the settling of each block)
            np.testing.assert_allclose(b["desired_goal"][:2] - start_b[:2], a["desired_goal"][:2] - start_a[:2],
                                       atol=5e-4)
            turn_a = goals.block_angle(a["desired_goal"][3:7], start_a[3:])
            turn_b = goals.block_angle(b["desired_goal"][3:7], start_b[3:])
            assert turn_a == pytest.approx(turn_b, abs=np.radians(0.5))
    finally:
        mapped.close()
        shifted.close()


def test_dense_rewards_are_capped_vectorised_and_a_fall_costs_an_episode():
    env = make(reward_type="dense", demonstrator="tall")
    try:
        obs, _ = env.reset(seed=2)
        assert env.unwrapped.task.shown.demonstrator == "tall"
        achieved = np.stack([obs["desired_goal"], obs["achieved_goal"], obs["achieved_goal"]])
        achieved[2, :3] += 5.0
        rewards = env.unwrapped.compute_reward(achieved, np.stack([obs["desired_goal"]] * 3),
                                               np.array([{"fallen": False}, {"fallen": True}, {"fallen": False}]))
        assert rewards[0] == 0.0 and rewards[1] == -600.0 and rewards[2] == -1.0
    finally:
        env.close()


# ------------------------------------------------------------------ bad input
def test_bad_replays_are_clear_errors(env, small_recording, tmp_path):
    for episode in (4, -1, "0", 1.0, True):
        with pytest.raises(InvalidInputError, match="episode"):
            env.reset(seed=0, options={"demonstration": (small_recording, episode)})
    bare = load_demonstrations(small_recording)
    bare = dataclasses.replace(bare, joint_names=(), episodes=tuple(dataclasses.replace(e, Q=None) for e in bare))
    path = write_demonstrations(tmp_path / "no_frames.h5", bare)
    with pytest.raises(InvalidInputError, match="no joint angles"):
        env.reset(seed=0, options={"demonstration": (path, 0)})
    with pytest.raises(DataFileError):
        env.reset(seed=0, options={"demonstration": (tmp_path / "missing.h5", 0)})
    for options in ({"demo": (small_recording, 0)}, {"demonstration": small_recording}, {"demonstration": (0, 0)}):
        with pytest.raises(InvalidInputError):
            env.reset(seed=0, options=options)
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape))  # the env still works


@pytest.mark.parametrize("kwargs", [{"level": "hard"}, {"demonstrator": "nobody"}, {"demo_image_size": (0, 10)},
                                    {"demo_image_size": 320}])
def test_bad_constructor_values_are_explained(kwargs):
    with pytest.raises(InvalidInputError, match="accepted|must"):
        make(**kwargs)


@pytest.mark.parametrize("env_id, robot, period", [
    ("hoap_actions/Imitate-v0", "fixed_legs", 1), ("hoap_actions/Imitate-v0", "full", 4),
    ("hoap_actions/PegInsert-v0", "fixed_legs", 4), ("hoap_actions/PegInsert-v0", "full", 4),
])
def test_each_env_steps_its_hand_ik_at_its_own_default_period_unless_told(env_id, robot, period):
    env = gymnasium.make(env_id, robot=robot, control_mode="ee_delta")
    told = gymnasium.make(env_id, robot=robot, control_mode="ee_delta", ik_period=2)
    try:
        assert env.unwrapped.controller.hand.ik_period == period
        assert told.unwrapped.controller.hand.ik_period == 2
    finally:
        env.close()
        told.close()


@pytest.mark.parametrize("env_id, robot, feet", [
    ("hoap_actions/Imitate-v0", "full", world.FIXED_LEGS_FEET_XY),
    ("hoap_actions/Imitate-v0", "fixed_legs", world.FIXED_LEGS_FEET_XY),
    ("hoap_actions/PegInsert-v0", "full", world.ROBOT_FEET_XY),
    ("hoap_actions/PegInsert-v0", "fixed_legs", world.FIXED_LEGS_FEET_XY),
])
def test_each_env_stands_its_robot_where_it_says(env_id, robot, feet):
    env = gymnasium.make(env_id, robot=robot, control_mode="ee_delta")
    try:
        env.reset(seed=0)
        assert env.unwrapped.robot.feet_xy == pytest.approx(feet)
        soles = [env.unwrapped.robot.frame_pose(sole)[0] for sole in ("r_sole", "l_sole")]
        assert np.mean(soles, axis=0)[:2] == pytest.approx(feet, abs=0.02)  # the soles are where it stands
    finally:
        env.close()


def test_in_imitate_both_robots_head_the_hand_alike_over_the_block_area():
    """Why the free-standing robot stands where the welded one does: there the IK model heads its hand as the
    welded robot's (within 2 degrees) over the block area, so the thumb reaches the same target headings."""
    from hoap_actions.policies.block_skills import GRASP_Z, BlockHand

    headings = {}
    for robot in ("full", "fixed_legs"):
        env = make(robot=robot, control_mode="ee_delta")
        try:
            obs, _ = env.reset(seed=0)
            hand = BlockHand(env)
            hand.start(obs)
            headings[robot] = [hand.heading_at(np.array([0.0, y, GRASP_Z])) for y in (-0.06, 0.0, 0.06)]
        finally:
            env.close()
    assert np.degrees(np.abs(np.subtract(headings["full"], headings["fixed_legs"]))).max() < 2.0
    assert np.all(np.diff(headings["full"]) > 0)  # turned further left the further left it reaches
