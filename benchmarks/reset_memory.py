"""How much a process grows per ``env.reset``: resident memory after warm-up resets, then after more.

Every reset rebuilds the physics world; anything kept per reset (by PyBullet, placo or this package)
shows here. One env per robot and control mode, in this process, one after the other.

    python benchmarks/reset_memory.py [--warmup 200] [--resets 10000]

Prints the growth and writes ``results/reset_memory.json``; the goal is under 5 MB per 10,000 resets.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

CONFIGS = ({"robot": "full", "control_mode": "joint_delta"}, {"robot": "full", "control_mode": "ee_delta"},
           {"robot": "fixed_legs", "control_mode": "joint_delta"})


def resident_kib() -> int:
    with open(f"/proc/{os.getpid()}/status") as status:
        return next(int(line.split()[1]) for line in status if line.startswith("VmRSS"))


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("reset_memory.json")])
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--resets", type=int, default=10_000)
    args = parser.parse_args(argv)
    import gymnasium

    import hoap_actions  # noqa: F401  (registers the environments)

    rows = []
    for config in CONFIGS:
        env = gymnasium.make("hoap_actions/PegInsert-v0", **config).unwrapped
        for seed in range(args.warmup):
            env.reset(seed=seed)
        gc.collect()
        before = resident_kib()
        for seed in range(args.resets):
            env.reset(seed=seed)
        gc.collect()
        grown = resident_kib() - before
        env.close()
        per_10k_mb = grown / args.resets * 10_000 / 1024
        rows.append({**config, "resets": args.resets, "grown_kib": grown, "per_10000_resets_mb": per_10k_mb})
        print(f"{config}: +{grown} KiB over {args.resets} resets ({per_10k_mb:.1f} MB per 10,000)", flush=True)
    document = {"benchmark": "reset_memory", "warmup": args.warmup, "rows": rows, "goal_mb_per_10000": 5.0,
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
