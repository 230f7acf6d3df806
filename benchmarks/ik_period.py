"""ee_delta's IK period: physics ticks per retimer and IK step, against speed and tracking.

For each robot and period, in one run: env steps per second on random actions (each period and
joint_delta taking turns, ``--runs`` times; medians), and the scripted expert and the PHMM policy
on the same layouts: success, falls and the hand's tracking error (per episode, the 95th percentile
over steps of the measured hand's distance from the controller's reference; median and max over
episodes). Period 1 is the controller as it was (an IK step every tick).

Layouts: validation only (the period was chosen on seeds 70000-70049, then compared paired on
71000-71099 with ``--runs 0 --policies phmm``, no speed); the chosen periods were measured once on
held-out layouts by ``policy_comparison.py`` (``docs/experiments/robot.md``).

    python benchmarks/ik_period.py [--robots full fixed_legs] [--periods 1 2 4 8] [--seeds 70000 70050]
                                   [--runs 5] [--policies scripted phmm] [--workers 1]

Writes ``results/ik_period.json``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import compare_policies, summarise

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json
from env_speed import time_run

ENV_ID = "hoap_actions/PegInsert-v0"


def steps_per_second(robot: str, period: int | None, steps: int, seed: int = 0) -> float:
    """Env steps per wall second on random actions; ``period`` None is joint_delta."""
    kwargs = {"control_mode": "joint_delta"} if period is None else {"control_mode": "ee_delta", "ik_period": period}
    return steps / time_run(ENV_ID, False, steps, seed, "random", robot=robot, **kwargs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], parents=[arguments("ik_period.json")])
    parser.add_argument("--robots", nargs="+", default=["full", "fixed_legs"])
    parser.add_argument("--periods", nargs="+", type=int, default=[1, 2, 4, 8])
    parser.add_argument("--seeds", nargs=2, type=int, default=[70000, 70050], metavar=("FIRST", "STOP"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--policies", nargs="+", choices=["scripted", "phmm"], default=["scripted", "phmm"])
    args = parser.parse_args()
    seeds = list(range(*args.seeds))
    rows = []
    for robot in args.robots:
        speeds: dict[str, list[float]] = {}
        for _ in range(args.runs):
            for period in [None, *args.periods]:
                speeds.setdefault(str(period or "joint_delta"), []).append(
                    steps_per_second(robot, period, args.steps))
        for period in args.periods:
            results = compare_policies(ENV_ID, {name: (name, {}) for name in args.policies}, seeds,
                                       workers=args.workers, robot=robot, env_kwargs={"ik_period": period})
            row: dict = {"robot": robot, "ik_period": period}
            if args.runs:
                row["steps_per_s"] = statistics.median(speeds[str(period)])
                row["joint_delta_steps_per_s"] = statistics.median(speeds["joint_delta"])
                row["ratio_to_joint_delta"] = row["steps_per_s"] / row["joint_delta_steps_per_s"]
            for name, episodes in results.items():
                summary = summarise(episodes)
                row[name] = {key: summary.get(key) for key in
                             ("success_rate", "success_ci95", "falls", "reasons", "hand_error_m", "mean_wall_s")}
                row[name]["failures"] = [[e.seed, e.reason] for e in episodes if not e.success]
            rows.append(row)
            speed = f"{row['ratio_to_joint_delta']:.2f}x joint_delta; " if args.runs else ""
            print(f"{robot} period {period}: {speed}" + ", ".join(
                f"{name} {row[name]['success_rate']:.1%} (hand error p95 median "
                f"{row[name]['hand_error_m']['median'] * 1e3:.2f} mm)" for name in args.policies), flush=True)
    write_json(args.output, {"benchmark": "ik_period", "seeds": args.seeds, "runs": args.runs,
                             "steps": args.steps, "rows": rows, "environment": numeric_environment(None)})


if __name__ == "__main__":
    main()
