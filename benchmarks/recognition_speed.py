"""Recognition speed: ``hoap-actions recognize`` on a held-out recording, with and without the scoring pass.

Runs the command (start-up included: what a user waits for) on a ``paper`` recording (seed 112 by
default, made under ``--data`` when missing) with the shipped models, for each ``--jobs`` and both
oracle settings (the default, which also recognises the true segments with their cuts given, and
``--no-oracle``); the settings take turns run after run, so a shared machine's load hits them alike,
and each run notes the 1-minute load average beside its time. Reports the median wall time and the
real-time factor (seconds of movement per wall second), and checks that every setting writes the same
figures (timings aside).

    python benchmarks/recognition_speed.py [--seed 112] [--runs 3] [--jobs 1 2]

Printed and written to ``results/recognition_speed.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, write_json

TIMINGS = ("wall_s", "decode_s", "jobs")
"""Keys of the command's JSON that are timings or settings, not figures."""


def time_run(demos: Path, jobs: int, oracle: bool, directory: Path) -> tuple[float, float, dict]:
    """Wall seconds of one ``recognize`` command, the load average before it, and the JSON it wrote."""
    report = directory / f"recognize-{jobs}-{oracle}.json"
    command = [sys.executable, "-m", "hoap_actions", "recognize", "--demos", str(demos), "--jobs", str(jobs),
               "--json", str(report), "--overwrite", "--oracle" if oracle else "--no-oracle"]
    load = os.getloadavg()[0]
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start, load, json.loads(report.read_text())


def _figures(report: dict) -> dict:
    """A report's figures: its keys but the timings and settings."""
    return {k: v for k, v in report.items() if k not in TIMINGS}


def _row(jobs: int, oracle: bool, timed: list[tuple[float, float, dict]], figures: dict) -> dict:
    """One setting's runs summed up (and printed), and whether each wrote ``figures``."""
    walls = [wall for wall, _, _ in timed]
    median = statistics.median(walls)
    movement = timed[0][2]["movement_s"]
    loads = [round(load, 2) for _, load, _ in timed]
    same = all(_figures(report) == figures for _, _, report in timed)
    print(f"{'default (oracle)' if oracle else '--no-oracle'}, {jobs} job(s): median {median:.1f} s for "
          f"{movement:.0f} s of movement, {movement / median:.1f}x real time (loads {loads}); "
          f"figures {'the same' if same else 'DIFFERENT'} over runs and jobs")
    return {"jobs": jobs, "oracle": oracle, "runs": len(timed), "median_wall_s": median, "movement_s": movement,
            "real_time_factor": movement / median, "wall_s_per_run": walls, "load_average_per_run": loads,
            "same_figures": same}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("recognition_speed.json", data=True)])
    parser.add_argument("--seed", type=int, default=112, help="the paper recording's seed (default: %(default)s)")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--jobs", type=int, nargs="+", default=[2], help="worker counts to compare")
    args = parser.parse_args(argv)
    demos = ensure_recording("paper", args.seed, args.data)
    settings = [(jobs, oracle) for oracle in (True, False) for jobs in args.jobs]
    runs: dict[tuple[int, bool], list] = {setting: [] for setting in settings}
    with tempfile.TemporaryDirectory() as directory:
        for _ in range(args.runs):
            for jobs, oracle in settings:
                runs[jobs, oracle].append(time_run(demos, jobs, oracle, Path(directory)))
    figures = {oracle: _figures(runs[args.jobs[0], oracle][0][2]) for oracle in (True, False)}
    rows = [_row(jobs, oracle, timed, figures[oracle]) for (jobs, oracle), timed in runs.items()]
    document = {"demos": str(demos), "results": rows, "figures": figures[True],
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
