"""Where the tracker's error lies, by demonstrated task: a results file of ``benchmarks/tracking.py`` grouped by
the action and direction of each tracked episode.

The per-episode figures are read from the results file; each episode's task (e.g. ``push forward``) from its
recording's ground truth. Per task: the RMS over its episodes of the all-marker and pooled shoulder, elbow and
finger errors (filtered and, when the run smoothed, smoothed), and the mean class agreement. A diagnostic of a
finished run: nothing is chosen on it.

    python benchmarks/tracking_by_task.py benchmarks/results/tracking_sighting_352.json \
        --output benchmarks/results/tracking_sighting_352_by_task.json

Recordings are ``data/paper-s<seed>.h5`` (the ones the results file names).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, write_json


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("tracking_by_task.json", data=True)])
    parser.add_argument("results", type=Path, help="a results file written by benchmarks/tracking.py")
    return parser.parse_args(argv)


def task_names(demos, episodes: list[int]) -> dict[int, str]:
    """Each episode's demonstrated task, ``"<action> <direction>"``."""
    return {k: f"{demos[k].ground_truth.action} {demos[k].ground_truth.direction}" for k in episodes}


def by_task(episodes: list[dict], tasks: dict) -> dict:
    """Per task, the RMS over its episodes of each error and the mean class agreement (``episodes``: the results
    file's per-episode summaries, their ``"episode"`` a key of ``tasks``, which names each one's task)."""
    import numpy as np

    def rms(values: list[float]) -> float:
        return float(np.sqrt(np.mean(np.square(values))))

    out: dict[str, dict] = {}
    for task in sorted(set(tasks.values())):
        chosen = [e for e in episodes if tasks[e["episode"]] == task]
        figures = {"episodes": len(chosen),
                   "rms_m_all": rms([e["rms_m_all"] for e in chosen]),
                   "rms_m_pooled": rms([e["rms_m_pooled"] for e in chosen]),
                   "frame_accuracy": float(np.mean([e["frame_accuracy"] for e in chosen]))}
        if all("smoothed" in e for e in chosen):
            figures.update({"smoothed_rms_m_all": rms([e["smoothed"]["rms_m_all"] for e in chosen]),
                            "smoothed_rms_m_pooled": rms([e["smoothed"]["rms_m_pooled"] for e in chosen]),
                            "smoothed_frame_accuracy": float(np.mean([e["smoothed"]["frame_accuracy"]
                                                                      for e in chosen]))})
        out[task] = figures
    return out


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.demonstration.datasets import load_demonstrations

    try:
        results = json.loads(args.results.read_text())
        recordings = results["per_recording"]
    except (OSError, ValueError, KeyError, TypeError):
        print(f"error: {args.results} is not a results file of benchmarks/tracking.py (JSON with per_recording)",
              file=sys.stderr)
        raise SystemExit(2) from None
    episodes, tasks = [], {}
    for seed, recording in recordings.items():
        demos = load_demonstrations(ensure_recording("paper", int(seed), args.data))
        named = task_names(demos, [e["episode"] for e in recording["episodes"]])
        for e in recording["episodes"]:
            tasks[(seed, e["episode"])] = named[e["episode"]]
            episodes.append({**e, "episode": (seed, e["episode"])})
    table = by_task(episodes, tasks)
    for task, figures in table.items():
        smoothed = (f"; smoothed {100 * figures['smoothed_rms_m_all']:.2f} cm, {figures['smoothed_frame_accuracy']:.1%}"
                    if "smoothed_rms_m_all" in figures else "")
        print(f"{task:>14} ({figures['episodes']} episodes): all markers {100 * figures['rms_m_all']:.2f} cm, "
              f"classes {figures['frame_accuracy']:.1%}{smoothed}")
    document = {"protocol": {"results": str(args.results), "seeds": [int(s) for s in recordings],
                             "source_protocol": results.get("protocol")},
                "by_task": table}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
