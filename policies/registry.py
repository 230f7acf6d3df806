"""Policies usable in any ``env.step`` loop, looked up by name for the CLI."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from hoap_actions.envs import ENV_IDS
from hoap_actions.envs.controls import MAX_HAND_STEP
from hoap_actions.errors import InvalidInputError
from hoap_actions.policies.behaviour_cloning import BehaviourCloningPolicy
from hoap_actions.policies.imitation_policy import (
    CameraImitation,
    DoNothing,
    ExecutionCeiling,
    FrequentImitation,
    MarkerImitation,
)
from hoap_actions.policies.phmm_policy import PHMMPolicy
from hoap_actions.policies.scripted_expert import ScriptedExpert


class RandomPolicy:
    """Uniform random actions from the env's action space (a baseline and a smoke test)."""

    failure: str | None = None
    control_mode = "joint_delta"
    env_ids = ENV_IDS  # any of the package's envs

    def __init__(self, env: gymnasium.Env, seed: int = 0) -> None:
        self.action_space = env.action_space
        self.action_space.seed(seed)

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """Nothing to reset: the action stream continues across episodes, seeded once."""

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.action_space.sample()


class StraightReach:
    """The straight-line reference for ``Reach-v1`` (ee_delta): the hand driven at the target at up to full
    speed, gripper open. A baseline for learners, and demonstrations they can start from; it fails where a
    peg or the board stands in the straight line (the hand yields on contact)."""

    failure: str | None = None
    control_mode = "ee_delta"
    env_ids = ("hoap_actions/Reach-v1",)

    def __init__(self, env: gymnasium.Env) -> None:
        del env  # the goal vectors of the observation are all it reads

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """Nothing to reset: each action depends on the current observation alone."""

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        step = (np.asarray(obs["desired_goal"], float) - np.asarray(obs["achieved_goal"], float)) / MAX_HAND_STEP
        return np.append(np.clip(step, -1.0, 1.0), -1.0).astype(np.float32)


POLICIES = {"random": RandomPolicy, "scripted": ScriptedExpert, "phmm": PHMMPolicy, "straight": StraightReach,
            "bc": BehaviourCloningPolicy, "imitation-oracle": ExecutionCeiling,
            "imitation-markers": MarkerImitation, "imitation-camera": CameraImitation,
            "imitation-frequent": FrequentImitation, "nothing": DoNothing}
"""Policies by name; each has ``control_mode`` (the env's) and ``env_ids`` (the envs it can act in)."""


def policy_class(name: str, env_id: str | None = None) -> type:
    """The policy class called ``name`` (one of :data:`POLICIES`), checked against ``env_id`` if given."""
    try:
        policy = POLICIES[name]
    except KeyError:
        raise InvalidInputError(f"unknown policy {name!r}; accepted: {sorted(POLICIES)}") from None
    if env_id is not None and env_id not in policy.env_ids:
        raise InvalidInputError(f"the {name} policy does not act in {env_id}; it acts in {list(policy.env_ids)}")
    return policy
