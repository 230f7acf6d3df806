"""Policies usable in any ``env.step`` loop, looked up by name for the CLI."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from hoap_actions.controllers.scripted_expert import ScriptedExpert
from hoap_actions.errors import InvalidInputError


class RandomPolicy:
    """Uniform random actions from the env's action space (a baseline and a smoke test)."""

    failure: str | None = None
    control_mode = "joint_delta"

    def __init__(self, env: gymnasium.Env, seed: int = 0) -> None:
        self.action_space = env.action_space
        self.action_space.seed(seed)

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """Nothing to reset: the action stream continues across episodes, seeded once."""

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.action_space.sample()


POLICIES = {"random": RandomPolicy, "scripted": ScriptedExpert}  # scripted: PegInsert with control_mode="ee_delta"


def policy_class(name: str) -> type:
    """The policy class called ``name`` (one of :data:`POLICIES`); its ``control_mode`` is the env's."""
    try:
        return POLICIES[name]
    except KeyError:
        raise InvalidInputError(f"unknown policy {name!r}; accepted: {sorted(POLICIES)}") from None
