"""A vector env whose first sub-env steps in the calling process while the others step in worker processes.

Gymnasium's ``AsyncVectorEnv`` leaves the calling process idle while every sub-env steps in a worker,
then wakes it to gather the answers: on a 2-core machine its two workers and the waiting caller share
two cores, and each step pays the workers' and the caller's wake-ups and the caller's bookkeeping one
after the other. Here the caller steps sub-env 0 itself while the workers step the rest, and the two
sides trade messages through shared memory, busy-waiting a moment for each other instead of sleeping
(:mod:`.vector_workers`), so the exchange hides behind a step's physics (``benchmarks/vector_envs.py``
and ``benchmarks/lockstep_limit.py`` measure it). :func:`make_hybrid` makes one from an env id, as
``gymnasium.make_vec`` does.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from hoap_actions.envs.vector_workers import SpinningWorkers, attribute_value, step_or_reset
from hoap_actions.errors import InvalidInputError

__all__ = ["DEFAULT_SPIN_S", "HybridVectorEnv", "make_hybrid"]

DEFAULT_SPIN_S = 0.0005
"""How long each side busy-waits for the other's message (s) when every process has a core: longer
than the exchange at a step (tens of microseconds), short enough to cost a learner's update between
steps little."""


class HybridVectorEnv(VectorEnv):
    """``num_envs`` sub-envs made by ``env_fns``: the first in this process, each other one in a worker
    process (:class:`~hoap_actions.envs.vector_workers.SpinningWorkers`; ``spin_s`` and ``context`` go to
    it). Autoreset is Gymnasium's default, the next step (``AutoresetMode.NEXT_STEP``); observations and
    infos are batched as Gymnasium's own vector envs batch them."""

    def __init__(self, env_fns: Sequence[Callable[[], gymnasium.Env]], spin_s: float | None = None,
                 context: str | None = None) -> None:
        if len(env_fns) < 2:
            raise InvalidInputError(f"a hybrid vector env needs at least 2 sub-envs (1 here, the rest in workers); "
                                    f"got {len(env_fns)}: use the env itself for one")
        if spin_s is None:  # busy-waiting only pays while every process has a core of its own
            spin_s = DEFAULT_SPIN_S if len(env_fns) <= (os.cpu_count() or 1) else 0.0
        # the workers first: they start before this process holds a physics client a fork would copy
        self.remote = SpinningWorkers(list(env_fns[1:]), spin_s=spin_s, context=context)
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
        self.remote.send("reset", [({"seed": s, "options": options},) for s in seeds[1:]])
        try:
            local = self.local.reset(seed=seeds[0], options=options)
        finally:
            remote = self.remote.gather()  # the workers' reset is under way: collect it whatever happened here
        self._local_done = False
        results = [local, *remote]
        return self._batched([r[0] for r in results]), self._infos([r[1] for r in results])

    def step(self, actions: Any) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every sub-env with its row of ``actions``: the workers' first, then this process's."""
        actions = np.asarray(actions)
        if actions.shape != self.action_space.shape or not np.isfinite(actions).all():
            raise InvalidInputError(f"actions must be {self.action_space.shape} finite numbers, one row per "
                                    f"sub-env; got shape {actions.shape}")  # refused before any sub-env steps
        self.remote.step(actions[1:].astype(self.single_action_space.dtype, copy=False))
        try:
            local, self._local_done = step_or_reset(self.local, actions[0], self._local_done)
        finally:
            remote = self.remote.gather()  # the workers' step is under way: collect it, so the env stays usable
        results = [local, *remote]
        return (self._batched([r[0] for r in results]),
                np.array([float(r[1]) for r in results]),
                np.array([bool(r[2]) for r in results]),
                np.array([bool(r[3]) for r in results]),
                self._infos([r[4] for r in results]))

    def _batched(self, observations: list[Any]) -> Any:
        """The sub-envs' observations batched as Gymnasium batches them (Boxes, and dicts of them, stacked
        directly: a quarter of the time of Gymnasium's general ``concatenate``)."""
        space = self.single_observation_space
        if isinstance(space, spaces.Box):
            return np.stack(observations).astype(space.dtype, copy=False)
        if isinstance(space, spaces.Dict) and all(isinstance(s, spaces.Box) for s in space.values()):
            return {key: np.stack([o[key] for o in observations]).astype(s.dtype, copy=False)
                    for key, s in space.items()}
        return concatenate(space, observations, create_empty_array(space, self.num_envs))

    def _infos(self, infos: list[dict[str, Any]]) -> dict[str, Any]:
        """The sub-envs' infos batched as Gymnasium batches them."""
        batched: dict[str, Any] = {}
        for i, info in enumerate(infos):
            batched = self._add_info(batched, info, i)
        return batched

    def render(self) -> tuple[Any, ...]:
        return self.call("render")

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        self.remote.send("call", [(name, args, kwargs)] * (self.num_envs - 1))
        try:
            first = attribute_value(self.local, name, args, kwargs)
        finally:
            rest = self.remote.gather()
        return (first, *rest)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        self.remote.send("get_attr", [(name,)] * (self.num_envs - 1))
        try:
            first = self.local.get_wrapper_attr(name)
        finally:
            rest = self.remote.gather()
        return (first, *rest)

    def close_extras(self, **kwargs: Any) -> None:
        try:
            self.remote.close()
        finally:
            self.local.close()


def make_hybrid(env_id: str, num_envs: int, **kwargs: Any) -> HybridVectorEnv:
    """``num_envs`` (>= 2) sub-envs of ``env_id`` made with ``kwargs`` by ``gymnasium.make``, the first in this
    process; ``vector_kwargs`` (``spin_s``, ``context``) go to :class:`HybridVectorEnv`."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 2:
        raise InvalidInputError(f"num_envs={num_envs!r}: a hybrid vector env needs a whole number >= 2 of sub-envs")
    vector_kwargs = kwargs.pop("vector_kwargs", None) or {}
    return HybridVectorEnv([lambda: gymnasium.make(env_id, **kwargs)] * num_envs, **vector_kwargs)
