"""Gymnasium wrappers for learners: part of an env's observation, actions on top of a base policy's, or an
action held for several steps."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from hoap_actions.errors import InvalidInputError

GOAL_KEYS = ("achieved_goal", "desired_goal")


class _ForwardsReward:
    """``compute_reward`` of the wrapped env (neither wrapper changes the goal vectors): HER relabels goals
    with it, and SB3's ``check_env`` calls it on the object it is given, which plain Gymnasium wrappers
    do not forward."""

    env: gymnasium.Env

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        return self.env.get_wrapper_attr("compute_reward")(achieved_goal, desired_goal, info)


class SelectObservation(_ForwardsReward, gymnasium.ObservationWrapper, gymnasium.utils.RecordConstructorArgs):
    """Keep the named fields of ``obs["observation"]`` (in the order given); the goal vectors stay.

    Why: a learner reaching with the hand gains nothing from 28 joint angles and velocities but must
    learn to ignore them; choosing fields by name (the env's ``parse_observation``) keeps the choice
    readable and immune to the layout of the vector. ``parse_observation`` stays the inner env's,
    reachable through ``get_wrapper_attr``.
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


class ResidualAction(_ForwardsReward, gymnasium.Wrapper):
    """``scale`` times the learner's action is added to a base policy's, and the sum clipped to the action
    space (residual RL).

    Why: a learner that starts from a competent controller has only its corrections to learn; a ``scale``
    below 1 bounds how far an untrained or noisy correction can pull the base off its course. The base sees
    each observation the env returns; goal relabelling (HER) does not fit, since the base acted on the goal
    the episode really had.
    """

    def __init__(self, env: gymnasium.Env, base: Callable[[dict[str, np.ndarray]], np.ndarray],
                 scale: float = 1.0) -> None:
        if not isinstance(env.action_space, spaces.Box):
            raise InvalidInputError(f"a residual needs a Box action space; this env's is {env.action_space}")
        if not (np.isfinite(scale) and scale > 0):
            raise InvalidInputError(f"scale={scale!r} must be a positive finite number")
        super().__init__(env)
        self.base = base
        self.scale = float(scale)
        self._last_obs: dict[str, np.ndarray] | None = None

    def reset(self, **kwargs: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._last_obs = obs
        return obs, info

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._last_obs is None:
            raise InvalidInputError("step() before reset(): the base policy needs an observation")
        space = self.action_space
        if np.shape(action) != space.shape:
            raise InvalidInputError(f"action has shape {np.shape(action)}; a residual must have the action space's "
                                    f"shape {space.shape}")
        total = np.clip(np.asarray(self.base(self._last_obs), dtype=float)
                        + self.scale * np.asarray(action, dtype=float),
                        space.low, space.high).astype(space.dtype)
        obs, reward, terminated, truncated, info = self.env.step(total)
        self._last_obs = obs
        return obs, reward, terminated, truncated, info


class RepeatAction(_ForwardsReward, gymnasium.Wrapper):
    """Each action is applied for ``repeat`` steps of the env (fewer when the episode ends first); the last
    step's observation, reward and info are returned.

    Why: a learner deciding every second step explores twice as far per decision and has half as many
    decisions to credit a reward to. The last reward, not a sum, keeps a goal env's reward equal to
    ``compute_reward`` of the returned achieved goal, which hindsight relabelling relies on.
    """

    def __init__(self, env: gymnasium.Env, repeat: int) -> None:
        if isinstance(repeat, bool) or not isinstance(repeat, (int, np.integer)) or repeat < 1:
            raise InvalidInputError(f"repeat={repeat!r} must be a whole number >= 1")
        super().__init__(env)
        self.repeat = int(repeat)

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        for _ in range(self.repeat):
            obs, reward, terminated, truncated, info = self.env.step(action)
            if terminated or truncated:
                break
        return obs, reward, terminated, truncated, info
