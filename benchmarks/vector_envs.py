"""Vectorised envs: steps per second of ``gymnasium.make_vec(..., vectorization_mode="async")`` with
``--envs`` sub-processes against one env in this process, the two taking turns ``--runs`` times.

Random actions, welded-legs and free-standing robots, joint_delta and ee_delta. The figure is the
ratio of env steps per wall second (all sub-envs' steps counted), which on N free cores can reach N.
Start-up (spawning the workers, building their worlds) is timed apart and left out of the ratio.

    python benchmarks/vector_envs.py [--envs 2] [--runs 3] [--steps 300]

Writes ``results/vector_envs.json``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import gymnasium

import hoap_actions  # noqa: F401  (registers the environments)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json
from env_speed import time_run

ENV_ID = "hoap_actions/PegInsert-v0"


def single_rate(steps: int, seed: int, **kwargs) -> float:
    """Env steps per wall second of one env in this process."""
    return steps / time_run(ENV_ID, False, steps, seed, "random", **kwargs)


def vector_rate(n_envs: int, steps: int, seed: int, **kwargs) -> tuple[float, float]:
    """Env steps per wall second of ``n_envs`` async sub-envs (autoreset), and their start-up (s)."""
    start = time.perf_counter()
    envs = gymnasium.make_vec(ENV_ID, num_envs=n_envs, vectorization_mode="async", **kwargs)
    envs.reset(seed=seed)
    startup = time.perf_counter() - start
    envs.action_space.seed(seed)
    start = time.perf_counter()
    for _ in range(steps):
        envs.step(envs.action_space.sample())
    elapsed = time.perf_counter() - start
    envs.close()
    return n_envs * steps / elapsed, startup


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], parents=[arguments("vector_envs.json")])
    parser.add_argument("--envs", type=int, default=2)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    rows = []
    for robot in ("fixed_legs", "full"):
        for control_mode in ("joint_delta", "ee_delta"):
            kwargs = {"robot": robot, "control_mode": control_mode}
            singles, vectors, startups = [], [], []
            for run in range(args.runs):
                singles.append(single_rate(args.steps, run, **kwargs))
                rate, startup = vector_rate(args.envs, args.steps, run, **kwargs)
                vectors.append(rate)
                startups.append(startup)
            row = {**kwargs, "envs": args.envs, "single_steps_per_s": statistics.median(singles),
                   "vector_steps_per_s": statistics.median(vectors), "startup_s": statistics.median(startups)}
            row["ratio"] = row["vector_steps_per_s"] / row["single_steps_per_s"]
            rows.append(row)
            print(f"{robot:10s} {control_mode:11s} one env {row['single_steps_per_s']:6.0f} steps/s, {args.envs} async "
                  f"{row['vector_steps_per_s']:6.0f}: {row['ratio']:.2f}x (start-up {row['startup_s']:.1f} s)",
                  flush=True)
    write_json(args.output, {"benchmark": "vector_envs", "runs": args.runs, "steps": args.steps, "rows": rows,
                             "environment": numeric_environment(None)})


if __name__ == "__main__":
    main()
