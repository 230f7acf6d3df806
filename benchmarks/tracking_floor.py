"""How close the shipped models' poses can come to recorded demonstrations: the floor under the tracker's pose error.

Per recording (``paper`` preset, episodes 0, 13, ..., 91): :func:`hoap_actions.tracking.pose_floor`, the
distance of each marker from the PHMM mean pose of discovery's class of the frame, at the segment's true
effect and, second, at the effect that fits the segment best, with the best phase per frame and no
offset. RMS pooled over the frames of known class, for all six markers and the issue's shoulder, elbow
and finger. A diagnostic: nothing is chosen on it, so it may run on any recording (a training one,
validation 300, held-out ones already used).

    python benchmarks/tracking_floor.py [--seeds 0 300 310 311 312] [--episodes 0 13 26 ...]

Recordings are ``data/paper-s<seed>.h5``, recorded when missing. Writes ``results/tracking_floor.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, write_json

EPISODES = tuple(range(0, 104, 13))


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("tracking_floor.json", data=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 300, 310, 311, 312],
                        help="paper recordings (0: a training one; 300: validation; 310-312: held-out, already used)")
    parser.add_argument("--episodes", type=int, nargs="+", default=list(EPISODES))
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    import numpy as np

    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import load_default_models
    from hoap_actions.tracking import SCORED_MARKERS, pose_floor

    started = time.perf_counter()
    models = load_default_models()
    names = list(models.marker_names_)
    per_recording = {}
    for seed in args.seeds:
        demos = load_demonstrations(ensure_recording("paper", seed, args.data))
        per_recording[seed] = {}
        for effect, fit in (("true_effect", False), ("fitted_effect", True)):
            distances = np.concatenate([pose_floor(models, demos, k, fit_effect=fit) for k in args.episodes])
            known = distances[np.isfinite(distances[:, 0])]
            figures = {"rms_m_all": float(np.sqrt(np.mean(known**2))), "frames": int(len(known)),
                       "rms_m": {m: float(np.sqrt(np.mean(known[:, names.index(m)] ** 2))) for m in SCORED_MARKERS}}
            per_recording[seed][effect] = figures
            print(f"paper seed {seed}, {effect.replace('_', ' ')}: RMS all {100 * figures['rms_m_all']:.2f} cm, "
                  + ", ".join(f"{m} {100 * v:.2f}" for m, v in figures["rms_m"].items()) + " cm", flush=True)
    summary = {effect: {"rms_m_all": spread([r[effect]["rms_m_all"] for r in per_recording.values()]),
                        **{f"rms_m_{m}": spread([r[effect]["rms_m"][m] for r in per_recording.values()])
                           for m in SCORED_MARKERS}}
               for effect in ("true_effect", "fitted_effect")}
    result = {"protocol": {"seeds": args.seeds, "episodes": args.episodes, "models": "shipped default models"},
              "summary": summary, "per_recording": per_recording,
              "environment": {**numeric_environment(None), "runtime_s": round(time.perf_counter() - started, 1)}}
    write_json(args.output, result)
    return result


if __name__ == "__main__":
    main()
