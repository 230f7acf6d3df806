"""Run a policy for many episodes and say how each ended: the loop behind ``hoap-actions demo``."""

from __future__ import annotations

import collections
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium
import numpy as np
from tqdm import tqdm

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.errors import InvalidInputError
from hoap_actions.seeds import check_seed


class Policy(Protocol):
    """``obs -> action`` for any ``env.step`` loop; ``failure`` names why it gave up (ends the episode)."""

    failure: str | None

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None: ...

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray: ...


@dataclass(frozen=True)
class EpisodeResult:
    seed: int
    success: bool
    reason: str  # "success", "fell", "timeout", or the policy's own failure ("unreachable layout", ...)
    steps: int
    wall_s: float


def run_episode(
    env: gymnasium.Env, policy: Policy, seed: int, frames: list[np.ndarray] | None = None
) -> EpisodeResult:
    """One episode on the layout drawn from ``seed``; appends rendered frames if a list is given."""
    start = time.perf_counter()
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info)
    steps, reason = 0, "timeout"
    while True:
        if frames is not None:
            frames.append(env.render())
        if policy.failure:
            reason = policy.failure
            break
        obs, _, terminated, truncated, info = env.step(policy(obs))
        steps += 1
        if info["is_success"]:
            reason = "success"
            break
        if info.get("fallen"):
            reason = "fell"
            break
        if terminated or truncated:
            break
    if frames is not None:
        frames.append(env.render())
    return EpisodeResult(seed, reason == "success", reason, steps, time.perf_counter() - start)


def run_episodes(
    env_id: str,
    policy_factory: Callable[[gymnasium.Env], Policy],
    episodes: int,
    seed: int = 0,
    video: Path | None = None,
    snapshot: Path | None = None,
    env_kwargs: dict[str, Any] | None = None,
) -> list[EpisodeResult]:
    """Episodes on seeds ``seed .. seed + episodes - 1``; the first one is filmed if asked.

    ``video`` (mp4) and ``snapshot`` (png) are written by the caller's claims: pass the partial
    paths that :func:`hoap_actions.outputs.claimed_file` yields, so they are checked before the first
    episode. Raises InvalidInputError for fewer than one episode or seeds outside 0..2**63-1.
    """
    if isinstance(episodes, bool) or not isinstance(episodes, (int, np.integer)) or episodes < 1:
        raise InvalidInputError(f"episodes must be a positive integer; got {episodes!r}")
    check_seed(seed, count=episodes)
    env = gymnasium.make(env_id, render_mode="rgb_array", **(env_kwargs or {}))
    policy = policy_factory(env)
    results = []
    try:
        for i in tqdm(range(episodes), desc="episodes", disable=not sys.stderr.isatty()):
            frames: list[np.ndarray] | None = [] if i == 0 and (video or snapshot) else None
            results.append(run_episode(env, policy, seed + i, frames))
            if frames:
                _write_media(frames, video, snapshot, env.metadata["render_fps"])
    finally:
        env.close()
    return results


def _write_media(frames: list[np.ndarray], video: Path | None, snapshot: Path | None, fps: int) -> None:
    import imageio.v3 as iio

    if snapshot:
        iio.imwrite(snapshot, frames[0])
    if video:
        iio.imwrite(video, np.stack(frames), fps=fps, codec="libx264", macro_block_size=1)


def summarise(results: list[EpisodeResult]) -> dict[str, Any]:
    """The JSON the CLI writes: success rate, falls, how episodes ended, and each episode."""
    return {
        "success_rate": float(np.mean([r.success for r in results])) if results else 0.0,
        "falls": sum(r.reason == "fell" for r in results),
        "reasons": dict(collections.Counter(r.reason for r in results)),
        "episodes": [asdict(r) for r in results],
    }
