"""``Imitate-v0``'s costs and its floor: reset time (drawing and performing the demonstration), the
demonstration's rendering, step time, and the success of two policies that ignore the demonstration
(zero actions: the robot stands still; uniform random actions) on seeds 91000-91049, both robots,
joint_delta, level ``mapped``. Neither should succeed: a figure above 0 would mean the task can be
solved without watching.

    python benchmarks/imitate_env.py [--seeds 50] [--first-seed 91000] [--timing-seeds 10]

Written to ``results/imitate_env.json``; the figures are quoted in ``docs/envs.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import wilson_interval

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

ENV_ID = "hoap_actions/Imitate-v0"


def timings(robot: str, seeds: range, steps: int) -> dict:
    """Median wall times (s): a reset, a reset plus rendering its demonstration (320 x 240), an env step
    of random actions, on ``seeds``."""
    env = gymnasium.make(ENV_ID, robot=robot)
    env.reset(seed=seeds[0] - 1)  # the demonstration scenes made once, as in any run after the first reset
    resets, rendered, frames, step_times = [], [], [], []
    for seed in seeds:
        start = time.perf_counter()
        env.reset(seed=seed)
        resets.append(time.perf_counter() - start)
        start = time.perf_counter()
        shown = env.get_wrapper_attr("demonstration")()
        rendered.append(time.perf_counter() - start)
        frames.append(len(shown.frames))
        env.action_space.seed(seed)
        start = time.perf_counter()
        for _ in range(steps):
            env.step(env.action_space.sample())
        step_times.append((time.perf_counter() - start) / steps)
    env.close()
    return {"robot": robot, "seeds": [seeds[0], seeds[-1]], "median_reset_s": statistics.median(resets),
            "median_render_demonstration_s": statistics.median(rendered),
            "median_render_frame_ms": 1e3 * statistics.median(r / f for r, f in zip(rendered, frames)),
            "median_frames": statistics.median(frames), "median_step_ms": 1e3 * statistics.median(step_times)}


def baseline(robot: str, policy: str, seeds: range) -> dict:
    """Success of ``policy`` ("zero" or "random" actions) over whole episodes of ``seeds``."""
    env = gymnasium.make(ENV_ID, robot=robot)
    episodes = []
    for seed in seeds:
        env.reset(seed=seed)
        env.action_space.seed(seed)
        while True:
            action = env.action_space.sample() if policy == "random" else np.zeros(env.action_space.shape)
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        truth = info["demonstration_truth"]
        episodes.append({"seed": seed, "action": truth["action"], "success": bool(info["is_success"]),
                         "fallen": bool(info["fallen"]), "position_error_m": truth["position_error_m"],
                         "angle_error_deg": float(np.degrees(truth["angle_error_rad"])),
                         "point_error_m": truth["point_error_m"]})
    env.close()
    successes = sum(e["success"] for e in episodes)
    low, high = wilson_interval(successes, len(episodes))
    by_action = {a: sum(e["success"] for e in episodes if e["action"] == a) for a in sorted({e["action"] for e in
                                                                                              episodes})}
    return {"robot": robot, "policy": policy, "level": "mapped", "successes": successes, "episodes": len(episodes),
            "rate": successes / len(episodes), "wilson95": [low, high], "falls": sum(e["fallen"] for e in episodes),
            "successes_by_action": by_action,
            "actions": {a: sum(e["action"] == a for e in episodes) for a in by_action}, "per_episode": episodes}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("imitate_env.json")])
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--first-seed", type=int, default=91000)
    parser.add_argument("--timing-seeds", type=int, default=10)
    parser.add_argument("--timing-steps", type=int, default=30)
    args = parser.parse_args(argv)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    timing_seeds = range(args.first_seed + 1000, args.first_seed + 1000 + args.timing_seeds)
    times = [timings(robot, timing_seeds, args.timing_steps) for robot in ("full", "fixed_legs")]
    for row in times:
        print(f"{row['robot']:10s} reset {row['median_reset_s']:.2f} s, demonstration rendered in "
              f"{row['median_render_demonstration_s']:.1f} s ({row['median_render_frame_ms']:.1f} ms a frame), "
              f"step {row['median_step_ms']:.1f} ms")
    baselines = []
    for robot in ("full", "fixed_legs"):
        for policy in ("zero", "random"):
            row = baseline(robot, policy, seeds)
            baselines.append(row)
            print(f"{robot:10s} {policy:6s} {row['successes']}/{row['episodes']} successes "
                  f"(95 % Wilson {100 * row['wilson95'][0]:.1f}-{100 * row['wilson95'][1]:.1f} %), "
                  f"{row['falls']} falls")
    document = {"timings": times, "baselines": baselines,
                "environment": numeric_environment(blas_threads=None, gymnasium=gymnasium.__version__)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
