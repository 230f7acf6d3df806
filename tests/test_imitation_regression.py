"""The whole imitation loop as a regression: the robot watches each demonstration through its camera and
does it to its own block, on 50 fixed episodes (slow: about 6 minutes on a quiet core, 15 on a busy one)."""

from __future__ import annotations

import gymnasium
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import run_episode
from hoap_actions.policies.imitation_policy import CameraImitation

SEEDS = range(90000, 90050)  # the first half of the validation episodes: the held-out figures are in the docs
REQUIRED = 0.90  # the success the loop must keep on them


@pytest.mark.slow
def test_the_robot_imitates_what_its_camera_saw_on_50_fixed_episodes():
    env = gymnasium.make("hoap_actions/Imitate-v0", robot="fixed_legs", control_mode=CameraImitation.control_mode)
    policy = CameraImitation(env)
    results = [run_episode(env, policy, seed) for seed in SEEDS]
    env.close()
    assert not any(result.reason == "fell" for result in results)
    missed = [result.seed for result in results if not result.success]
    assert 1.0 - len(missed) / len(results) >= REQUIRED, f"missed {missed}"
