"""Control tick speed and the scripted expert's pace: how long one 240 Hz control step takes.

Measures, on the standing robot in PegInsert-v0 (control_mode="ee_delta"):

- the control computation of one tick (ruckig retimer step + placo IK solve), median over a
  moving target (goal: <= 0.1 ms), with its two parts; and a whole controller tick inside the
  physics loop (adding the PyBullet hand read and the 28 joint motor commands);
- the scripted expert's episodes: wall time, simulated time and real-time factor (simulated
  seconds per wall second), success and failure reasons.

    python benchmarks/control_tick.py [--episodes 10] [--seed 1000]

Prints a table and writes ``results/control_tick.json``; earlier figures are in ``docs/experiments/robot.md``.
"""

from __future__ import annotations

import argparse
import collections
import sys
import time
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import run_episode
from hoap_actions.envs.hoap_env import PHYSICS_STEPS_PER_ACTION
from hoap_actions.envs.sim import TIMESTEP
from hoap_actions.policies.scripted_expert import ScriptedExpert

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json


def _moving_target(start: np.ndarray, k: int) -> np.ndarray:
    return start + np.array([0.03 * np.sin(k / 300), 0.04 * np.sin(k / 230), 0.015 * np.sin(k / 170)])


def bench_tick(ticks: int = 4000) -> dict[str, float]:
    """Median microseconds of the control computation (retimer step + IK solve) back to back, of
    its two parts, and of a whole controller tick inside the physics loop, the target moving."""
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    env.reset(seed=0)
    sim, hand = env.unwrapped.sim, env.unwrapped.controller.hand
    for _ in range(480):  # let the reset's posture and CoM targets settle
        hand.tick()
        sim.step(1)
    start = hand.reference.copy()
    compute, retimer, ik = [], [], []
    for k in range(ticks):
        t0 = time.perf_counter_ns()
        reference = hand.retimer.step(_moving_target(start, k)).position
        t1 = time.perf_counter_ns()
        hand.ik.solve(reference)
        t2 = time.perf_counter_ns()
        compute.append(t2 - t0)
        retimer.append(t1 - t0)
        ik.append(t2 - t1)
    env.reset(seed=0)
    start = hand.reference.copy()
    whole = []
    for k in range(ticks):
        hand.set_target(_moving_target(start, k))
        t0 = time.perf_counter_ns()
        hand.tick()
        whole.append(time.perf_counter_ns() - t0)
        sim.step(1)
    env.close()
    return {
        "compute_median_us": float(np.median(compute)) / 1e3,
        "retimer_median_us": float(np.median(retimer)) / 1e3,
        "ik_solve_median_us": float(np.median(ik)) / 1e3,
        "tick_in_physics_loop_median_us": float(np.median(whole)) / 1e3,
    }


def bench_expert(episodes: int, seed: int) -> dict:
    """Episodes of the scripted expert: wall and simulated time per episode, real-time factor, reasons."""
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    policy = ScriptedExpert(env)
    results = [run_episode(env, policy, seed + i) for i in range(episodes)]
    env.close()
    sim_seconds = np.array([r.steps * PHYSICS_STEPS_PER_ACTION * TIMESTEP for r in results])
    wall_seconds = np.array([r.wall_s for r in results])
    return {
        "episodes": episodes,
        "seeds": [seed, seed + episodes - 1],
        "success_rate": float(np.mean([r.success for r in results])),
        "reasons": dict(collections.Counter(r.reason for r in results)),
        "episode_wall_s_median": float(np.median(wall_seconds)),
        "episode_sim_s_median": float(np.median(sim_seconds)),
        "real_time_factor": float(sim_seconds.sum() / wall_seconds.sum()),
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("control_tick.json")])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args(argv)
    tick = bench_tick()
    expert = bench_expert(args.episodes, args.seed)
    print(
        f"control computation (retimer + IK): median {tick['compute_median_us']:.1f} us "
        f"(retimer {tick['retimer_median_us']:.1f} us, IK solve {tick['ik_solve_median_us']:.1f} us)"
    )
    print(
        f"whole tick in the physics loop (+ PyBullet hand read and 28 motor commands): "
        f"median {tick['tick_in_physics_loop_median_us']:.1f} us"
    )
    print(
        f"scripted expert, seeds {expert['seeds'][0]}..{expert['seeds'][1]}: success {expert['success_rate']:.0%}, "
        f"episode {expert['episode_wall_s_median']:.2f} s wall for {expert['episode_sim_s_median']:.2f} s simulated, "
        f"real-time factor {expert['real_time_factor']:.2f}"
    )
    print(f"  reasons: {expert['reasons']}")
    document = {"tick": tick, "expert": expert, "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
