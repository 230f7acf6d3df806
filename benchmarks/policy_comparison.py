"""The PHMM policy beside the scripted expert on the same grasp-and-insert layouts, in the same run.

Held-out layouts, declared before the first run of the PHMM policy: ``PegInsert-v0`` resets with
seeds 30000-30199 (200 layouts), used once for the figure. The policy was developed on seeds 0-99
(``--seeds 0 100``). Both policies run every layout, interleaved seed by seed in one env per worker,
so machine load falls alike on both. Per policy: success rate with its 95 % Wilson interval, falls,
mean episode wall time, reasons for failure; for the PHMM policy also the perception error (largest
centre error of the target peg and hole) and each synthesised path's largest deviation from the
executed hand path.

Held-out layouts for the two robot models (``--robot full`` / ``fixed_legs``), each declared in
``docs/experiments/robot.md`` before its run and used once: 60000-60199 for both robots; 62000-62199 and then
63000-63199 for the two later versions of the welded-legs robot; 64100-64299 and 65000-65199 later; 66000-66199
(welded legs) and 67000-67199 (free-standing) for the hand controller's IK period and the folded URDF.

    python benchmarks/policy_comparison.py [--seeds 30000 30200] [--workers 2] [--models DIR] [--robot fixed_legs]

Writes ``results/policy_comparison.json`` (or ``--output``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from hoap_actions.apps.episodes import compare_policies, summarise
from hoap_actions.envs.robot import ROBOT_MODELS

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

HELD_OUT_SEEDS = (30000, 30200)  # [first, last): never run while the PHMM policy was developed (seeds 0-99)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("policy_comparison.json")])
    parser.add_argument("--seeds", type=int, nargs=2, default=HELD_OUT_SEEDS, metavar=("FIRST", "STOP"))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--models", type=Path, default=None, help="models directory (default: the shipped models)")
    parser.add_argument("--robot", default="full", choices=list(ROBOT_MODELS))
    args = parser.parse_args()
    seeds = range(*args.seeds)
    phmm_kwargs = {} if args.models is None else {"models": str(args.models)}
    start = time.perf_counter()
    results = compare_policies("hoap_actions/PegInsert-v0",
                               {"phmm": ("phmm", phmm_kwargs), "scripted": ("scripted", {})},
                               seeds, workers=args.workers, robot=args.robot)
    document = {"seeds": list(args.seeds), "robot": args.robot, "workers": args.workers,
                "wall_s": time.perf_counter() - start, "environment": numeric_environment(None)}
    for name, episodes in results.items():
        summary = summarise(episodes)
        document[name] = summary
        low, high = summary["success_ci95"]
        print(f"{name:>9} ({args.robot}): success {summary['success_rate']:.1%} [{low:.1%}, {high:.1%}] over "
              f"{len(episodes)} layouts, "
              f"falls {summary['falls']}, mean episode {summary['mean_wall_s']:.1f} s, {summary['reasons']}")
        if "perception_error_m" in summary:
            p = summary["perception_error_m"]
            print(f"           perception error (target peg and hole): median {1000 * (p['median'] or 0):.2f} mm, "
                  f"max {1000 * (p['max'] or 0):.2f} mm, not located {p['not_located']}")
            for path, d in summary["path_deviation_m"].items():
                print(f"           {path} path deviation from the executed hand: median {1000 * d['median']:.1f} mm, "
                      f"max {1000 * d['max']:.1f} mm")
    write_json(args.output, document)


if __name__ == "__main__":
    main()
