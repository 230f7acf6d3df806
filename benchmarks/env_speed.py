"""Environment speed: env steps per second and simulated seconds per wall second, per id.

Each figure is the median of several runs, with and without rendering an ``rgb_array`` frame every
step, for random actions (the robot often falls: many contacts) and for zero actions (it stands). Printed and written to ``benchmarks/results/env_speed.json``.

    python benchmarks/env_speed.py [--runs 5] [--steps 300]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions
from hoap_actions.envs.core import PHYSICS_STEPS_PER_ACTION
from hoap_actions.envs.sim import TIMESTEP

RESULTS = Path(__file__).parent / "results" / "env_speed.json"


def time_run(env_id: str, render: bool, steps: int, seed: int, actions_kind: str) -> float:
    """Wall seconds for ``steps`` steps of random or zero actions (reset excluded)."""
    env = gymnasium.make(env_id, render_mode="rgb_array" if render else None)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    actions = [env.action_space.sample() * (actions_kind == "random") for _ in range(steps)]
    start = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if render:
            env.render()
        if terminated or truncated:
            env.reset()
    elapsed = time.perf_counter() - start
    env.close()
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    sim_seconds_per_step = PHYSICS_STEPS_PER_ACTION * TIMESTEP
    rows = []
    for env_id in hoap_actions.ENV_IDS:
        for actions_kind, render in (("random", False), ("zero", False), ("random", True)):
            steps = args.steps if not render else max(args.steps // 5, 20)
            walls = [time_run(env_id, render, steps, seed, actions_kind) for seed in range(args.runs)]
            median = statistics.median(walls)
            row = {
                "env_id": env_id,
                "actions": actions_kind,
                "render": render,
                "steps_per_run": steps,
                "runs": args.runs,
                "median_steps_per_s": steps / median,
                "median_sim_s_per_wall_s": steps * sim_seconds_per_step / median,
                "median_physics_step_ms": 1e3 * median / (steps * PHYSICS_STEPS_PER_ACTION),
            }
            rows.append(row)
            print(
                f"{env_id:28s} {actions_kind:6s} render={str(render):5s}  {row['median_steps_per_s']:8.1f} steps/s  "
                f"{row['median_sim_s_per_wall_s']:6.2f} sim s / wall s  "
                f"({row['median_physics_step_ms']:.3f} ms per physics step incl. overhead)"
            )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(
        json.dumps({"machine": platform.platform(), "numpy": np.__version__, "results": rows}, indent=2) + "\n"
    )
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
