"""Gymnasium wrappers for learners that should see only part of an env's observation."""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium
import numpy as np
from gymnasium import spaces

from hoap_actions.errors import InvalidInputError

GOAL_KEYS = ("achieved_goal", "desired_goal")


class SelectObservation(gymnasium.ObservationWrapper, gymnasium.utils.RecordConstructorArgs):
    """Keep the named fields of ``obs["observation"]`` (in the order given); the goal vectors stay.

    Why: a learner reaching with the hand gains nothing from 28 joint angles and velocities but must
    learn to ignore them; choosing fields by name (the env's ``parse_observation``) keeps the choice
    readable and immune to the layout of the vector. ``compute_reward`` is forwarded (HER relabels
    goals with it, SB3's ``check_env`` calls it on the object it is given); ``parse_observation`` stays
    the inner env's, reachable through ``get_wrapper_attr``.
    """

    def __init__(self, env: gymnasium.Env, fields: Sequence[str]) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(self, fields=list(fields))  # the env's spec can remake it
        gymnasium.ObservationWrapper.__init__(self, env)
        self._parse = env.get_wrapper_attr("parse_observation")
        space = env.observation_space
        example = self._parse({key: np.zeros(space[key].shape, dtype=np.float32) for key in space.keys()})
        available = [name for name in example if name not in GOAL_KEYS]
        fields = list(fields)
        unknown = [name for name in fields if name not in available]
        if not fields or unknown or len(set(fields)) != len(fields):
            raise InvalidInputError(f"fields={fields!r} must name distinct fields of this env's observation; "
                                    f"accepted: {available}")
        self.fields = tuple(fields)
        size = sum(np.size(example[name]) for name in fields)
        self.observation_space = spaces.Dict({
            "observation": spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32),
            **{key: space[key] for key in GOAL_KEYS},
        })

    def observation(self, observation: dict[str, np.ndarray]) -> dict[str, Any]:
        parsed = self._parse(observation)
        kept = np.concatenate([np.ravel(parsed[name]) for name in self.fields]).astype(np.float32)
        return {"observation": kept, **{key: observation[key] for key in GOAL_KEYS}}

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """The inner env's reward: the goal vectors are unchanged by this wrapper."""
        return self.env.get_wrapper_attr("compute_reward")(achieved_goal, desired_goal, info)
