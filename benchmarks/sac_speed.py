"""SAC + HER's wall time, Stable-Baselines3's learner against SBX's (the same algorithm and settings in JAX),
with each run's learning curve: ``examples/train_sb3.py`` run for every training seed with each learner in
turn (the order alternating from seed to seed), one run at a time.

The wall time is the whole run as a user waits for it (training and the evaluations, the process's
start-up included); the time inside ``learn`` alone is kept beside it. The learning curves are the
success rates on the evaluation layouts at every ``--eval-every`` steps: the change in learner should
leave them within their spread over seeds.

    pip install "hoap-actions[rl,sbx]"
    python benchmarks/sac_speed.py [--seeds 0 1 2] [--robot fixed_legs] [--steps 50000]

Writes ``results/sac_speed.json``; the figures and their history are in ``docs/experiments/rl.md``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

from hoap_actions.envs.robot import ROBOT_MODELS

SCRIPT = Path(__file__).resolve().parents[1] / "examples" / "train_sb3.py"
LEARNERS = ("sb3", "sbx")


def run_once(learner: str, seed: int, args: argparse.Namespace, folder: Path) -> dict:
    """One training run in its own process: its wall time and the learning curve it wrote."""
    curve = folder / f"{learner}_{seed}.json"
    command = [sys.executable, str(SCRIPT), "--learner", learner, "--robot", args.robot, "--env", args.env,
               "--steps", str(args.steps), "--eval-every", str(args.eval_every), "--seed", str(seed),
               "--eval-first-seed", str(args.eval_first_seed), "--eval-episodes", str(args.eval_episodes),
               "--json", str(curve)]
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        raise SystemExit(f"{learner} seed {seed} failed: {last}")
    points = json.loads(curve.read_text())["curve"]
    print(f"{learner} seed {seed}: {wall / 60:.1f} min, learn {points[-1]['learn_wall_s'] / 60:.1f} min, success "
          + " / ".join(f"{p['success_rate']:.0%}" for p in points), flush=True)
    return {"learner": learner, "seed": seed, "wall_s": wall, "learn_wall_s": points[-1]["learn_wall_s"],
            "curve": [{key: p[key] for key in ("steps", "success_rate", "falls", "learn_wall_s")} for p in points]}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("sac_speed.json")])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--robot", choices=list(ROBOT_MODELS), default="fixed_legs")
    parser.add_argument("--env", default="hoap_actions/Reach-v1")
    parser.add_argument("--steps", type=int, default=50000)
    parser.add_argument("--eval-every", type=int, default=10000)
    parser.add_argument("--eval-first-seed", type=int, default=50000)
    parser.add_argument("--eval-episodes", type=int, default=50)
    args = parser.parse_args(argv)
    missing = [module for module in ("stable_baselines3", "sbx") if importlib.util.find_spec(module) is None]
    if missing or min(args.steps, args.eval_every, args.eval_episodes) < 1 or min(args.seeds) < 0:
        # checked before the first run: a missing learner would otherwise fail after a quarter of an hour
        parser.error(f"needs {missing} (pip install 'hoap-actions[rl,sbx]')" if missing else
                     "--steps, --eval-every and --eval-episodes must be >= 1 and --seeds >= 0")
    runs = []
    with tempfile.TemporaryDirectory() as folder:
        for k, seed in enumerate(args.seeds):
            for learner in LEARNERS if k % 2 == 0 else LEARNERS[::-1]:
                runs.append(run_once(learner, seed, args, Path(folder)))
    summary = {}
    for learner in LEARNERS:
        mine = [run for run in runs if run["learner"] == learner]
        summary[learner] = {
            "median_wall_s": statistics.median(run["wall_s"] for run in mine),
            "median_learn_wall_s": statistics.median(run["learn_wall_s"] for run in mine),
            "success_by_steps": {point["steps"]: [run["curve"][i]["success_rate"] for run in mine]
                                 for i, point in enumerate(mine[0]["curve"])},
        }
    ratio = summary["sb3"]["median_wall_s"] / summary["sbx"]["median_wall_s"]
    print(f"wall time, median over seeds: sb3 {summary['sb3']['median_wall_s'] / 60:.1f} min, sbx "
          f"{summary['sbx']['median_wall_s'] / 60:.1f} min: {ratio:.2f}x faster")
    document = {"settings": {key: value for key, value in vars(args).items() if key != "output"}, "runs": runs,
                "summary": summary, "wall_ratio_sb3_over_sbx": ratio,
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
