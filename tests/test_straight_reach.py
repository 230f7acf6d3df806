"""The straight-line reach: the reference (and demonstrator) for learners on Reach-v1."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs.controls import MAX_HAND_STEP
from hoap_actions.errors import InvalidInputError
from hoap_actions.policies.registry import StraightReach, policy_class


def test_action_is_the_clipped_step_towards_the_target_with_the_gripper_open():
    policy = StraightReach(None)
    obs = {"achieved_goal": np.array([0.0, 0.0, 0.05]), "desired_goal": np.array([0.0025, -0.3, 0.05])}
    np.testing.assert_allclose(policy(obs), [0.5, -1.0, 0.0, -1.0])
    assert policy(obs).dtype == np.float32
    obs["desired_goal"] = obs["achieved_goal"] + [MAX_HAND_STEP, 0.0, -MAX_HAND_STEP / 4]
    np.testing.assert_allclose(policy(obs), [1.0, 0.0, -0.25, -1.0], atol=1e-6)


def test_it_reaches_most_targets_and_never_falls():
    """It reaches 94 % of the validation layouts (docs/experiments/rl.md): at least two of layouts 0-2 within
    1 cm; never a fall."""
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta")
    policy = StraightReach(env)
    end = []
    for seed in (0, 1, 2):
        obs, info = env.reset(seed=seed)
        policy.reset(obs, info)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(policy(obs))
        end.append(np.linalg.norm(obs["achieved_goal"] - obs["desired_goal"]))
        assert not info["fallen"]
    env.close()
    assert sum(distance < 0.01 for distance in end) >= 2


def test_it_is_refused_where_it_cannot_act():
    with pytest.raises(InvalidInputError, match="does not act in hoap_actions/PegInsert-v0"):
        policy_class("straight", "hoap_actions/PegInsert-v0")


def test_an_episode_reports_how_closely_the_hand_tracked_its_reference():
    """ee_delta episodes carry the hand's tracking error (95th percentile over steps); the straight
    reach moves the reference at the controller's full speed, and the servos follow within a centimetre."""
    from hoap_actions.apps.episodes import run_episode, summarise

    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta", robot="fixed_legs")
    result = run_episode(env, StraightReach(env), seed=0)
    env.close()
    assert 0.0 < result.hand_error_m < 0.01
    assert summarise([result])["hand_error_m"] == {"median": result.hand_error_m, "max": result.hand_error_m}
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="joint_delta", robot="fixed_legs")
    assert run_episode(env, policy_class("random")(env), seed=0).hand_error_m is None
    env.close()
