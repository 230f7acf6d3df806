"""Environment speed: env steps per second and simulated seconds per wall second, per id.

Each figure is the median of several runs, with and without rendering an ``rgb_array`` frame every
step, for random actions (the robot often falls: many contacts) and for zero actions (it stands);
and the median time of a ``reset``, which builds the physics world afresh every episode. With
panda-gym installed (``pip install "hoap-actions[bench]"``), each env and control mode is also timed
against its panda-gym peer (``PandaPickAndPlace-v3`` for PegInsert, ``PandaReach-v3`` for Reach), the two
taking turns run after run on random actions, and the ratio of their simulated seconds per wall second
is printed. Both robot models are timed: ``full`` (free-standing) and ``fixed_legs`` (legs welded), and
each robot standing in joint_delta against the bare physics of its own world (``Sim.step`` alone), in
turns in the same run. ee_delta runs at the env's default IK period (``envs.controls.IK_PERIOD``).

    python benchmarks/env_speed.py [--runs 5] [--steps 300] [--peers-only] [--robots full fixed_legs]

Printed and written to ``results/env_speed.json``; earlier figures are in ``docs/experiments/speed.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import gymnasium

import hoap_actions
from hoap_actions.envs.hoap_env import PHYSICS_STEPS_PER_ACTION
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.envs.sim import TIMESTEP

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

PEERS = {"hoap_actions/PegInsert-v0": "PandaPickAndPlace-v3", "hoap_actions/Reach-v1": "PandaReach-v3"}


def time_run(env_id: str, render: bool, steps: int, seed: int, actions_kind: str, **kwargs) -> float:
    """Wall seconds for ``steps`` steps of random or zero actions (reset excluded); ``kwargs`` go to ``make``."""
    if render:
        kwargs["render_mode"] = "rgb_array"
    env = gymnasium.make(env_id, **kwargs)  # panda-gym refuses render_mode=None; its default draws nothing
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


def time_resets(env_id: str, control_mode: str, n: int) -> float:
    """Median wall seconds of ``env.reset(seed=s)`` over ``n`` seeds, each after a few steps."""
    env = gymnasium.make(env_id, control_mode=control_mode)
    env.reset(seed=0)
    walls = []
    for seed in range(n):
        for _ in range(5):
            env.step(env.action_space.sample() * 0)
        start = time.perf_counter()
        env.reset(seed=seed)
        walls.append(time.perf_counter() - start)
    env.close()
    return statistics.median(walls)


def compare_with_peers(runs: int, steps: int, sim_seconds_per_step: float, robots: list[str]) -> list[dict]:
    """Simulated seconds per wall second of each env, robot and control mode against its panda-gym
    peer, the two timed in turn ``runs`` times (random actions, no rendering); [] without panda-gym."""
    try:
        import panda_gym  # noqa: F401  (registers the Panda ids)
    except ImportError:
        print("panda-gym is not installed (pip install 'hoap-actions[bench]'): no peer comparison")
        return []
    out = []
    for env_id, peer in PEERS.items():
        probe = gymnasium.make(peer)
        peer_sim_s = probe.unwrapped.sim.timestep * probe.unwrapped.sim.n_substeps  # per env step
        probe.close()
        for robot in robots:
            for control_mode in ("joint_delta", "ee_delta"):
                ours, theirs = [], []
                for seed in range(runs):
                    ours.append(time_run(env_id, False, steps, seed, "random", control_mode=control_mode, robot=robot))
                    theirs.append(time_run(peer, False, steps, seed, "random"))
                ours_rate = steps * sim_seconds_per_step / statistics.median(ours)
                peer_rate = steps * peer_sim_s / statistics.median(theirs)
                out.append({"env_id": env_id, "robot": robot, "control_mode": control_mode, "peer": peer, "runs": runs,
                            "steps": steps, "sim_s_per_wall_s": ours_rate, "peer_sim_s_per_wall_s": peer_rate,
                            "steps_per_s": steps / statistics.median(ours),
                            "peer_steps_per_s": steps / statistics.median(theirs), "ratio": ours_rate / peer_rate,
                            # each round's ratio (the two envs took turns): the spread of the median's
                            "run_ratios": [sim_seconds_per_step * peer_wall / (peer_sim_s * our_wall)
                                           for our_wall, peer_wall in zip(ours, theirs)]})
                print(f"{env_id:28s} {robot:10s} {control_mode:11s} {ours_rate:6.2f} sim s / wall s against {peer} "
                      f"{peer_rate:6.2f}: {ours_rate / peer_rate:.2f}x")
    return out


def compare_with_physics_floor(runs: int, steps: int, robots: list[str]) -> list[dict]:
    """Each robot's joint_delta env standing (zero actions) against the bare physics of the same world
    (``Sim.step`` alone, as many ticks), the two taking turns ``runs`` times: what the env adds to its
    physics."""
    out = []
    for robot in robots:
        env_walls, floor_walls = [], []
        for seed in range(runs):
            env_walls.append(time_run("hoap_actions/PegInsert-v0", False, steps, seed, "zero", robot=robot))
            env = gymnasium.make("hoap_actions/PegInsert-v0", robot=robot)
            env.reset(seed=seed)
            sim = env.unwrapped.sim  # the benchmark times the simulator itself, under the env
            start = time.perf_counter()
            for _ in range(steps):
                sim.step(PHYSICS_STEPS_PER_ACTION)
            floor_walls.append(time.perf_counter() - start)
            env.close()
        ratio = statistics.median(floor_walls) / statistics.median(env_walls)
        out.append({"robot": robot, "control_mode": "joint_delta", "actions": "zero", "runs": runs, "steps": steps,
                    "steps_per_s": steps / statistics.median(env_walls),
                    "floor_steps_per_s": steps / statistics.median(floor_walls), "ratio_to_floor": ratio})
        print(f"PegInsert-v0 {robot:10s} joint_delta standing: {ratio:.2f}x its bare physics (same world, same run)")
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("env_speed.json")])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--peers-only", action="store_true", help="only the comparison with panda-gym")
    parser.add_argument("--robots", nargs="+", choices=list(ROBOT_MODELS), default=list(ROBOT_MODELS))
    args = parser.parse_args(argv)
    sim_seconds_per_step = PHYSICS_STEPS_PER_ACTION * TIMESTEP
    peers = compare_with_peers(args.runs, args.steps, sim_seconds_per_step, args.robots)
    floors = compare_with_physics_floor(args.runs, args.steps, args.robots)
    rows = []
    cases = [(env_id, robot, kind, render) for env_id in hoap_actions.ENV_IDS for robot in args.robots
             for kind, render in (("random", False), ("zero", False), ("random", True))]
    for env_id, robot, actions_kind, render in [] if args.peers_only else cases:
        steps = args.steps if not render else max(args.steps // 5, 20)
        walls = [time_run(env_id, render, steps, seed, actions_kind, robot=robot) for seed in range(args.runs)]
        median = statistics.median(walls)
        row = {
            "env_id": env_id,
            "robot": robot,
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
            f"{env_id:28s} {robot:10s} {actions_kind:6s} render={str(render):5s}  {row['median_steps_per_s']:8.1f} "
            "steps/s  "
            f"{row['median_sim_s_per_wall_s']:6.2f} sim s / wall s  "
            f"({row['median_physics_step_ms']:.3f} ms per physics step incl. overhead)"
        )
    resets = []
    for env_id in () if args.peers_only else hoap_actions.ENV_IDS:
        for control_mode in ("joint_delta", "ee_delta"):
            median = time_resets(env_id, control_mode, 5 * args.runs)
            resets.append({"env_id": env_id, "control_mode": control_mode, "median_reset_ms": 1e3 * median})
            print(f"{env_id:28s} {control_mode:11s} reset {1e3 * median:6.1f} ms (median of {5 * args.runs})")
    document = {"results": rows, "resets": resets, "peers": peers, "physics_floor": floors,
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
