"""How a sweep stops: SIGINT or SIGTERM at seeded random moments of ``hoap-actions demo --workers 2``.

Each trial starts the command (a long sweep, or a short one that is filming or writing when the signal
lands), sends the signal, and records the exit status, the time from the signal to the exit, how long
until no process of the run is left, and the files left in its output folder.

    python benchmarks/interrupts.py [--trials 20] [--seed 20261205]

Writes ``results/interrupts.json``; the goal is exit 130 within 2 s, no process and no file left.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

LONG, SHORT = 1000, 6  # episodes: a sweep the signal always interrupts, and one it may catch writing


def run_trial(sig: signal.Signals, after_s: float, episodes: int) -> dict:
    out = Path(tempfile.mkdtemp(prefix="hoap-interrupt-"))
    command = [sys.executable, "-m", "hoap_actions", "demo", "--episodes", str(episodes), "--workers", "2",
               "--json", str(out / "report.json"), "--video", str(out / "video.mp4")]
    proc = subprocess.Popen(command, cwd=out, start_new_session=True, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    time.sleep(after_s)
    sent = time.monotonic()
    if proc.poll() is None:
        proc.send_signal(sig)
    proc.wait(timeout=120)
    stopped = time.monotonic() - sent
    gone = None
    while time.monotonic() - sent < stopped + 10:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            gone = time.monotonic() - sent - stopped
            break
        time.sleep(0.05)
    else:
        os.killpg(proc.pid, signal.SIGKILL)
    return {"signal": sig.name, "after_s": round(after_s, 2), "episodes": episodes, "exit": proc.returncode,
            "stop_s": round(stopped, 3), "processes_gone_after_exit_s": None if gone is None else round(gone, 3),
            "files_left": sorted(p.name for p in out.iterdir())}


def summarise(rows: list[dict]) -> dict:
    gone = [r["processes_gone_after_exit_s"] for r in rows]
    return {"trials": len(rows), "exit_130": sum(r["exit"] == 130 for r in rows),
            "killed_by_the_signal_itself": sum(r["exit"] in (-signal.SIGINT, -signal.SIGTERM) for r in rows),
            "max_stop_s": max(r["stop_s"] for r in rows),
            "processes_left_after_10_s": sum(g is None for g in gone),
            "max_processes_gone_after_exit_s": max(g for g in gone if g is not None),
            "trials_with_files_left": sum(bool(r["files_left"]) for r in rows)}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("interrupts.json")])
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--seed", type=int, default=20261205)
    args = parser.parse_args(argv)
    draw = random.Random(args.seed)
    rows = []
    for trial in range(args.trials):
        sig = (signal.SIGINT, signal.SIGTERM)[trial % 2]
        episodes = LONG if trial < args.trials - 4 else SHORT
        rows.append(run_trial(sig, draw.uniform(0.2, 14.0), episodes))
        print(rows[-1], flush=True)
    summary = summarise(rows)
    print(summary)
    write_json(args.output, {"benchmark": "interrupts", "seed": args.seed, "rows": rows, "summary": summary,
                             "goal": {"exit": 130, "stop_s": 2.0, "files_left": 0},
                             "environment": numeric_environment(blas_threads=None)})
    return summary


if __name__ == "__main__":
    main()
