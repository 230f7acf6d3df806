"""What one 240 Hz physics step costs, piece by piece: the floor under ``env_speed.py``'s figures.

Times ``Sim.step`` (median over runs of 480 steps, no Python control in the loop) for the PegInsert
world standing still, and for the humanoid alone on the floor, each with PyBullet's default 50
solver iterations and with the solver capped at 10 and at 1 iteration.  The humanoid alone with one
iteration is about the least PyBullet can spend on a free-standing 28-joint body under position
control; its simulated seconds per wall second bound any environment built on it at this rate.

    python benchmarks/physics_floor.py [--runs 5] [--steps 480]

Writes ``results/physics_floor.json``; earlier figures are in ``docs/experiments/speed.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

ITERATIONS = (None, 10, 1)  # None: PyBullet's default (50)


def step_cost_us(sim, steps: int, runs: int) -> float:
    """Median wall time of one ``sim.step()`` in microseconds."""
    walls = []
    for _ in range(runs):
        start = time.perf_counter()
        sim.step(steps)
        walls.append((time.perf_counter() - start) / steps)
    return 1e6 * statistics.median(walls)


def peg_insert_world(iterations: int | None, steps: int, runs: int) -> float:
    """The PegInsert environment's world after reset, the robot holding its posture."""
    import gymnasium

    import hoap_actions  # noqa: F401  (registers the ids)

    env = gymnasium.make("hoap_actions/PegInsert-v0")
    env.reset(seed=0)
    sim = env.unwrapped.sim
    if iterations is not None:
        sim.set_solver_iterations(iterations)
    cost = step_cost_us(sim, steps, runs)
    env.close()
    return cost


def robot_alone(iterations: int | None, steps: int, runs: int) -> float:
    """The humanoid alone on the floor plane, holding its home posture."""
    from hoap_actions.envs import world
    from hoap_actions.envs.robot import Robot
    from hoap_actions.envs.sim import Sim

    sim = Sim()
    sim.add_ground_plane(z=world.FLOOR_Z)
    Robot(sim)
    if iterations is not None:
        sim.set_solver_iterations(iterations)
    cost = step_cost_us(sim, steps, runs)
    sim.close()
    return cost


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], parents=[arguments("physics_floor.json")])
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--steps", type=int, default=480)
    args = parser.parse_args(argv)
    from hoap_actions.envs.sim import TIMESTEP

    rows = []
    for world_name, measure in (("PegInsert-v0 world", peg_insert_world), ("humanoid alone", robot_alone)):
        for iterations in ITERATIONS:
            cost = measure(iterations, args.steps, args.runs)
            row = {"world": world_name, "solver_iterations": iterations or 50, "step_us_median": cost,
                   "sim_s_per_wall_s_at_most": TIMESTEP * 1e6 / cost}
            rows.append(row)
            print(f"{world_name:20s} {row['solver_iterations']:3d} iterations: {cost:7.1f} us per step "
                  f"-> at most {row['sim_s_per_wall_s_at_most']:5.1f} simulated s per wall s")
    result = {"timestep_s": TIMESTEP, "steps_per_run": args.steps, "runs": args.runs, "rows": rows,
              "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, result)
    return result


if __name__ == "__main__":
    main()
