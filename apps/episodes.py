"""Run a policy for many episodes and say how each ended: the loop behind ``hoap-actions demo``."""

from __future__ import annotations

import atexit
import collections
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium
import numpy as np
from tqdm import tqdm

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.videos import side_by_side, write_video
from hoap_actions.envs.controls import HAND_CONTROL_MODES
from hoap_actions.errors import InvalidInputError
from hoap_actions.parallel import ordered_map
from hoap_actions.seeds import check_seed


class Policy(Protocol):
    """``obs -> action`` for any ``env.step`` loop; ``failure`` names why it gave up (ends the episode).
    A policy may also say it is ``done`` (it has nothing left to do), which ends the episode too."""

    failure: str | None

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None: ...

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray: ...


@dataclass(frozen=True)
class EpisodeResult:
    """How one episode ended. For a policy that locates the objects itself (``located()``), the
    largest centre error (m) of its target peg and hole against the observation's true poses; for one
    that follows synthesised paths (``path_deviations()``), each path's largest distance (m) from the
    executed hand."""

    seed: int
    success: bool
    reason: str  # "success", "fell", "timeout", "finished without success", or the policy's own failure
    steps: int
    wall_s: float
    perception_error_m: float | None = None
    path_deviation_m: dict[str, float] | None = None
    hand_error_m: float | None = None  # ee_delta: 95th percentile over steps of the hand's distance from its reference
    recognised: str | None = None
    reset_s: float | None = None  # wall time of env.reset (an imitation env performs its demonstration there)
    reading_s: float | None = None  # wall time the policy spent reading a demonstration (reading_s())
    filming_s: float | None = None  # wall time the env took to film the demonstration the policy asked for


def run_episode(
    env: gymnasium.Env, policy: Policy, seed: int, frames: list[np.ndarray] | None = None,
    options: dict[str, Any] | None = None,
) -> EpisodeResult:
    """One episode on the layout drawn from ``seed`` (``options`` go to ``env.reset``, e.g. the recorded
    demonstration ``Imitate-v0`` replays); appends rendered frames if a list is given."""
    start = time.perf_counter()
    obs, info = env.reset(seed=seed, options=options)
    reset_s = time.perf_counter() - start
    truth = env.get_wrapper_attr("parse_observation")(obs) if hasattr(policy, "located") else None
    policy.reset(obs, info)
    perception_error = _perception_error(policy.located(), truth) if truth is not None else None
    steps, reason = 0, "timeout"
    hand_error = _hand_error_reader(env)
    hand_errors: list[float] = []
    while True:
        if frames is not None:
            frames.append(env.render())
        if policy.failure:
            reason = policy.failure
            break
        if getattr(policy, "done", False):  # it did all it meant to, and the goal is not reached
            reason = "finished without success"
            break
        obs, _, terminated, truncated, info = env.step(policy(obs))
        steps += 1
        if hand_error is not None:
            hand_errors.append(hand_error(obs))
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
    deviations = policy.path_deviations() if hasattr(policy, "path_deviations") else None
    return EpisodeResult(seed, reason == "success", reason, steps, time.perf_counter() - start,
                         perception_error, deviations,
                         float(np.percentile(hand_errors, 95)) if hand_errors else None,
                         policy.recognised() if hasattr(policy, "recognised") else None, reset_s,
                         policy.reading_s() if hasattr(policy, "reading_s") else None,
                         policy.filming_s() if hasattr(policy, "filming_s") else None)


def _hand_error_reader(env: gymnasium.Env) -> Callable[[dict[str, np.ndarray]], float] | None:
    """For an ee_delta env, ``obs -> `` the distance (m) of the measured hand from the controller's
    reference, how closely the hand-space controller tracks; None for other control modes."""
    if env.get_wrapper_attr("control_mode") not in HAND_CONTROL_MODES:
        return None
    parse, status = env.get_wrapper_attr("parse_observation"), lambda: env.get_wrapper_attr("hand_status")
    return lambda obs: float(np.linalg.norm(parse(obs)["tcp_position"] - status().reference))


def _perception_error(located: dict[str, np.ndarray] | None, truth: dict[str, Any]) -> float | None:
    """Largest centre error (m) of the located target peg and hole; None if either was not located."""
    if located is None:
        return None
    peg = truth["peg_positions"][truth["target_peg"]]
    hole = truth["hole_positions"][truth["target_hole"]]
    return float(max(np.linalg.norm(located["peg"] - peg), np.linalg.norm(located["hole"] - hole)))


def film_episode(
    env_id: str,
    policy_factory: Callable[[gymnasium.Env], Policy],
    seed: int,
    control_mode: str,
    video: Path | None = None,
    snapshot: Path | None = None,
    camera: str = "closeup",
    robot: str = "full",
    env_kwargs: dict[str, Any] | None = None,
    options: dict[str, Any] | None = None,
) -> EpisodeResult:
    """One episode filmed from ``camera``: an mp4 of it at ``video`` and, at ``snapshot``, the policy's
    own picture of it (``figure()``, e.g. the PHMM policy's Fig. 9) or else its first frame. A policy that
    was shown a demonstration (``shown_frames()``, the imitation policies) has it played beside the robot. Pass the
    partial paths that :func:`hoap_actions.outputs.claimed_file` yields, so the outputs are checked
    before the episode runs. ``env_kwargs`` go to ``gymnasium.make``, ``options`` to ``env.reset``."""
    check_seed(seed)
    env = gymnasium.make(env_id, render_mode="rgb_array", camera=camera, control_mode=control_mode, robot=robot,
                         **(env_kwargs or {}))
    try:
        policy = policy_factory(env)
        frames: list[np.ndarray] = []
        result = run_episode(env, policy, seed, frames, options)
        figure = policy.figure() if hasattr(policy, "figure") else None
        if video and hasattr(policy, "shown_frames"):  # what it was shown, played beside what it did
            shown = policy.shown_frames()
            demonstration_fps = env.get_wrapper_attr("demonstration")().fps
            frames = side_by_side(shown, demonstration_fps, frames, env.metadata["render_fps"])
    finally:
        env.close()
    import imageio.v3 as iio

    if snapshot:
        iio.imwrite(snapshot, figure if figure is not None else frames[0])
    if video:
        write_video(video, frames, env.metadata["render_fps"])
    return result


_WORKER: dict[str, Any] = {}


def _start_worker(env_id: str, policies: dict[str, tuple[str, dict]], robot: str, env_kwargs: dict | None = None
                  ) -> None:
    from hoap_actions.policies.registry import policy_class

    classes = {name: policy_class(cls, env_id) for name, (cls, _) in policies.items()}
    modes = {c.control_mode for c in classes.values()}
    if len(modes) != 1:
        raise InvalidInputError(f"the compared policies act through different control modes {sorted(modes)}")
    env = gymnasium.make(env_id, render_mode="rgb_array", control_mode=modes.pop(), robot=robot, **(env_kwargs or {}))
    atexit.register(env.close)  # a worker process closes its simulator before the interpreter goes
    _WORKER.update(env=env, policies={name: classes[name](env, **kwargs) for name, (_, kwargs) in policies.items()})


def _run_seed(job: tuple[int, dict[str, Any] | None]) -> dict[str, EpisodeResult]:
    seed, options = job
    return {name: run_episode(_WORKER["env"], policy, seed, options=options)
            for name, policy in _WORKER["policies"].items()}


def compare_policies(
    env_id: str, policies: dict[str, tuple[str, dict]], seeds: Sequence[int], workers: int = 1, robot: str = "full",
    ray_address: str | None = None, env_kwargs: dict[str, Any] | None = None,
    options: Sequence[dict[str, Any] | None] | None = None,
) -> dict[str, list[EpisodeResult]]:
    """Every policy on every seed's layout, interleaved (seed by seed, policy after policy, in one
    env per worker), so machine load falls alike on all. ``policies`` maps a label to a policy name
    (:data:`~hoap_actions.policies.registry.POLICIES`) and its keyword arguments. Episodes
    depend on their seed alone, so ``workers`` processes, or Ray actors with ``ray_address`` (see
    :func:`hoap_actions.parallel.ordered_map`), give the serial results. ``robot`` is the env's robot
    model (``"full"`` or ``"fixed_legs"``); ``env_kwargs`` go to ``gymnasium.make`` besides it (e.g.
    ``{"ik_period": 4}``); ``options``, one per seed, go to its ``env.reset`` (e.g.
    ``{"demonstration": (path, episode)}`` on ``Imitate-v0``)."""
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise InvalidInputError("seeds is empty; give at least one")
    options = [None] * len(seeds) if options is None else list(options)
    if len(options) != len(seeds):
        raise InvalidInputError(f"options must give one entry per seed ({len(seeds)}); got {len(options)}")
    for s in seeds:
        check_seed(s)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InvalidInputError(f"workers must be a positive integer; got {workers!r}")
    initargs = (env_id, policies, robot, env_kwargs)
    if workers == 1 and ray_address is None:
        _start_worker(*initargs)
        try:
            rows = [_run_seed(job) for job in tqdm(list(zip(seeds, options)), desc="layouts",
                                                    disable=not sys.stderr.isatty())]
        finally:
            _WORKER.pop("env").close()
    else:
        results = ordered_map(_run_seed, list(zip(seeds, options)), _start_worker, initargs, workers, ray_address)
        rows = list(tqdm(results, total=len(seeds), desc="layouts", disable=not sys.stderr.isatty()))
    return {name: [row[name] for row in rows] for name in policies}


def summarise(results: list[EpisodeResult], timings: bool = True) -> dict[str, Any]:
    """Success rate (with its 95 % Wilson interval), falls, how episodes ended, mean wall time,
    perception errors and path deviations where the policy has them, and each episode.

    ``timings=False`` leaves the wall times out: what is left depends on the seeds alone, so it is
    the same whatever the number of worker processes (the CLI's ``--json``).
    """
    n = len(results)
    successes = sum(r.success for r in results)
    summary: dict[str, Any] = {
        "success_rate": successes / n if n else 0.0,
        "success_ci95": wilson_interval(successes, n),
        "falls": sum(r.reason == "fell" for r in results),
        "reasons": dict(collections.Counter(r.reason for r in results)),
        "mean_wall_s": float(np.mean([r.wall_s for r in results])) if n else 0.0,
    }
    errors = [r.perception_error_m for r in results if r.perception_error_m is not None]
    if any(r.perception_error_m is not None or r.path_deviation_m is not None for r in results):
        summary["perception_error_m"] = _median_max(errors) | {"not_located": n - len(errors)}
        names = sorted({k for r in results for k in (r.path_deviation_m or {})})
        summary["path_deviation_m"] = {k: _median_max([r.path_deviation_m[k] for r in results
                                                         if r.path_deviation_m and k in r.path_deviation_m])
                                       for k in names}
    hand = [r.hand_error_m for r in results if r.hand_error_m is not None]
    if hand:
        summary["hand_error_m"] = _median_max(hand)
    summary["episodes"] = [asdict(r) for r in results]
    if not timings:
        del summary["mean_wall_s"]
        for episode in summary["episodes"]:
            for key in ("wall_s", "reset_s", "reading_s", "filming_s"):
                del episode[key]
    return summary


def _median_max(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "max": None}
    return {"median": float(np.median(values)), "max": float(np.max(values))}


def wilson_interval(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """95 % Wilson score interval of a success rate (stays inside [0, 1] and is honest at 0 and n)."""
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (float(max(0.0, centre - half)), float(min(1.0, centre + half)))


def paired_outcomes(first: Sequence[dict], second: Sequence[dict], resamples: int = 10_000) -> dict[str, Any]:
    """Two runs' episodes on the same seeds (``summarise``'s episode dictionaries, in the same order):
    the episodes only one solved, the exact McNemar p, and the success rate difference ``first - second``
    with its 95 % bootstrap interval over episodes (resampling seeded 0)."""
    from scipy import stats

    if [e["seed"] for e in first] != [e["seed"] for e in second]:
        raise InvalidInputError("paired_outcomes needs the two runs' episodes on the same seeds, in the same order")
    x = np.array([e["success"] for e in first], dtype=float)
    y = np.array([e["success"] for e in second], dtype=float)
    only_a, only_b = int(np.sum((x == 1) & (y == 0))), int(np.sum((x == 0) & (y == 1)))
    p = stats.binomtest(min(only_a, only_b), only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
    rows = np.random.default_rng(0).integers(0, len(x), size=(resamples, len(x)))
    differences = (x[rows] - y[rows]).mean(axis=1)
    return {"difference": float((x - y).mean()), "difference_ci95": np.percentile(differences, [2.5, 97.5]).tolist(),
            "only_first": only_a, "only_second": only_b, "mcnemar_p": float(p)}

