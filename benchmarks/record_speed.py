"""Recording speed: recordings (episodes) per second and simulated seconds per wall second.

Records a preset (``small`` by default) several times to a temporary directory, writing the HDF5 file
included, and reports the median of the runs, for each number of worker processes in ``--workers``:
the worker counts take turns run after run (a shared machine's load hits them alike), and the ratio of
the medians is printed beside the speeds.

    python benchmarks/record_speed.py [--preset small] [--runs 5] [--workers 1 2]

Printed and written to ``results/record_speed.json``; earlier figures are in ``docs/experiments/speed.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.demonstration.recording import record
from hoap_actions.demonstration.tasks import FPS

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json


def time_run(preset: str, seed: int, directory: Path, workers: int = 1) -> tuple[float, int, int, int]:
    """Wall seconds to record ``preset``; episodes, frames and file bytes of the result."""
    out = directory / f"{preset}-{seed}-{workers}.h5"
    start = time.perf_counter()
    record(preset, out, seed=seed, overwrite=True, progress=False, workers=workers)
    elapsed = time.perf_counter() - start
    demos = load_demonstrations(out)
    return elapsed, len(demos), int(demos.lengths().sum()), out.stat().st_size


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("record_speed.json")])
    parser.add_argument("--preset", default="small")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--workers", type=int, nargs="+", default=[1], help="worker counts to compare")
    args = parser.parse_args(argv)
    runs: dict[int, list] = {w: [] for w in args.workers}
    with tempfile.TemporaryDirectory() as directory:
        for seed in range(args.runs):
            for workers in args.workers:
                runs[workers].append(time_run(args.preset, seed, Path(directory), workers))
    rows = []
    for workers, timed in runs.items():
        walls = [r[0] for r in timed]
        median = statistics.median(walls)
        episodes = statistics.median(r[1] for r in timed)
        frames = statistics.median(r[2] for r in timed)
        rows.append({
            "preset": args.preset,
            "workers": workers,
            "runs": args.runs,
            "median_wall_s": median,
            "median_recordings_per_s": episodes / median,
            "median_sim_s_per_wall_s": frames / FPS / median,
            "episodes": episodes,
            "frames": frames,
            "file_bytes": statistics.median(r[3] for r in timed),
            "wall_s_per_run": walls,
            "speedup_over_first": (rows[0]["median_wall_s"] if rows else median) / median,
        })
        print(
            f"preset {args.preset}, {workers} worker(s): {rows[-1]['median_recordings_per_s']:.2f} recordings/s, "
            f"{rows[-1]['median_sim_s_per_wall_s']:.1f} simulated s per wall s (median of {args.runs} runs: "
            f"{median:.2f} s for {episodes:.0f} episodes, {frames:.0f} frames); "
            f"{rows[-1]['speedup_over_first']:.2f}x the {rows[0]['workers']}-worker speed"
        )
    document = {"results": rows, "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
