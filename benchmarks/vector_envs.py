"""Vectorised envs: steps per second of ``--envs`` sub-envs against one env in this process, taking turns
``--runs`` times: Gymnasium's ``make_vec(..., vectorization_mode="async")`` (every sub-env in a worker
process), the package's :class:`~hoap_actions.envs.vector.HybridVectorEnv` (the first sub-env in this
process, the others in workers) and, when Stable-Baselines3 is installed, its ``SubprocVecEnv``.

Random actions, welded-legs and free-standing robots, joint_delta and ee_delta. The figure is the
ratio of env steps per wall second (all sub-envs' steps counted), which on N free cores can reach N.
Start-up (spawning the workers, building their worlds) is timed apart and left out of the ratio.

    python benchmarks/vector_envs.py [--envs 2] [--runs 3] [--steps 300]

Writes ``results/vector_envs.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs.vector import make_hybrid

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json
from env_speed import time_run

ENV_ID = "hoap_actions/PegInsert-v0"


def single_rate(steps: int, seed: int, **kwargs) -> float:
    """Env steps per wall second of one env in this process."""
    return steps / time_run(ENV_ID, False, steps, seed, "random", **kwargs)


def _make(kind: str, n_envs: int, **kwargs):
    if kind == "async":
        return gymnasium.make_vec(ENV_ID, num_envs=n_envs, vectorization_mode="async", **kwargs)
    if kind == "hybrid":
        return make_hybrid(ENV_ID, n_envs, **kwargs)
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    return make_vec_env(ENV_ID, n_envs=n_envs, env_kwargs=kwargs, vec_env_cls=SubprocVecEnv)


def vector_rate(kind: str, n_envs: int, steps: int, seed: int, **kwargs) -> tuple[float, float]:
    """Env steps per wall second of ``n_envs`` sub-envs of a vector env of ``kind`` (autoreset), and its
    start-up (s)."""
    start = time.perf_counter()
    envs = _make(kind, n_envs, **kwargs)
    if kind == "sb3_subproc":
        envs.seed(seed)
        envs.reset()
    else:
        envs.reset(seed=seed)
    startup = time.perf_counter() - start
    envs.action_space.seed(seed)
    actions = [[envs.action_space.sample() for _ in range(n_envs)] if kind == "sb3_subproc"
               else envs.action_space.sample() for _ in range(steps)]
    start = time.perf_counter()
    for action in actions:
        envs.step(np.asarray(action))
    elapsed = time.perf_counter() - start
    envs.close()
    return n_envs * steps / elapsed, startup


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], parents=[arguments("vector_envs.json")])
    parser.add_argument("--envs", type=int, default=2)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    kinds = ["async", "hybrid"] + (["sb3_subproc"] if importlib.util.find_spec("stable_baselines3") else [])
    rows = []
    for robot in ("fixed_legs", "full"):
        for control_mode in ("joint_delta", "ee_delta"):
            kwargs = {"robot": robot, "control_mode": control_mode}
            singles, vectors, startups = [], {k: [] for k in kinds}, {k: [] for k in kinds}
            for run in range(args.runs):
                singles.append(single_rate(args.steps, run, **kwargs))
                for kind in kinds:
                    rate, startup = vector_rate(kind, args.envs, args.steps, run, **kwargs)
                    vectors[kind].append(rate)
                    startups[kind].append(startup)
            single = statistics.median(singles)
            row = {**kwargs, "envs": args.envs, "single_steps_per_s": single, "single_runs": singles,
                   "vector": {kind: {"steps_per_s": statistics.median(vectors[kind]), "runs": vectors[kind],
                                     "ratio": statistics.median(vectors[kind]) / single,
                                     "startup_s": statistics.median(startups[kind])} for kind in kinds}}
            rows.append(row)
            shown = ", ".join(f"{kind} {v['ratio']:.2f}x (start-up {v['startup_s']:.1f} s)"
                              for kind, v in row["vector"].items())
            print(f"{robot:10s} {control_mode:11s} one env {single:6.0f} steps/s; {args.envs} sub-envs: {shown}",
                  flush=True)
    write_json(args.output, {"benchmark": "vector_envs", "runs": args.runs, "steps": args.steps, "rows": rows,
                             "environment": numeric_environment(None)})


if __name__ == "__main__":
    main()
