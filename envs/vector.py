"""A vector env whose first sub-env steps in the calling process while the others step in worker processes.

Gymnasium's ``AsyncVectorEnv`` leaves the calling process idle while every sub-env steps in a worker,
then wakes it to gather the answers: on a 2-core machine its two workers and the waiting caller share
two cores, and each step pays the workers' and the caller's wake-ups and the caller's bookkeeping one
after the other. Here the caller steps sub-env 0 itself while the workers step the rest, so the
workers' round trip hides behind a step's physics (``benchmarks/vector_envs.py`` measures both).
:func:`make_hybrid` makes one from an env id, as ``gymnasium.make_vec`` does.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AsyncVectorEnv, AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from hoap_actions.errors import InvalidInputError

__all__ = ["HybridVectorEnv", "make_hybrid"]


class HybridVectorEnv(VectorEnv):
    """``num_envs`` sub-envs made by ``env_fns``: the first in this process, the others in an
    ``AsyncVectorEnv`` of worker processes (``worker_kwargs`` go to it). Autoreset is Gymnasium's
    default, the next step (``AutoresetMode.NEXT_STEP``); observations and infos are batched as
    Gymnasium's own vector envs batch them."""

    def __init__(self, env_fns: Sequence[Callable[[], gymnasium.Env]], **worker_kwargs: Any) -> None:
        if len(env_fns) < 2:
            raise InvalidInputError(f"a hybrid vector env needs at least 2 sub-envs (1 here, the rest in workers); "
                                    f"got {len(env_fns)}: use the env itself for one")
        # the workers first: they start before this process holds a physics client a fork would copy
        self.remote = AsyncVectorEnv(list(env_fns[1:]), autoreset_mode=AutoresetMode.NEXT_STEP,
                                     **{"copy": False, **worker_kwargs})
        try:
            self.local = env_fns[0]()
        except BaseException:
            self.remote.close()
            raise
        if not isinstance(self.local.action_space, spaces.Box):
            self.close_extras()
            raise InvalidInputError(f"a hybrid vector env batches Box action spaces (every hoap_actions env's); got "
                                    f"{self.local.action_space}")
        self.num_envs = len(env_fns)
        self.metadata = dict(self.local.metadata, autoreset_mode=AutoresetMode.NEXT_STEP)
        self.spec = self.local.spec
        self.render_mode = self.local.render_mode
        self.single_observation_space = self.local.observation_space
        self.single_action_space = self.local.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._local_done = False

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset every sub-env: ``seed`` an int (sub-env ``i`` gets ``seed + i``), one seed per sub-env or None."""
        if seed is None:
            seeds: list[int | None] = [None] * self.num_envs
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise InvalidInputError(f"reset needs one seed per sub-env ({self.num_envs}); got {len(seeds)}")
        self.remote.reset_async(seed=seeds[1:], options=options)
        local_obs, local_info = self.local.reset(seed=seeds[0], options=options)
        remote_obs, remote_info = self.remote.reset_wait()
        self._local_done = False
        return _stacked(local_obs, remote_obs), self._infos(local_info, remote_info)

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-env with its row of ``actions``: the workers' first, then this process's."""
        actions = np.asarray(actions)
        if actions.shape != self.action_space.shape or not np.isfinite(actions).all():
            raise InvalidInputError(f"actions must be {self.action_space.shape} finite numbers, one row per "
                                    f"sub-env; got shape {actions.shape}")  # refused before any sub-env steps
        first, rest = actions[0], actions[1:]
        self.remote.step_async(rest)
        try:
            if self._local_done:
                local_obs, local_info = self.local.reset()
                local_reward, local_terminated, local_truncated = 0.0, False, False
            else:
                local_obs, local_reward, local_terminated, local_truncated, local_info = self.local.step(first)
        except BaseException:
            self.remote.step_wait()  # the workers' step is under way: collect it, so the vector env stays usable
            raise
        self._local_done = bool(local_terminated or local_truncated)
        remote_obs, rewards, terminations, truncations, remote_info = self.remote.step_wait()
        return (_stacked(local_obs, remote_obs),
                np.concatenate([[float(local_reward)], rewards]),
                np.concatenate([[bool(local_terminated)], terminations]),
                np.concatenate([[bool(local_truncated)], truncations]),
                self._infos(local_info, remote_info))

    def _infos(self, local_info: dict[str, Any], remote_info: dict[str, Any]) -> dict[str, Any]:
        """The local sub-env's info batched as Gymnasium batches it, the workers' batched infos after it."""
        return _shifted(self._add_info({}, local_info, 0), remote_info, self.num_envs)

    def render(self) -> tuple[Any, ...]:
        return (self.local.render(), *self.remote.render())

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        attribute = self.local.get_wrapper_attr(name)
        first = attribute(*args, **kwargs) if callable(attribute) else attribute
        return (first, *self.remote.call(name, *args, **kwargs))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        return (self.local.get_wrapper_attr(name), *self.remote.get_attr(name))

    def close_extras(self, **kwargs: Any) -> None:
        try:
            self.remote.close(**kwargs)
        finally:
            self.local.close()


def _stacked(first: Any, rest: Any) -> Any:
    """One sub-env's observation put before a batch of the others' (dicts and tuples of arrays)."""
    if isinstance(first, dict):
        return {key: _stacked(value, rest[key]) for key, value in first.items()}
    if isinstance(first, tuple):
        return tuple(_stacked(value, others) for value, others in zip(first, rest, strict=True))
    return np.concatenate([np.asarray(first)[None], rest])


def _shifted(infos: dict[str, Any], rest: dict[str, Any], num_envs: int) -> dict[str, Any]:
    """``infos`` (batched for ``num_envs``, sub-env 0 filled) with the batched infos ``rest`` of sub-envs
    1.. written after it: a key the first sub-env lacks gets the array type the others' batch has."""
    for key, value in rest.items():
        if key.startswith("_") and key[1:] in rest:
            continue
        mask = rest[f"_{key}"] if f"_{key}" in rest else None
        if isinstance(value, dict):
            infos[key] = _shifted(infos.get(key, {}), value, num_envs)
            continue
        if key not in infos:
            infos[key] = np.zeros((num_envs, *value.shape[1:]), dtype=value.dtype) if value.dtype != object \
                else np.full(num_envs, None, dtype=object)
            infos[f"_{key}"] = np.zeros(num_envs, dtype=np.bool_)
        infos[key][1:] = value
        if mask is not None:
            infos[f"_{key}"][1:] = mask
    return infos


def make_hybrid(env_id: str, num_envs: int, **kwargs: Any) -> HybridVectorEnv:
    """``num_envs`` (>= 2) sub-envs of ``env_id`` made with ``kwargs`` by ``gymnasium.make``, the first in this
    process; ``vector_kwargs`` go to the workers' ``AsyncVectorEnv``."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 2:
        raise InvalidInputError(f"num_envs={num_envs!r}: a hybrid vector env needs a whole number >= 2 of sub-envs")
    vector_kwargs = kwargs.pop("vector_kwargs", None) or {}
    return HybridVectorEnv([lambda: gymnasium.make(env_id, **kwargs)] * num_envs, **vector_kwargs)
