"""Rewards for learning: every step in [-1, 0], and a fall never pays (it costs a whole episode)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs import ENV_IDS


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("reward_type", ["sparse", "dense"])
def test_a_fall_costs_more_than_any_episode_without_one(env_id, reward_type):
    env = gymnasium.make(env_id, reward_type=reward_type)
    try:
        base = env.unwrapped
        steps = gymnasium.spec(env_id).max_episode_steps
        assert base.task_cls.episode_steps == steps  # the registered time limit is the task's
        obs, _ = env.reset(seed=0)
        achieved, desired = obs["achieved_goal"], obs["desired_goal"]
        standing = base.compute_reward(achieved, desired, {"fallen": False})
        fallen = base.compute_reward(achieved, desired, {"fallen": True})
        assert -1.0 <= standing <= 0.0
        # falling on the first step against the worst possible whole episode without a fall
        assert fallen <= steps * -1.0
        far = desired.copy()
        far[0] += 5.0  # 5 m off along x, whatever the goal's width
        assert base.compute_reward(far, desired, None) >= -1.0  # a dense step is capped at -1 too
    finally:
        env.close()


def test_rewards_are_vectorised_with_one_info_per_goal_as_her_passes_them():
    env = gymnasium.make("hoap_actions/Reach-v1", reward_type="sparse")
    try:
        base = env.unwrapped
        obs, _ = env.reset(seed=0)
        achieved = np.stack([obs["desired_goal"], obs["desired_goal"] + 0.5, obs["desired_goal"]])
        desired = np.stack([obs["desired_goal"]] * 3)
        infos = np.array([{"fallen": False}, {"fallen": False}, {"fallen": True}])
        rewards = base.compute_reward(achieved, desired, infos)
        np.testing.assert_array_equal(rewards, [0.0, -1.0, -150.0])
    finally:
        env.close()


def test_a_falling_episode_gets_the_penalty_on_its_last_step():
    """Random joint_delta actions topple the robot on PegInsert (14 of 20 episodes): the step that
    ends it with a fall carries the penalty, and nothing else does."""
    env = gymnasium.make("hoap_actions/PegInsert-v0")
    try:
        env.action_space.seed(0)
        for seed in range(20):
            env.reset(seed=seed)
            rewards = []
            for _ in range(600):
                obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
                rewards.append(reward)
                if terminated or truncated:
                    break
            if info["fallen"]:
                assert rewards[-1] == -600.0 and min(rewards[:-1], default=0.0) >= -1.0
                return
        pytest.fail("no random episode fell in 20: the check had nothing to check")
    finally:
        env.close()
