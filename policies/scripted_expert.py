"""A scripted grasp-and-insert expert for ``hoap_actions/PegInsert-v0`` with ``control_mode="ee_delta"``.

It reads the true peg and hole positions from the observation (the task's fields, through the
env's ``parse_observation``) and gives the shared execution layer
(:class:`~hoap_actions.policies.execution.GraspAndInsert`) straight-line hand paths: straight up
out of the rest posture, over the grasp point, down; up with the peg, over (or around) the other
pegs to the hole, lined up from the measured peg, down 8 mm, let go.

This short-armed robot cannot lift its hand high close to its right shoulder, so the heights come
from the policy's own whole-body IK (pure queries,
:meth:`~hoap_actions.controllers.wholebody_ik.WholeBodyIK.probe`): the highest reachable heights for
the approach and the carry. Because it measures the peg every step, the execution layer's checks
all run: a knocked-over target peg, a slipped grasp, and the measure-and-correct alignment over the
hole.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hoap_actions.envs import scene as scene_module
from hoap_actions.envs import world
from hoap_actions.policies.execution import (
    ALIGN_HEIGHT,
    KNOCKED_OVER,
    GraspAndInsert,
    Leg,
    WorldEstimate,
    straight_leg,
)
from hoap_actions.policies.grasp import REACH_PROBE_TOLERANCE, footprint_clearance, thumb_outline

__all__ = ["ScriptedExpert", "footprint_clearance", "thumb_outline"]

Z_APPROACH = (0.085, 0.08, 0.075, 0.07)  # tcp z (m), tried highest first; palm 2 cm below the tcp, pegs 5 cm tall
Z_CARRY = (0.1, 0.095, 0.09, 0.085, 0.08, 0.075)  # tcp z (m), tried highest first
PEG_CLEARANCE_Z = 0.005  # m, a carried peg's bottom must pass this far over another peg's top
BOARD_CLEARANCE_Z = 0.01  # m, a carried peg's bottom over the board's top on the way to the hole
VIA_FRACTION = 0.4  # where on the way a carry that starts low rises
CARRY_CLEARANCE = 0.03  # m, horizontal distance kept from other pegs when the carried peg cannot pass over


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) from points (N, 2) to the segment a-b."""
    ab = b - a
    t = np.clip(((points - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


class ScriptedExpert(GraspAndInsert):
    """``obs -> action`` grasp-and-insert from the true poses, with straight hand paths (module docstring).

    Parameters
    ----------
    env
        a PegInsert env made with ``control_mode="ee_delta"`` (wrappers are fine).
    """

    # ------------------------------------------------------------------ the world, from the observation
    def locate(self, obs: dict[str, np.ndarray], fields: dict[str, Any]) -> WorldEstimate:
        pegs = fields["peg_positions"]
        target = fields["target_peg"]
        return WorldEstimate(peg=pegs[target], others=np.delete(pegs, target, axis=0),
                             holes=fields["hole_positions"], hole=fields["hole_positions"][fields["target_hole"]])

    def measure_peg(self, fields: dict[str, Any]) -> tuple[np.ndarray, bool]:
        qx, qy = fields["peg_quaternions"][fields["target_peg"], :2]
        upright = 1.0 - 2.0 * (qx * qx + qy * qy) > np.cos(KNOCKED_OVER)  # the peg axis's z component
        return fields["achieved_goal"], bool(upright)

    # ------------------------------------------------------------------ heights, from IK queries
    def _reachable(self, xy: np.ndarray, heights: tuple[float, ...]) -> float | None:
        """The first of ``heights`` at which the IK brings the hand over ``xy`` (None if none)."""
        for z in heights:
            if self.ik.probe([*xy, z]).error < REACH_PROBE_TOLERANCE:
                return z
        return None

    def prepare(self) -> str | None:
        """Approach and carry heights and the carry's way around the other pegs."""
        grasp_xy = self.plan.tcp(self.world.peg)[:2]
        self.approach_z = self._reachable(grasp_xy, Z_APPROACH)
        hold = self.plan.z  # tcp over the peg's bottom once it is held
        self.align_z = scene_module.BOARD_SIZE[2] + ALIGN_HEIGHT + hold
        hole_xy = self.world.hole[:2] + (grasp_xy - self.world.peg[:2])
        if self.approach_z is None or self._reachable(hole_xy, (self.align_z,)) is None:
            return "unreachable layout"
        heights = tuple(z for z in Z_CARRY if z > self.align_z) + (self.align_z,)
        self.lift_z = self._reachable(grasp_xy, heights) or self.align_z
        hole_z = self._reachable(hole_xy, heights) or self.align_z
        way = [np.array([*hole_xy, hole_z])]
        if self.lift_z - hold < scene_module.BOARD_SIZE[2] + BOARD_CLEARANCE_Z:  # rise on the way, clear of the board
            via = grasp_xy + VIA_FRACTION * (hole_xy - grasp_xy)
            way.insert(0, np.array([*via, self._reachable(via, heights) or self.align_z]))
        if min(p[2] for p in way) - hold < scene_module.PEG_LENGTH + PEG_CLEARANCE_Z:  # cannot pass over the pegs
            xy = self._way_around(grasp_xy, hole_xy)
            if len(xy) > 1:
                way = [np.array([*xy[0], min(p[2] for p in way)]), way[-1]]
        self.carry_way = way
        return None

    def _way_around(self, start: np.ndarray, end: np.ndarray) -> list[np.ndarray]:
        """The straight way if it keeps clear of the other pegs, else one via point beside it."""
        others = self.world.others[:, :2] + (start - self.world.peg[:2])  # where the tcp would be over them
        if len(others) == 0 or _segment_distance(others, start, end).min() >= CARRY_CLEARANCE:
            return [end]
        direction = end - start
        normal = np.array([-direction[1], direction[0]]) / max(np.linalg.norm(direction), 1e-9)
        middle = (start + end) / 2
        for offset in np.arange(0.01, 0.081, 0.01):
            for sign in (1.0, -1.0):
                via = middle + sign * offset * normal
                if min(_segment_distance(others, start, via).min(),
                       _segment_distance(others, via, end).min()) >= CARRY_CLEARANCE:
                    return [via, end]
        return [end]

    # ------------------------------------------------------------------ straight paths
    def approach_legs(self, start: np.ndarray, grasp: np.ndarray) -> list[Leg]:
        """Up to the approach height (forwards over the table's edge when the hand starts in front of
        it, where it cannot rise straight up), over the grasp point, down to it."""
        rise = np.array([max(start[0], world.WORK_AREA_LOW[0]), start[1], max(start[2], self.approach_z)])
        return [straight_leg(rise, 0.005), straight_leg([*grasp[:2], self.approach_z]), straight_leg(grasp, 0.001)]

    def back_off_legs(self, start: np.ndarray) -> list[Leg]:
        return [straight_leg([*start[:2], self.approach_z], 0.005)]

    def lift_legs(self, grasp: np.ndarray) -> list[Leg]:
        return [straight_leg([*grasp[:2], self.lift_z], 0.005)]

    def move_bottom_target(self) -> np.ndarray:
        """The peg's bottom ``ALIGN_HEIGHT`` over the board, over the hole: lined up there, then in."""
        return np.array([*self.world.hole[:2], scene_module.BOARD_SIZE[2] + ALIGN_HEIGHT])

    def move_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        shift = np.r_[end[:2] - self.carry_way[-1][:2], 0.0]  # the way was planned for the planned grip
        return [straight_leg(p + shift, 0.003) for p in self.carry_way] + [straight_leg(end, 0.003)]

    def insert_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        return [straight_leg(end, 0.002)]

    def remove_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        return [straight_leg([*start[:2], self.align_z + 0.01], 0.01)]


