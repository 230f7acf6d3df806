"""Whole-body inverse kinematics (placo): standing on both feet, reaching with the right hand.

One :meth:`WholeBodyIK.solve` is one QP step (~60 us), meant to run once per 240 Hz physics tick
on a target that moves under a millimetre per tick (see ``hand_control.py``). Tasks and constraints:

- feet: hard frame tasks, fixed where the soles stood at :meth:`WholeBodyIK.reset`;
- centre of mass: hard constraint keeping its divergent component (CoM + velocity / omega) inside
  the support polygon (the soles' convex hull, clockwise, as placo wants it) shrunk by 3 cm, plus a
  soft xy task (1e2) towards the polygon's centre;
- hand (``r_tcp``): soft position task (1e4, seeing at most 2 cm of error per solve) and a weak
  (1) tilt task keeping the tcp's z axis, the axis of a held peg, vertical: where a level forearm
  cannot reach, the hand tilts a few degrees rather than misses;
- pelvis: soft tasks holding it level (1e2) and over its reset position in x and y (1e3); it may
  rise and sink, which is how the legs lower the shoulders;
- posture: weak (1e-3) joint task towards a rest posture; the idle left arm held firmly (1);
- leg damping: a cost (1 per rad^2) on each step of the leg joints. Without it the QP has almost no
  curvature along the legs' squat direction once the knees near full extension, and its
  Gauss-Newton step overshoots into a period-2 cycle: on a fixed target the knees alternated at the
  +-5 rad/s limit every tick (0.02 rad at 120 Hz), in 864 of the 4800 ticks of a random ee_delta run;
- joint position limits (the knees and waist narrower than the URDF's, see
  :data:`IK_JOINT_LIMITS`) and velocity limits: 5 rad/s for the arms (the URDF's), but
  :data:`BODY_SPEED` for the legs and the waist (see there; :meth:`WholeBodyIK.set_body_speed`).

A robot with welded legs and a fixed pelvis (``fixed_legs=True``, the env's ``robot="fixed_legs"``)
keeps only the hand, tilt, posture and held-arm tasks and the limits: the legs and the floating base
are masked out of the QP, and the feet, centre-of-mass and pelvis tasks, which exist to keep a
standing robot on its feet, are not in the problem.

At reset the posture, CoM and tilt targets start at the measured state and move to their goals at
bounded rates, so a reset never swings the body at full joint speed.

Base synchronisation: placo's floating base is set from PyBullet's pelvis pose once per episode (in
:meth:`reset`), then moves only by the solver, pinned by the hard feet tasks to the soles' world
poses. While the soles do not slip, that base equals PyBullet's up to servo tracking error; copying
PyBullet's base every tick would feed that error back into the command and fight the feet tasks.

Failures never raise: a QP error or a non-finite solution restores the last good posture and is
reported as :attr:`IKStatus.SOLVER_FAILED`; a hand left further than ``tolerance`` from its target
is :attr:`IKStatus.TARGET_UNREACHED`.
"""

from __future__ import annotations

import enum
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import placo
from numpy.typing import ArrayLike
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError
from hoap_actions.urdf import LEG_JOINTS, urdf_path

logger = logging.getLogger(__name__)

__all__ = ["IKResult", "IKStatus", "Probe", "WholeBodyIK", "polygon_distance"]

SOLE_HALF = (0.054, 0.0365)  # m, half length and width of the 108 x 73 mm HOAP-3 sole
FEET = ("r_sole", "l_sole")
HANDS = {"right": "r_tcp", "left": "l_tcp"}
"""The hand frame (tcp) of each side."""
PELVIS = "pelvis"
FROZEN = ("head_pan", "head_tilt", "head_roll", "r_gripper", "l_gripper")
"""Joints the IK leaves where they are: they move no task frame (the grippers are commanded apart)."""
MAX_HAND_PULL = 0.02  # m, largest hand error the QP sees in one solve
MAX_HEADING_PULL = 0.05  # rad, largest heading error the QP sees in one solve (a heading is asked)
COM_HEIGHT = 0.3  # m, the standing robot's CoM over its soles (for the DCM's natural frequency)
IK_JOINT_LIMITS = {"r_knee": (-0.017, 1.1), "l_knee": (-0.017, 1.1), "waist_pitch": (-0.017, 0.5)}
"""IK-only ranges (rad). Knees bent at most 63 deg (a squat of about 3 cm): deeper, the IK sinks the
robot 10 cm to reach the far left, the left arm meets the table and the pelvis drops below the fall
threshold. Waist leaning at most 29 deg: further, the servos' 4.5 N m cannot hold the trunk and the
robot topples (reaching for a target 1 m away did)."""
ARM_JOINTS = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_yaw")
ARMS = {side: tuple(f"{side[0]}_{joint}" for joint in ARM_JOINTS) for side in HANDS}
"""Each arm's joints; the idle one is held (``held``): it follows the posture, not a counterweight."""
POSTURE_RATE = 0.5  # rad/s at which the posture target moves from the reset posture to the rest posture
COM_RATE = 0.02  # m/s at which the CoM target moves to the polygon's centre and the margin grows
TILT_RATE = 0.5  # rad/s at which the hand's tilt target goes from its reset tilt to level
BODY = (*LEG_JOINTS, "waist_pitch")
"""The joints that move the trunk: the legs and the waist."""
LEG_DAMPING = 1.0  # per rad^2 of a leg joint's step: damps the QP's knee cycle (a hand error costs 1e4 per m^2)
BODY_SPEED = 0.3  # rad/s, IK velocity limit of the legs and the waist
"""The legs and the waist carry the trunk (3.3 of the robot's 8.8 kg); moved fast, the reaction to
their accelerations rocks the feet on their 4 cm heels, and bang-bang ee_delta actions pumped that
rocking until the robot fell backwards (3 falls in 8000 steps at the URDF's 5 rad/s; none in 6000
steps at 0.3 rad/s with the leg damping, and the scripted expert still solves 19 of 20 layouts). The
arms keep 5 rad/s: they are light, and they follow the hand while the body catches up."""


class IKStatus(enum.IntEnum):
    """How a solve ended; an ``IntEnum`` so it can sit in an observation or ``info`` as a number."""

    OK = 0
    TARGET_UNREACHED = 1
    SOLVER_FAILED = 2


@dataclass(frozen=True)
class Probe:
    """A reachability query's outcome: the hand error left (m) and the hand's rotation (3, 3) there."""

    error: float
    rotation: np.ndarray


@dataclass(frozen=True)
class IKResult:
    """One solve: joint targets ``q`` (n,) in the caller's joint order (rad), the status, and the
    distance (m) from the IK model's hand to its target after the step."""

    q: np.ndarray
    status: IKStatus
    hand_error: float


class WholeBodyIK:
    """placo whole-body IK for the HOAP-3 model, in the joint order ``joint_names`` of the caller.

    Parameters
    ----------
    joint_names
        the caller's joint order (e.g. ``Robot.joint_names``); every name must be a
        revolute joint of the URDF.
    home_posture
        (n,) posture the regularisation pulls towards (rad).
    dt
        period of :meth:`solve` calls (s); with the URDF's velocity limits it bounds each step.
    urdf
        model file; defaults to the packaged ``hoap3.urdf``.
    hand_weight
        soft weight of the hand position task (per m^2 of error).
    axis_weight
        soft weight of the peg-axis-vertical task (per rad^2): low, so that where the
        arm cannot reach with a level forearm the hand tilts rather than misses.
    heading_weight
        soft weight of the hand's heading about the vertical (per rad^2), when a solve is given one
        (:meth:`solve`'s ``heading``): a task of its own, in the problem only while a heading is asked.
    posture_weight
        soft weight of the posture task (per rad^2).
    pelvis_weight
        soft weight keeping the pelvis level (per rad^2).
    pelvis_xy_weight
        soft weight holding the pelvis over its reset position (per m^2).
    com_weight
        soft weight of the CoM xy task towards the support polygon's centre (per m^2).
    com_margin
        how far inside the support polygon the CoM must stay (m).
    tolerance
        hand error (m) above which a solve reports ``TARGET_UNREACHED``.
    frozen
        joints the solver must not move (fewer free variables, a faster QP).
    held, held_weight
        joints kept near their posture by a stronger soft task (per rad^2); default: the other arm's.
    joint_limits
        ranges (rad) narrower than the URDF's for the IK only, e.g. the knees.
    leg_damping
        soft weight on each leg joint's step (per rad^2), against the QP's knee cycle.
    body_speed
        velocity limit (rad/s) of the legs and the waist in the IK (:attr:`body_speed`;
        :meth:`set_body_speed` changes it for a while). A bolted trunk keeps it too: at the
        URDF's 5 rad/s its swings shook grasps loose (4 slipped in 50 validation layouts).
    fixed_legs
        the robot's pelvis is fixed and its legs welded (they keep the angles given at
        :meth:`reset`); no balance tasks.
    hand
        the hand the position, tilt and heading tasks move: ``"right"`` (the envs' ee_delta hand) or
        ``"left"`` (:data:`HANDS`).
    """

    def __init__(
        self,
        joint_names: Sequence[str],
        home_posture: ArrayLike,
        dt: float = 1.0 / 240.0,
        urdf: str | Path | None = None,
        hand_weight: float = 1e4,
        axis_weight: float = 1.0,
        heading_weight: float = 1.0,
        posture_weight: float = 1e-3,
        pelvis_weight: float = 1e2,
        pelvis_xy_weight: float = 1e3,
        com_weight: float = 1e2,
        com_margin: float = 0.03,
        tolerance: float = 3e-3,
        frozen: Sequence[str] = FROZEN,
        held: Sequence[str] | None = None,
        held_weight: float = 1.0,
        joint_limits: Mapping[str, tuple[float, float]] = IK_JOINT_LIMITS,
        leg_damping: float = LEG_DAMPING,
        body_speed: float = BODY_SPEED,
        fixed_legs: bool = False,
        hand: str = "right",
    ) -> None:
        if hand not in HANDS:
            raise InvalidInputError(f"hand={hand!r} is not a hand; accepted: {sorted(HANDS)}")
        self.hand_frame = HANDS[hand]
        if held is None:
            held = ARMS["left" if hand == "right" else "right"]
        self.joint_names = tuple(joint_names)
        self.fixed_legs = bool(fixed_legs)
        home = np.asarray(home_posture, dtype=float)
        if home.shape != (len(self.joint_names),) or not np.all(np.isfinite(home)):
            raise InvalidInputError(
                f"home_posture must be finite with shape ({len(self.joint_names)},), one angle per joint; got "
                f"{home.shape}"
            )
        self.home_posture = home
        self.dt = float(dt)
        self.com_margin = float(com_margin)
        self.tolerance = float(tolerance)
        self.body_speed = float(body_speed)
        self.robot = placo.RobotWrapper(str(urdf or urdf_path("hoap3.urdf")), placo.Flags.ignore_collisions)
        known = set(self.robot.joint_names())
        missing = [n for n in self.joint_names if n not in known]
        if missing:
            raise InvalidInputError(f"joints {missing} are not in the IK model; its joints: {sorted(known)}")
        self._q_index = np.array([self.robot.get_joint_offset(n) for n in self.joint_names])
        for name, (low, high) in joint_limits.items():
            self.robot.set_joint_limits(name, float(low), float(high))

        solver = self.solver = placo.KinematicsSolver(self.robot)
        solver.dt = self.dt
        self.set_body_speed(body_speed)
        solver.enable_joint_limits(True)
        solver.enable_velocity_limits(True)
        for name in frozen:
            solver.mask_dof(name)
        if self.fixed_legs:  # nothing to balance: the legs and the pelvis leave the problem
            solver.mask_fbase(True)
            for name in LEG_JOINTS:
                solver.mask_dof(name)
        else:
            leg_damping_task = solver.add_regularization_task(0.0)  # per-joint weights replace the 0 default
            for name in LEG_JOINTS:
                leg_damping_task.set_joint_weight(name, float(leg_damping))
            self._feet = []
            for frame in FEET:
                task = solver.add_frame_task(frame, np.eye(4))
                task.configure(frame, "hard", 1.0, 1.0)
                self._feet.append(task)
            self._polygon = solver.add_com_polygon_constraint([np.zeros(2)] * 3, self.com_margin)
            self._polygon.configure("support_polygon", "hard", 1.0)
            # The divergent component of motion (CoM + CoM velocity / omega), not just the CoM, must stay
            # inside: this also bounds how fast the commanded CoM may head for the polygon's edge.
            self._polygon.dcm = True
            self._polygon.omega = float(np.sqrt(9.81 / COM_HEIGHT))
            # placo keeps every array it is given as a polygon: new arrays at each reset grew the process by
            # about 1 kB a reset, so the corners are written into arrays kept per corner count
            self._polygon_points: dict[int, list[np.ndarray]] = {}
            self._com = solver.add_com_task(np.zeros(3))
            self._com.mask.set_axises("xy")
            self._com.configure("com_xy", "soft", float(com_weight))
        self._hand = solver.add_position_task(self.hand_frame, np.zeros(3))
        self._hand.configure("hand", "soft", float(hand_weight))
        # Tilt only: the orientation target is re-levelled at the hand's current heading each solve
        # and the world-z error is masked, so the heading stays free. (placo's axis-align task
        # returns NaN when the axis is exactly aligned, as at the home posture.)
        self._tilt = solver.add_orientation_task(self.hand_frame, np.eye(3))
        self._tilt.mask.set_axises("xy", "task")
        self._tilt.configure("hand_tilt", "soft", float(axis_weight))
        self.heading_weight = float(heading_weight)
        self._heading_task = None
        if not self.fixed_legs:
            self._pelvis = solver.add_orientation_task(PELVIS, np.eye(3))
            self._pelvis.configure("pelvis_level", "soft", float(pelvis_weight))
            # The pelvis stays over its reset position: 2 cm behind the table edge, and moving it far to
            # reach (back, or sideways) swings the trunk enough to topple the robot (measured). It may
            # rise and sink: the legs lower and raise the shoulders.
            self._pelvis_xy = solver.add_position_task(PELVIS, np.zeros(3))
            self._pelvis_xy.mask.set_axises("xy")
            self._pelvis_xy.configure("pelvis_xy", "soft", float(pelvis_xy_weight))
        self._posture = solver.add_joints_task()
        self._posture.configure("posture", "soft", float(posture_weight))
        # Joints held firmly at their posture (the idle arm): left free, the IK swings them as
        # counterweights, into the table and the pegs.
        self._held = [self.joint_names.index(n) for n in held]
        self._held_task = solver.add_joints_task()
        self._held_task.configure("held", "soft", float(held_weight))
        self._good_q = self.robot.state.q.copy()
        self.polygon = np.zeros((0, 2))
        self._posture_target = home.copy()
        self._com_target = np.zeros(2)
        self._com_goal = np.zeros(2)
        self._margin = self.com_margin
        self._tilt_rotvec = np.zeros(3)
        self._tilt_rotation = np.eye(3)
        self._settled = True

    # ------------------------------------------------------------------ state
    def reset(self, q: ArrayLike, base_position: ArrayLike, base_quaternion: ArrayLike) -> None:
        """Take the robot's measured state: joints ``q`` (n,), pelvis position (3,) and quaternion
        (x, y, z, w); the feet tasks, support polygon and hand target start from it."""
        q = np.asarray(q, dtype=float)
        robot = self.robot
        state_q = robot.state.q.copy()
        state_q[self._q_index] = q
        robot.state.q = state_q
        robot.state.qd = np.zeros_like(robot.state.qd)
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(np.asarray(base_quaternion, dtype=float)).as_matrix()
        T[:3, 3] = np.asarray(base_position, dtype=float)
        robot.set_T_world_fbase(T)
        robot.update_kinematics()
        # Posture, CoM and margin start where the robot is and move to their goals at bounded rates
        # (see _settle): jumping to them at once would swing the body at full joint speed.
        self._posture_target = q.copy()
        T_hand = robot.get_T_world_frame(self.hand_frame)
        self._hand.target_world = T_hand[:3, 3].copy()
        if self.fixed_legs:
            self._com_target, self._com_goal, self._margin = np.zeros(2), np.zeros(2), self.com_margin
        else:
            self._reset_balance()
        self._tilt_rotvec = Rotation.from_matrix(_heading(T_hand).T @ T_hand[:3, :3]).as_rotvec()
        self._tilt_rotation = _rodrigues(self._tilt_rotvec)
        self._settled = False
        self._settle()
        self._good_q = robot.state.q.copy()

    def _reset_balance(self) -> None:
        """Feet tasks on the soles where they stand, their support polygon, the pelvis held as it is,
        and the CoM target and margin starting from the measured CoM."""
        robot = self.robot
        corners = []
        for frame, task in zip(FEET, self._feet):
            T_sole = robot.get_T_world_frame(frame)
            task.T_world_frame = T_sole
            for sx in (1.0, -1.0):
                for sy in (1.0, -1.0):
                    corners.append((T_sole @ np.array([sx * SOLE_HALF[0], sy * SOLE_HALF[1], 0.0, 1.0]))[:2])
        corners = np.array(corners)
        self.polygon = corners[ConvexHull(corners).vertices[::-1]]  # scipy gives counter-clockwise
        points = self._polygon_points.setdefault(len(self.polygon), [np.zeros(2) for _ in self.polygon])
        for point, corner in zip(points, self.polygon):
            point[:] = corner
        self._polygon.polygon = points
        T_pelvis = robot.get_T_world_frame(PELVIS)
        self._pelvis.R_world_frame = T_pelvis[:3, :3]
        self._pelvis_xy.target_world = T_pelvis[:3, 3]
        com = robot.com_world()[:2]
        self._com_target, self._com_goal = com.copy(), self.polygon.mean(axis=0)
        self._margin = float(np.clip(polygon_distance(com, self.polygon) - 0.002, 0.0, self.com_margin))

    def _send_balance_targets(self) -> None:
        if not self.fixed_legs:
            self._com.target_world = np.r_[self._com_target, 0.0]
            self._polygon.margin = self._margin

    def _settle(self) -> None:
        """Move the posture, CoM-target and margin one tick towards their goals (no-op once there)."""
        if self._settled:
            return
        dt = self.dt
        self._posture_target += np.clip(self.home_posture - self._posture_target, -POSTURE_RATE * dt, POSTURE_RATE * dt)
        self._com_target += np.clip(self._com_goal - self._com_target, -COM_RATE * dt, COM_RATE * dt)
        self._margin = min(self.com_margin, self._margin + COM_RATE * dt)
        angle = float(np.linalg.norm(self._tilt_rotvec))
        if angle > 0.0:
            self._tilt_rotvec *= max(0.0, angle - TILT_RATE * dt) / angle
            self._tilt_rotation = _rodrigues(self._tilt_rotvec)
        self._set_posture_targets()
        self._send_balance_targets()
        self._settled = bool(
            np.array_equal(self._posture_target, self.home_posture)
            and np.array_equal(self._com_target, self._com_goal)
            and self._margin == self.com_margin
            and angle == 0.0
        )

    def _set_posture_targets(self) -> None:
        target = self._posture_target.tolist()
        self._posture.set_joints(dict(zip(self.joint_names, target)))
        self._held_task.set_joints({self.joint_names[i]: target[i] for i in self._held})

    def set_body_speed(self, speed: float) -> None:
        """Limit the legs and the waist to ``speed`` (rad/s, > 0) from the next solve on; the arms keep theirs."""
        speed = float(speed)
        if not np.isfinite(speed) or speed <= 0.0:
            raise InvalidInputError(f"speed must be a finite joint speed > 0 (rad/s); got {speed}")
        for name in BODY:
            self.robot.set_velocity_limit(name, speed)

    @property
    def q(self) -> np.ndarray:
        """The IK model's current joint angles (n,) in the caller's order (rad)."""
        return self.robot.state.q[self._q_index]

    def hand_position(self) -> np.ndarray:
        """The IK model's hand (tcp) position (3,) in the world (m)."""
        return self.robot.get_T_world_frame(self.hand_frame)[:3, 3]

    def hand_heading(self) -> float:
        """The IK model's hand heading (rad) about the vertical: the forearm's direction seen from above."""
        return _yaw(self.robot.get_T_world_frame(self.hand_frame))

    def com(self) -> np.ndarray:
        """The IK model's centre of mass (3,) in the world (m)."""
        return self.robot.com_world()

    def hand_pose_at(self, q: ArrayLike, base_position: ArrayLike, base_quaternion: ArrayLike) -> np.ndarray:
        """Forward kinematics: the hand (tcp) frame (4, 4) in the world for joints ``q`` (n,) and the
        pelvis pose; the IK's own state is left as it was (a pure query)."""
        robot = self.robot
        saved_q, saved_base = robot.state.q.copy(), robot.get_T_world_fbase().copy()
        state_q = saved_q.copy()
        state_q[self._q_index] = np.asarray(q, dtype=float)
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(np.asarray(base_quaternion, dtype=float)).as_matrix()
        T[:3, 3] = np.asarray(base_position, dtype=float)
        robot.state.q = state_q
        robot.set_T_world_fbase(T)
        robot.update_kinematics()
        hand = robot.get_T_world_frame(self.hand_frame).copy()
        robot.state.q = saved_q
        robot.set_T_world_fbase(saved_base)
        robot.update_kinematics()
        return hand

    def probe(self, hand_target: ArrayLike, iterations: int = 200, step: float = 1e-3,
              heading: float | None = None) -> Probe:
        """Where the hand ends up when its target moves in a straight line to ``hand_target`` by
        ``step`` (m) per solve, followed by up to ``iterations`` solves on it (with ``heading``, asked
        to turn the hand to it there). The IK state is restored afterwards, so this is a pure
        reachability query. (Jumping to a far target at once can leave the QP in a worse local optimum
        than the streamed path the controller takes.)"""
        saved_q = self.robot.state.q.copy()
        saved = [
            np.copy(value) for value in (
                self._hand.target_world, self._posture_target, self._com_target, self._margin,
                self._tilt_rotvec, self._tilt_rotation, self._settled,
            )
        ]
        goal = np.asarray(hand_target, dtype=float)
        start = self.hand_position()
        n_path = int(np.ceil(np.linalg.norm(goal - start) / step))
        for k in range(1, n_path):
            self.solve(start + (goal - start) * (k / n_path))
        error, turned = np.inf, np.inf
        for _ in range(iterations):
            result = self.solve(goal, heading)
            now = 0.0 if heading is None else _yaw(self.robot.get_T_world_frame(self.hand_frame))
            if result.status == IKStatus.SOLVER_FAILED or (abs(error - result.hand_error) < 1e-7
                                                           and abs(turned - now) < 1e-7):
                break
            error, turned = result.hand_error, now
        rotation = self.robot.get_T_world_frame(self.hand_frame)[:3, :3].copy()
        self._hold_heading(False)
        hand, self._posture_target, self._com_target, margin, self._tilt_rotvec, self._tilt_rotation, settled = saved
        self._hand.target_world = hand
        self._margin, self._settled = float(margin), bool(settled)
        self._set_posture_targets()
        self._send_balance_targets()
        self.robot.state.q = saved_q
        self.robot.state.qd = np.zeros_like(self.robot.state.qd)
        self.robot.update_kinematics()
        self._good_q = saved_q.copy()
        return Probe(float(error), rotation)

    # ------------------------------------------------------------------ solving
    def _hold_heading(self, held: bool) -> None:
        """Put the heading task in the problem (``held``) or take it out: without one, the solver is the
        one without headings, unchanged."""
        if held and self._heading_task is None:
            self._heading_task = self.solver.add_orientation_task(self.hand_frame, np.eye(3))
            self._heading_task.mask.set_axises("z", "world")
            self._heading_task.configure("hand_heading", "soft", self.heading_weight)
        elif not held and self._heading_task is not None:
            self.solver.remove_task(self._heading_task)
            self._heading_task = None

    def solve(self, hand_target: ArrayLike, heading: float | None = None) -> IKResult:
        """One QP step towards ``hand_target`` (3,) (m, world) and, if given, the hand's ``heading`` about
        the vertical (rad; the forearm's direction, seen from above); never raises on an infeasible target."""
        target = np.asarray(hand_target, dtype=float)
        self._hold_heading(heading is not None)
        robot = self.robot
        self._settle()
        try:
            robot.update_kinematics()
            # The task sees at most MAX_HAND_PULL of error: the trade-off against the other tasks
            # grows with the error, and a far target would otherwise drag the pelvis and the CoM.
            T_hand = robot.get_T_world_frame(self.hand_frame)
            pull = target - T_hand[:3, 3]
            distance = math.sqrt(pull @ pull)  # np.linalg.norm's own sum, without its dispatch
            self._hand.target_world = (T_hand[:3, 3] + pull * min(1.0, MAX_HAND_PULL / distance) if distance > 0.0
                                       else target)
            level = _heading(T_hand)
            self._tilt.R_world_frame = level @ self._tilt_rotation
            if heading is not None:
                now = _yaw(level)
                turn = float(np.clip(np.angle(np.exp(1j * (heading - now))), -MAX_HEADING_PULL, MAX_HEADING_PULL))
                self._heading_task.R_world_frame = _yaw_matrix(now + turn) @ level.T @ T_hand[:3, :3]
            self.solver.solve(True)
            robot.update_kinematics()
            q = robot.state.q
            if not math.isfinite(q @ q):  # NaN or inf in any angle (or one beyond 1e154 rad)
                raise FloatingPointError("non-finite IK solution")
        except (RuntimeError, FloatingPointError) as error:
            logger.debug("IK step failed (%s); holding the last good posture", error)
            robot.state.q = self._good_q.copy()
            robot.state.qd = np.zeros_like(robot.state.qd)
            robot.update_kinematics()
            error_m = float(np.linalg.norm(self.hand_position() - target))
            return IKResult(self.q, IKStatus.SOLVER_FAILED, error_m)
        self._good_q = q.copy()
        miss = robot.get_T_world_frame(self.hand_frame)[:3, 3] - target
        error_m = math.sqrt(miss @ miss)
        status = IKStatus.OK if error_m <= self.tolerance else IKStatus.TARGET_UNREACHED
        return IKResult(q[self._q_index], status, error_m)


def _heading(T: np.ndarray) -> np.ndarray:
    """The level rotation with the same heading as the x axis of ``T`` (the forearm direction)."""
    c, s = T[0, 0], T[1, 0]
    norm = np.hypot(c, s)
    if norm < 1e-9:  # forearm vertical: any heading will do
        return np.eye(3)
    return _level(c / norm, s / norm)


def _yaw(T: np.ndarray) -> float:
    """The heading (rad) about the vertical of the x axis of ``T``."""
    return float(np.arctan2(T[1, 0], T[0, 0]))


def _yaw_matrix(angle: float) -> np.ndarray:
    return _level(np.cos(angle), np.sin(angle))


def _level(c: float, s: float) -> np.ndarray:
    """The rotation about the vertical whose cosine and sine are ``c`` and ``s``."""
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rodrigues(rotvec: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (cheaper than scipy for one small rotation per tick)."""
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        return np.eye(3)
    k = rotvec / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def polygon_distance(point: np.ndarray, polygon: np.ndarray) -> float:
    """Signed distance (m) from a 2-D point to the edges of a clockwise convex polygon, > 0 inside."""
    a = polygon
    b = np.roll(polygon, -1, axis=0)
    edge = b - a
    # for a clockwise polygon the interior is on the right of each edge: cross(edge, p - a) < 0
    cross = edge[:, 0] * (point[1] - a[:, 1]) - edge[:, 1] * (point[0] - a[:, 0])
    return float(np.min(-cross / np.linalg.norm(edge, axis=1)))
