"""Perception accuracy: peg and hole centres located from the overhead camera against the simulator's poses.

Held-out layouts, declared before the first run: the method was tuned on ``PegInsert-v0`` resets with
seeds 0-49 and measured once on seeds 10000-10099 in the home posture (``joint_delta``), whose level
forearm hid 2 pegs. Since then the face fit needs three points (a 2-pixel face crashed it on seed 12
of the PHMM policy's development seeds) and the robot acts from the ee_delta start posture, hand out
of the camera's view: measured once more on fresh seeds 11000-11099 in that posture. The rework of
``locate`` for speed (same method, about 170 ms per image before) was developed on seeds 12000-12049
(and 0-49) and measured once on fresh seeds 11100-11199 (the default; ``--seeds`` and
``--control-mode`` to change). Centres as defined in ``hoap_actions.vision.perception``: a peg's
centre of mass (its base position), a hole's axis at the board's top surface
(``Scene.hole_positions``). A detection is matched to the nearest true object of its kind within
``MATCH_RADIUS``; a true object with no match is missed, a detection with none is a phantom. The
segmentation image is never given to the perception.

    python benchmarks/perception_accuracy.py [--seeds 11100 11200] [--width 320]

Prints per object type the median and max 3-D centre error, missed, phantom and the time per image
(render and perception apart); writes ``results/perception_accuracy.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import gymnasium
import numpy as np

import hoap_actions  # noqa: F401 - registers the envs
from hoap_actions.vision.perception import locate

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

# [first, last) seeds, never used while tuning (0-49), reworking for speed (12000-12049) or measuring before
# (10000-10099, 11000-11099)
HELD_OUT_SEEDS = (11100, 11200)
MATCH_RADIUS = 0.01  # m, a detection farther than this from every true object of its kind is a phantom


def measure(seeds: range, width: int, control_mode: str = "ee_delta") -> dict:
    """Errors (m) per kind, missed and phantom counts, failures by seed, and timings (s)."""
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode=control_mode)
    sim, scene = env.unwrapped.sim, env.unwrapped.scene
    errors: dict[str, list[float]] = {"peg": [], "hole": []}
    missed = {"peg": 0, "hole": 0}
    phantom = {"peg": 0, "hole": 0}
    failures: list[dict] = []
    render_s, locate_s = [], []
    for seed in seeds:
        env.reset(seed=seed)
        camera = replace(sim.cameras["overhead"], width=width, height=width * 3 // 4)
        start = time.perf_counter()
        image = sim.render(camera)
        render_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        found = locate(image.rgb, image.depth, camera)
        locate_s.append(time.perf_counter() - start)
        truth_pegs = {name.removeprefix("peg_"): scene.peg_pose(i)[0] for i, name in enumerate(scene.peg_names)}
        for colour, true in truth_pegs.items():
            detection = found.peg(colour)
            if detection is None:
                missed["peg"] += 1
                failures.append({"seed": seed, "peg": colour, "missed": True})
                continue
            error = float(np.linalg.norm(detection.position_m - true))
            if error > MATCH_RADIUS:
                missed["peg"] += 1
                phantom["peg"] += 1
            else:
                errors["peg"].append(error)
            if error > 0.001:
                failures.append({"seed": seed, "peg": colour, "error_mm": 1000 * error,
                                 "confidence": detection.confidence})
        true_holes = scene.hole_positions()
        matched = set()
        for hole in found.holes:
            distances = np.linalg.norm(true_holes - hole.position_m, axis=1)
            nearest = int(np.argmin(distances))
            if distances[nearest] > MATCH_RADIUS or nearest in matched:
                phantom["hole"] += 1
                continue
            matched.add(nearest)
            errors["hole"].append(float(distances[nearest]))
            if distances[nearest] > 0.001:
                failures.append({"seed": seed, "hole": nearest, "error_mm": 1000 * float(distances[nearest])})
        missed["hole"] += len(true_holes) - len(matched)
    env.close()
    return {"errors": errors, "missed": missed, "phantom": phantom, "failures": failures,
            "render_s": render_s, "locate_s": locate_s}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("perception_accuracy.json")])
    parser.add_argument("--seeds", type=int, nargs=2, default=HELD_OUT_SEEDS, metavar=("FIRST", "END"))
    parser.add_argument("--width", type=int, default=320, help="image width in px, height 3/4 of it (default "
                                                               "%(default)s)")
    parser.add_argument("--control-mode", default="ee_delta", choices=["ee_delta", "joint_delta"],
                        help="the posture the robot starts in: ee_delta's (hand out of view) or the home posture")
    args = parser.parse_args()
    seeds = range(*args.seeds)
    result = measure(seeds, args.width, args.control_mode)
    summary = {}
    for kind in ("peg", "hole"):
        mm = 1000 * np.asarray(result["errors"][kind])
        summary[kind] = {"median_error_mm": float(np.median(mm)), "max_error_mm": float(mm.max()),
                         "located": int(mm.size), "missed": result["missed"][kind], "phantom": result["phantom"][kind]}
        print(f"{kind:5s} median {summary[kind]['median_error_mm']:.3f} mm  max {summary[kind]['max_error_mm']:.3f} "
              "mm  "
              f"located {mm.size}  missed {result['missed'][kind]}  phantom {result['phantom'][kind]}")
    render_ms, locate_ms = 1000 * np.median(result["render_s"]), 1000 * np.median(result["locate_s"])
    print(f"per image ({args.width}x{args.width * 3 // 4}): render {render_ms:.1f} ms, perception {locate_ms:.1f} ms "
          "(medians)")
    for failure in result["failures"]:
        print("  over 1 mm or missed:", failure)
    write_json(args.output, {
        "seeds": [seeds.start, seeds.stop], "control_mode": args.control_mode,
        "image_size": [args.width, args.width * 3 // 4], **summary,
        "render_ms_median": render_ms, "perception_ms_median": locate_ms, "failures": result["failures"],
        "environment": numeric_environment(None, opencv=cv2.__version__),
    })


if __name__ == "__main__":
    main()
