"""A scripted grasp-and-insert expert for ``hoap_actions/PegInsert-v0`` with ``control_mode="ee_delta"``.

It reads the true peg and hole positions from the observation vector (layout documented in
:class:`~hoap_actions.envs.tasks.peg_insert.PegInsertTask`) and runs the paper's approach / move /
remove sequence (Fig. 9) as tcp waypoints, steering the desired hand position with ee_delta actions
along straight lines.

The hand is a palm plate and a thumb closing towards it, and the forearm stays about horizontal
(the IK keeps the peg axis, the tcp's z, vertical), so palm, open thumb and forearm sweep a wide
footprint behind the tcp. At reset the expert plans with the controller's whole-body IK (pure
queries, :meth:`~hoap_actions.controllers.wholebody_ik.WholeBodyIK.probe`): where along the palm the
peg will sit so that the footprint keeps clear of the other pegs and of the board, and the highest
reachable heights for the approach and the carry (this short-armed robot cannot lift its hand
high close to its right shoulder). It comes down with the thumb half open and the peg a few
millimetres off the palm, slides until the palm just touches it, squeezes (a friction grasp),
lifts, carries it (around the other pegs when it cannot pass over them), lines the peg's bottom up
with the hole from measured positions, lowers it 8 mm in and lets go: the peg drops to the bottom.

When the expert gives up it says why in :attr:`ScriptedExpert.failure`: ``"unreachable layout"``
(the IK cannot bring the hand to the peg or the hole, found while planning or while moving),
``"grasp slipped"`` (the peg does not follow the hand), ``"peg knocked over"`` (the hand or arm
toppled the target peg before grasping it) or ``"approach blocked"`` (every grasp shift came down on
something, usually the forearm on a peg right behind the target). The episode loop
adds ``"success"``, ``"fell"`` and ``"timeout"``. The hand's heading is read from the robot (it is
not in the observation).
"""

from __future__ import annotations

import enum
from typing import Any

import gymnasium
import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.envs import scene as scene_module
from hoap_actions.envs.controls import HAND_BOX_HIGH, HAND_BOX_LOW, MAX_HAND_STEP, EEDeltaController
from hoap_actions.envs.tasks.peg_insert import PegInsertTask
from hoap_actions.errors import InvalidInputError

__all__ = ["ScriptedExpert", "footprint_clearance", "thumb_outline"]

# ---------------------------------------------------------------------------- heights (tcp z, m)
Z_APPROACH = (0.085, 0.08, 0.075, 0.07)  # tried highest first; palm 2 cm below the tcp, pegs 5 cm tall
Z_GRASP_LOW = 0.038  # palm from 1.8 cm: around the peg's upper 3 cm; low, so the hole is within reach
Z_GRASP_HIGH = 0.047  # palm from 2.7 cm: clears the board's top (2.5 cm) when it lies under the palm
BOARD_CLEARANCE = 0.005  # m, footprint-to-board gap below which the high grasp is used
Z_CARRY = (0.1, 0.095, 0.09, 0.085, 0.08, 0.075)  # tried highest first
PEG_CLEARANCE_Z = 0.005  # m, a carried peg's bottom must pass this far over another peg's top
BOARD_CLEARANCE_Z = 0.01  # m, a carried peg's bottom over the board's top on the way to the hole
VIA_FRACTION = 0.4  # where on the way a carry that starts low rises
CARRY_CLEARANCE = 0.03  # m, horizontal distance kept from other pegs when the carried peg cannot pass over
REACH_PROBE_TOLERANCE = 0.0015  # m, IK hand error accepted at a planned waypoint
# ---------------------------------------------------------------------------- grasp
PRE_CLOSURE = 0.4  # gripper closure while coming down: thumb 21 deg open, a small footprint
GRASP_CLOSURE = 0.78  # 2 deg past contact (0.75): PyBullet squeezes in proportion; more pushes the peg out
PALM_CLEARANCE = 0.004  # m, peg centre off the palm line (towards the thumb) while coming down
PALM_GAP = 0.0005  # m, gap left between palm and peg before the thumb closes
GRASP_SHIFTS = (0.0, -0.006, 0.006)  # m, peg along the palm (tcp x); further out the grip is poor
CLEARANCE_GOAL = 0.006  # m, footprint-to-peg gap beyond which a grasp shift is good enough
# ---------------------------------------------------------------------------- insertion
ALIGN_HEIGHT = 0.003  # m, peg bottom over the board surface while it is lined up with the hole
ALIGN_TOLERANCE = 0.0007  # m, lateral peg-bottom-to-hole error accepted before going down
MAX_CORRECTIONS = 4  # measure-and-correct rounds over the hole before going down regardless
INSERT_DEPTH = 0.008  # m, how far the peg's bottom enters the hole before the hand lets go
# ---------------------------------------------------------------------------- pacing and checks
REACH_TOLERANCE = 0.002  # m, tcp-to-waypoint distance at which a move counts as done
SETTLE_SPEED = 0.02  # m/s, tcp speed under which the hand counts as settled
CLOSE_STEPS = 9  # steps (0.3 s) for the thumb to close on the peg
OPEN_STEPS = 8  # steps for the thumb to open and the peg to drop
MOVE_STEPS = 90  # steps (3 s) a move may take before the expert moves on regardless
BLOCKED_HEIGHT = 0.008  # m, tcp this far above its reference while coming down: something is under the hand
MIN_LIFT = 0.02  # m, how far the peg must have risen with the hand after the lift
SLIP_DISTANCE = 0.01  # m, drift of the peg relative to the hand that counts as a slipped grasp
KNOCKED_OVER = np.radians(30.0)  # tilt of the target peg before the grasp at which the expert gives up

# ---------------------------------------------------------------------------- hand footprint
# Outlines in the tcp frame (u along the forearm, v towards the palm; m), measured on hoap3.urdf.
PALM = np.array([[-0.051, 0.0075], [0.024, 0.0075], [0.024, 0.0155], [-0.051, 0.0155]])
FOREARM = np.array([[-0.19, -0.018], [-0.046, -0.018], [-0.046, 0.018], [-0.19, 0.018]])  # wrist to elbow
THUMB_CLOSED = np.array([[-0.041, -0.0155], [0.024, -0.0155], [0.024, -0.0075], [-0.041, -0.0075]])
THUMB_PIVOT = np.array([-0.038, -0.012])
THUMB_CONTACT_CLOSURE = 0.75  # closure at which the thumb lies parallel to the palm (on a 15 mm peg)
THUMB_RANGE = np.radians(60.0)  # rad of thumb rotation from open (0) to closed (1)


def thumb_outline(closure: float) -> np.ndarray:
    """The thumb plate's outline (4, 2) in the tcp frame at a gripper closure in [0, 1]."""
    angle = -(THUMB_CONTACT_CLOSURE - closure) * THUMB_RANGE  # outwards, about the hand's z
    c, s = np.cos(angle), np.sin(angle)
    return THUMB_PIVOT + (THUMB_CLOSED - THUMB_PIVOT) @ np.array([[c, s], [-s, c]])


def _distance_to_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance (m) from each point (N, 2) to a convex polygon (K, 2); 0 inside."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip((ap * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    distance = np.linalg.norm(ap - t[..., None] * ab, axis=-1).min(axis=1)
    cross = ab[:, 0] * ap[..., 1] - ab[:, 1] * ap[..., 0]
    inside = np.all(cross >= 0.0, axis=1) | np.all(cross <= 0.0, axis=1)
    return np.where(inside, 0.0, distance)


def footprint_clearance(points_uv: np.ndarray, radius: float, closure: float = PRE_CLOSURE) -> float:
    """Least gap (m) between the hand's footprint and discs of ``radius`` at ``points_uv`` (N, 2),
    given in the tcp frame; ``inf`` for no points."""
    if len(points_uv) == 0:
        return np.inf
    parts = (PALM, FOREARM, thumb_outline(closure))
    return float(np.min([_distance_to_polygon(points_uv, part) for part in parts]) - radius)


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) from points (N, 2) to the segment a-b."""
    ab = b - a
    t = np.clip(((points - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


class Phase(enum.Enum):
    RISE = enum.auto()
    APPROACH = enum.auto()
    DESCEND = enum.auto()
    BACK_OFF = enum.auto()
    TOUCH = enum.auto()
    CLOSE = enum.auto()
    LIFT = enum.auto()
    CARRY = enum.auto()
    ALIGN = enum.auto()
    INSERT = enum.auto()
    RELEASE = enum.auto()
    RETRACT = enum.auto()
    DONE = enum.auto()


class ScriptedExpert:
    """``obs -> action`` grasp-and-insert policy (the :class:`~hoap_actions.episodes.Policy` protocol).

    Args:
        env: a PegInsert env made with ``control_mode="ee_delta"`` (wrappers are looked through).
    """

    failure: str | None
    control_mode = "ee_delta"  # the env's control mode this policy acts through
    env_ids = ("hoap_actions/PegInsert-v0",)  # the envs whose task it performs

    def __init__(self, env: gymnasium.Env) -> None:
        base = env.unwrapped
        if not isinstance(getattr(base, "task", None), PegInsertTask):
            raise InvalidInputError(
                f"ScriptedExpert performs grasp-and-insert; it needs one of {list(self.env_ids)}, not {type(base).__name__}"
            )
        if not isinstance(getattr(base, "controller", None), EEDeltaController):
            raise InvalidInputError(
                f"ScriptedExpert needs control_mode='ee_delta'; this env uses {getattr(base, 'control_mode', None)!r}"
            )
        self.env = base
        self.ik = base.controller.hand.ik
        self.n_joints = len(base.robot.joint_names)
        self.n_pegs = base.scene.n_pegs
        self.failure = None
        self.phase = Phase.APPROACH

    # ------------------------------------------------------------------ observation
    def _parse(self, obs: dict[str, np.ndarray]) -> None:
        """Pull the tcp, the pegs, the target peg and hole and the peg's bottom out of the observation."""
        o = np.asarray(obs["observation"], dtype=float)
        n = self.n_joints
        self.tcp = o[2 * n + 7 : 2 * n + 10]
        task = o[2 * n + 10 :]
        k = 7 * self.n_pegs
        poses = task[:k].reshape(self.n_pegs, 7)
        pegs = poses[:, :3]
        self.holes = task[k : k + 3 * scene_module.N_HOLES].reshape(scene_module.N_HOLES, 3)
        one_hot = task[k + 3 * scene_module.N_HOLES :]
        target = int(np.argmax(one_hot[: self.n_pegs]))
        self.peg = pegs[target]
        qx, qy = poses[target, 3:5]
        self.peg_upright = 1.0 - 2.0 * (qx * qx + qy * qy) > np.cos(KNOCKED_OVER)  # axis z component
        self.others = np.delete(pegs, target, axis=0)
        self.hole = self.holes[int(np.argmax(one_hot[self.n_pegs :]))]
        self.peg_bottom = np.asarray(obs["achieved_goal"], dtype=float)

    def _board_outline(self, spacing: float = 0.005) -> np.ndarray:
        """Points (N, 2) every ``spacing`` m along the board's outline, from the hole centres."""
        centre = self.holes[:, :2].mean(axis=0)
        along = self.holes[-1, :2] - self.holes[0, :2]
        along /= np.linalg.norm(along)
        across = np.array([-along[1], along[0]])
        half = np.array(scene_module.BOARD_SIZE[:2]) / 2  # (across, along) in the board's frame
        corners = [centre + sx * half[0] * across + sy * half[1] * along for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
        points = []
        for a, b in zip(corners, corners[1:] + corners[:1]):
            n = max(2, int(np.linalg.norm(b - a) / spacing))
            points += [a + (b - a) * t for t in np.linspace(0.0, 1.0, n, endpoint=False)]
        return np.array(points)

    @staticmethod
    def _axes(rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal unit vectors along the forearm (tcp x) and from thumb to palm (tcp y)."""
        x = rotation[:2, 0] / np.linalg.norm(rotation[:2, 0])
        return x, np.array([-x[1], x[0]])

    def _hand_axes(self) -> tuple[np.ndarray, np.ndarray]:
        return self._axes(Rotation.from_quat(self.env.robot.frame_pose("r_tcp")[1]).as_matrix())

    def _grasp_xy(self, shift: float, clearance: float, axes: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Tcp xy that puts the peg ``shift`` along the palm (tcp x) and ``clearance`` off it, thumb-wards."""
        x, y = axes if axes is not None else self._hand_axes()
        return self.peg[:2] - shift * x + clearance * y

    # ------------------------------------------------------------------ planning
    def _reachable(self, xy: np.ndarray, heights: tuple[float, ...]) -> float | None:
        """The first of ``heights`` at which the IK brings the hand over ``xy`` (None if none)."""
        for z in heights:
            if self.ik.probe([*xy, z]).error < REACH_PROBE_TOLERANCE:
                return z
        return None

    def _plan(self) -> None:
        """Grasp shift and height, approach and carry heights, the carry's way: from IK queries."""
        probe = self.ik.probe([*self.peg[:2], Z_GRASP_LOW])
        if probe.error > REACH_PROBE_TOLERANCE:
            self.failure = "unreachable layout"
            return
        axes = self._axes(probe.rotation)
        x, y = axes
        board = self._board_outline()
        best = None
        for shift in GRASP_SHIFTS:
            tcp = self._grasp_xy(shift, PALM_CLEARANCE, axes)
            rel_pegs, rel_board = self.others[:, :2] - tcp, board - tcp
            gap = footprint_clearance(np.c_[rel_pegs @ x, rel_pegs @ y], scene_module.PEG_RADIUS)
            board_gap = footprint_clearance(np.c_[rel_board @ x, rel_board @ y], 0.0)
            if best is None or min(gap, CLEARANCE_GOAL) > min(best[1], CLEARANCE_GOAL):
                best = (shift, gap, board_gap)
            if gap >= CLEARANCE_GOAL:
                break
        self.shift, _, board_gap = best
        self.grasp_z = Z_GRASP_HIGH if board_gap < BOARD_CLEARANCE else Z_GRASP_LOW
        grasp_xy = self._grasp_xy(self.shift, PALM_CLEARANCE, axes)
        self.approach_z = self._reachable(grasp_xy, Z_APPROACH)
        hold = self.grasp_z  # tcp over the peg's bottom once it is held
        self.align_z = scene_module.BOARD_SIZE[2] + ALIGN_HEIGHT + hold
        hole_xy = self.hole[:2] + (grasp_xy - self.peg[:2])
        if self.approach_z is None or self._reachable(hole_xy, (self.align_z,)) is None:
            self.failure = "unreachable layout"
            return
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

    def _way_around(self, start: np.ndarray, end: np.ndarray) -> list[np.ndarray]:
        """The straight way if it keeps clear of the other pegs, else one via point beside it."""
        others = self.others[:, :2] + (start - self.peg[:2])  # where the tcp would be over them
        if len(others) == 0 or _segment_distance(others, start, end).min() >= CARRY_CLEARANCE:
            return [end]
        direction = end - start
        normal = np.array([-direction[1], direction[0]]) / max(np.linalg.norm(direction), 1e-9)
        middle = (start + end) / 2
        for offset in np.arange(0.01, 0.081, 0.01):
            for sign in (1.0, -1.0):
                via = middle + sign * offset * normal
                if min(_segment_distance(others, start, via).min(), _segment_distance(others, via, end).min()) >= CARRY_CLEARANCE:
                    return [via, end]
        return [end]

    # ------------------------------------------------------------------ policy
    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        self._parse(obs)
        self.failure = None
        self.desired = self.tcp.copy()
        self.previous_tcp = self.tcp.copy()
        self.grip = PRE_CLOSURE
        self.tried_shifts: list[float] = []
        self.hold_offset = np.zeros(3)
        self.corrections = 0
        self.blocked_steps = 0
        self._plan()
        if self.failure is None:
            self.tried_shifts.append(self.shift)
        # straight up first: the forearm starts low over the table, across the pegs' tops
        self.target = np.array([*self.tcp[:2], max(self.tcp[2], self.approach_z or self.tcp[2])])
        self._enter(Phase.RISE)

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        self._parse(obs)
        speed = np.linalg.norm(self.tcp - self.previous_tcp) * self.env.metadata["render_fps"]
        self.previous_tcp = self.tcp.copy()
        self.steps_in_phase += 1
        self._update(speed)
        step = (np.clip(self.target, HAND_BOX_LOW, HAND_BOX_HIGH) - self.desired) / MAX_HAND_STEP
        step /= max(1.0, float(np.max(np.abs(step))))  # uniform scaling: straight moves
        self.desired = np.clip(self.desired + MAX_HAND_STEP * step, HAND_BOX_LOW, HAND_BOX_HIGH)
        return np.array([*step, self.grip], dtype=np.float32)

    # ------------------------------------------------------------------ phases
    def _arrived(self, speed: float, tolerance: float = REACH_TOLERANCE) -> bool:
        """The desired point is at the waypoint and the measured hand has settled near it (or time is up)."""
        at_target = np.allclose(self.desired, np.clip(self.target, HAND_BOX_LOW, HAND_BOX_HIGH))
        close = np.linalg.norm(self.tcp - self.target) < tolerance and speed < SETTLE_SPEED
        return bool(at_target and (close or self.steps_in_phase > MOVE_STEPS))

    def _enter(self, phase: Phase) -> None:
        self.phase, self.steps_in_phase = phase, 0

    def _update(self, speed: float) -> None:
        """Advance the state machine on this step's observation; sets ``target`` and ``grip``."""
        if self.failure is not None:
            return
        if self.env.controller.hand.unreachable and self.phase in (Phase.APPROACH, Phase.DESCEND, Phase.CARRY, Phase.ALIGN):
            self.failure = "unreachable layout"
        if not self.peg_upright and self.phase in (Phase.RISE, Phase.APPROACH, Phase.DESCEND, Phase.BACK_OFF, Phase.TOUCH):
            self.failure = "peg knocked over"
        phase = self.phase
        if phase == Phase.RISE and self._arrived(speed, tolerance=0.005):
            phase = Phase.APPROACH
            self._enter(phase)
        if phase == Phase.APPROACH:
            self.target = np.array([*self._grasp_xy(self.shift, PALM_CLEARANCE), self.approach_z])
            if self._arrived(speed):
                self._enter(Phase.DESCEND)
        elif phase == Phase.DESCEND:
            self.target = np.array([*self._grasp_xy(self.shift, PALM_CLEARANCE), self.grasp_z])
            reference = self.env.controller.hand.reference
            self.blocked_steps = self.blocked_steps + 1 if self.tcp[2] - reference[2] > BLOCKED_HEIGHT else 0
            if self.blocked_steps >= 3:
                self._enter(Phase.BACK_OFF)
            elif self._arrived(speed, tolerance=0.001):
                self._enter(Phase.TOUCH)
        elif phase == Phase.BACK_OFF:  # something under the hand: go up, try another shift
            self.target = np.array([*self.target[:2], self.approach_z])
            if self._arrived(speed, tolerance=0.005):
                untried = [s for s in GRASP_SHIFTS if s not in self.tried_shifts]
                if not untried:
                    self.failure = "approach blocked"
                    return
                self.shift = untried[0]
                self.tried_shifts.append(self.shift)
                self.blocked_steps = 0
                self._enter(Phase.APPROACH)
        elif phase == Phase.TOUCH:
            self.target = np.array([*self._grasp_xy(self.shift, PALM_GAP), self.grasp_z])
            if self._arrived(speed, tolerance=0.001):
                self.grip = GRASP_CLOSURE
                self._enter(Phase.CLOSE)
        elif phase == Phase.CLOSE:
            if self.steps_in_phase >= CLOSE_STEPS:
                self.target = np.array([*self.target[:2], self.lift_z])
                self._enter(Phase.LIFT)
        elif phase == Phase.LIFT:
            if self._arrived(speed, tolerance=0.005):
                if self.peg_bottom[2] < MIN_LIFT:
                    self.failure = "grasp slipped"
                self.hold_offset = self.tcp - self.peg_bottom
                shift = np.r_[self.hold_offset[:2] - (self.carry_way[-1][:2] - self.hole[:2]), 0.0]
                self.way = [p + shift for p in self.carry_way]
                self.target = self.way.pop(0)
                self._enter(Phase.CARRY)
        elif phase == Phase.CARRY:
            self._check_slip()
            if self._arrived(speed, tolerance=0.003):
                if self.way:
                    self.target = self.way.pop(0)
                    self.steps_in_phase = 0
                else:
                    xy = self.hole[:2] + self.tcp[:2] - self.peg_bottom[:2]
                    self.target = np.array([*xy, self.align_z])
                    self._enter(Phase.ALIGN)
        elif phase == Phase.ALIGN:
            self._check_slip()
            if self._arrived(speed, tolerance=0.003):
                error = self.hole[:2] - self.peg_bottom[:2]
                if np.linalg.norm(error) < ALIGN_TOLERANCE or self.corrections >= MAX_CORRECTIONS:
                    depth = scene_module.BOARD_SIZE[2] - INSERT_DEPTH
                    self.target = np.array([*self.target[:2], depth + self.tcp[2] - self.peg_bottom[2]])
                    self._enter(Phase.INSERT)
                else:
                    self.target[:2] += error
                    self.corrections += 1
                    self.steps_in_phase = 0
        elif phase == Phase.INSERT:
            if self._arrived(speed, tolerance=0.002):
                self.grip = 0.0
                self._enter(Phase.RELEASE)
        elif phase == Phase.RELEASE:
            if self.steps_in_phase >= OPEN_STEPS:
                self.target = np.array([*self.target[:2], self.align_z + 0.01])
                self._enter(Phase.RETRACT)
        elif phase == Phase.RETRACT and self._arrived(speed, tolerance=0.01):
            self._enter(Phase.DONE)

    def _check_slip(self) -> None:
        if np.linalg.norm(self.tcp - self.peg_bottom - self.hold_offset) > SLIP_DISTANCE:
            self.failure = "grasp slipped"
