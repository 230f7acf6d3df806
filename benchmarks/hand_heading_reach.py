"""How far the robot's hand can turn about the vertical where it stands: the headings the whole-body IK
reaches, asked of it (``WholeBodyIK.probe(..., heading=...)``), at points of ``Imitate-v0``'s block area.

The ee_delta action sets the hand's position; the IK then picks the heading (the forearm's direction,
seen from above). The block skills can only press on the block at headings near that one, which is what
the imitation's execution ceiling misses (``docs/experiments/imitation.md``). This asks, at each point
of a grid over the area where the robot's blocks start and end and at the heights of a grasp and of a
thumb push, for the IK's own heading turned by each of ``--turns`` degrees, and records the heading it
reaches and how far the hand leaves its point (IK model only, no physics).

    python benchmarks/hand_heading_reach.py [--robot fixed_legs|full] [--hand right|left] [--heading-weight W]

``--hand left`` asks the same of the left hand (which the envs do not act with): where it reaches the
block area and how it is headed there. ``--heading-weight`` is the IK's weight of the heading asked (1, the
default, as the tilt task's; ``ee_heading_delta`` asks with 100). Writes
``results/hand_heading_reach_<robot>[_left_hand][_weight<W>].json``: per point and height, the IK's heading
and, per asked turn, the turn reached (deg), the palm's tilt from level (deg) and the hand's distance from
its point (mm); and, over the points, the largest turn each way reached with the hand no further than
``--tolerance`` beyond where the IK alone puts it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import gymnasium
import numpy as np

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.controllers.hand_control import rest_posture
from hoap_actions.controllers.wholebody_ik import WholeBodyIK
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.policies.block_skills import GRASP_Z, PUSH_Z

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import RESULTS, arguments, numeric_environment, write_json

XS = (-0.03, 0.0, 0.03)  # m, forward of the table's centre line (Imitate-v0's block area)
YS = (-0.06, -0.03, 0.0, 0.03, 0.06, 0.09)  # m, to the robot's left
HEIGHTS = {"grasp": GRASP_Z, "push": PUSH_Z}


def heading(rotation: np.ndarray) -> float:
    return float(np.degrees(np.arctan2(rotation[1, 0], rotation[0, 0])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("hand_heading_reach.json")])
    parser.add_argument("--robot", default="fixed_legs", choices=list(ROBOT_MODELS))
    parser.add_argument("--turns", type=float, nargs="+", default=[-45, -30, -15, -5, 5, 15, 30, 45],
                        help="turns asked of the IK's own heading (deg)")
    parser.add_argument("--hand", default="right", choices=["right", "left"],
                        help="the hand asked (the envs act with the right one)")
    parser.add_argument("--heading-weight", type=float, default=1.0,
                        help="the IK's weight of the asked heading (per rad^2; ee_heading_delta's is 100)")
    parser.add_argument("--tolerance", type=float, default=0.001, help="how much further from its point (m) than "
                        "without a heading the hand may end and still count as there")
    args = parser.parse_args()
    if args.output == RESULTS / "hand_heading_reach.json":
        suffix = "" if args.hand == "right" else f"_{args.hand}_hand"
        suffix += "" if args.heading_weight == 1.0 else f"_weight{args.heading_weight:g}"
        args.output = RESULTS / f"hand_heading_reach_{args.robot}{suffix}.json"
    env = gymnasium.make("hoap_actions/Imitate-v0", robot=args.robot, control_mode="ee_delta")
    obs, _ = env.reset(seed=0)
    state = env.get_wrapper_attr("parse_observation")(obs)
    robot = env.get_wrapper_attr("robot_description")
    env.close()
    ik = WholeBodyIK(robot.joint_names, rest_posture(robot), fixed_legs=robot.fixed_legs, hand=args.hand,
                     heading_weight=args.heading_weight)
    tolerance_mm = 1e3 * args.tolerance
    rows, ranges = [], []
    for name, z in HEIGHTS.items():
        for x in XS:
            for y in YS:
                point = np.array([x, y, z])
                ik.reset(state["joint_positions"], state["base_position"], state["base_quaternion"])
                free = ik.probe(point)
                chosen = heading(free.rotation)
                asked = []
                for turn in args.turns:
                    got = ik.probe(point, heading=np.radians(chosen + turn))
                    asked.append({"asked_deg": turn, "reached_deg": round(heading(got.rotation) - chosen, 2),
                                  "tilt_deg": round(tilt(got.rotation), 2), "hand_error_mm": round(1e3 * got.error, 2)})
                rows.append({"height": name, "point_m": point.tolist(), "ik_heading_deg": round(chosen, 2),
                             "ik_tilt_deg": round(tilt(free.rotation), 2),
                             "ik_hand_error_mm": round(1e3 * free.error, 2), "turns": asked})
                ranges.append(reach(asked, 1e3 * free.error + tolerance_mm))
                print(f"{name} ({x:+.2f}, {y:+.2f}): IK heading {chosen:+.1f} deg; turns reached, the hand within "
                      f"{tolerance_mm:.0f} mm of where it was: {ranges[-1][0]:+.1f} .. {ranges[-1][1]:+.1f} deg")
    summary = {"largest_right_turn_deg": min(r[0] for r in ranges), "largest_left_turn_deg": max(r[1] for r in ranges),
               "median_range_deg": float(np.median([r[1] - r[0] for r in ranges])), "per_point_range_deg": ranges}
    write_json(args.output, {"robot": args.robot, "hand": args.hand, "heading_weight": args.heading_weight,
                             "turns_asked_deg": args.turns,
                             "tolerance_m": args.tolerance, "points": rows, "summary": summary,
                             "environment": numeric_environment(None)})
    print(f"over {len(rows)} points: turns reached, the hand within {tolerance_mm:.0f} mm of where it was, "
          f"{summary['largest_right_turn_deg']:+.1f} .. {summary['largest_left_turn_deg']:+.1f} deg; median range "
          f"{summary['median_range_deg']:.1f} deg")


def tilt(rotation: np.ndarray) -> float:
    """The palm's tilt from level (deg): the angle of the tcp's z axis from the vertical."""
    return float(np.degrees(np.arccos(np.clip(rotation[2, 2], -1.0, 1.0))))


def reach(asked: list[dict], tolerance_mm: float) -> list[float]:
    """The largest turns (deg) right and left reached with the hand within ``tolerance_mm`` of its point
    (0 when none: the IK's own heading)."""
    there = [a["reached_deg"] for a in asked if a["hand_error_mm"] <= tolerance_mm]
    return [min([0.0, *there]), max([0.0, *there])]


if __name__ == "__main__":
    main()
