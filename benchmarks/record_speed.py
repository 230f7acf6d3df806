"""Recording speed: recordings (episodes) per second and simulated seconds per wall second.

Records a preset (``small`` by default) several times to a temporary directory, writing the HDF5 file
included, and reports the median of the runs.

    python benchmarks/record_speed.py [--preset small] [--runs 5]

Printed and written to ``results/record_speed.json``; earlier figures are in ``results/NOTES.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

from hoap_actions.envs.demo_tasks import FPS
from hoap_actions.envs.recording import record
from hoap_actions.primitives.datasets import load_demonstrations

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json  # noqa: E402


def time_run(preset: str, seed: int, directory: Path) -> tuple[float, int, int, int]:
    """Wall seconds to record ``preset``; episodes, frames and file bytes of the result."""
    out = directory / f"{preset}-{seed}.h5"
    start = time.perf_counter()
    record(preset, out, seed=seed, overwrite=True, progress=False)
    elapsed = time.perf_counter() - start
    demos = load_demonstrations(out)
    return elapsed, len(demos), int(demos.lengths().sum()), out.stat().st_size


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("record_speed.json")])
    parser.add_argument("--preset", default="small")
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as directory:
        runs = [time_run(args.preset, seed, Path(directory)) for seed in range(args.runs)]
    walls = [r[0] for r in runs]
    median = statistics.median(walls)
    episodes = statistics.median(r[1] for r in runs)
    frames = statistics.median(r[2] for r in runs)
    row = {
        "preset": args.preset,
        "runs": args.runs,
        "median_wall_s": median,
        "median_recordings_per_s": episodes / median,
        "median_sim_s_per_wall_s": frames / FPS / median,
        "episodes": episodes,
        "frames": frames,
        "file_bytes": statistics.median(r[3] for r in runs),
        "wall_s_per_run": walls,
    }
    print(
        f"preset {args.preset}: {row['median_recordings_per_s']:.2f} recordings/s, "
        f"{row['median_sim_s_per_wall_s']:.1f} simulated s per wall s "
        f"(median of {args.runs} runs: {median:.2f} s for {episodes:.0f} episodes, {frames:.0f} frames)"
    )
    document = {"results": [row], "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    print(f"wrote {args.output}")
    return document


if __name__ == "__main__":
    main()
