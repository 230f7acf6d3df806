"""From a desired hand position to joint targets, once per physics tick: ruckig smoothing, then IK.

:class:`HandController` owns a :class:`~hoap_actions.controllers.retiming.StreamingRetimer` (3 DOF,
the hand position) and a :class:`~hoap_actions.controllers.wholebody_ik.WholeBodyIK`. Each
:meth:`HandController.tick` advances the retimer one period towards the desired position, solves
one IK step for the smoothed point and sends the joint targets to the robot.

Two corrections use the measured hand (PyBullet's tcp). While the reference is at rest, a slow
integral term adds the measured error to the IK target, so servo sag under gravity leaves no steady
millimetre offset; it is frozen while the hand moves, because tracking lag and sway are not sag and
winding them up shakes the robot. And the IK target never goes more than :data:`MAX_LEAD` below
the measured hand, so a hand pressed down on an obstacle does not drag the whole body down after
it. (Only downwards: capping it sideways too makes the command follow the robot's own rocking,
which grows into a fall.) The push itself is the servos' full torque, up to ~30 N (measured); when
it tips the robot, the balance guard below releases it.

Balance comes before the hand. The IK keeps the model's centre of mass inside the support polygon,
but it plans kinematically: the real feet can still rock on an edge when the body's motion or a
push of the hand on the table or the board loads the ankles beyond what a 4 cm heel can hold, and
bang-bang actions then pumped that rocking until the robot fell (2 falls in 40 000 random and
bang-bang steps with the IK's slow body; none in another 40 000 with this guard). So while a sole is tilted more than
:data:`BALANCE_TILT`, and for :data:`BALANCE_HOLD` after, the hand yields: the reference is set to
where the servos actually hold the hand when the tilt is first seen (the measured hand carried into
the IK's frame through the pelvis, so the robot's own sway does not move it) and held there, which
ends at once any push on the table or the board (a palm pressed on the board lifted the robot's
front with 33 N); the legs and the waist slow to :data:`BALANCE_BODY_SPEED` and the integral term
is cleared. A rocking robot that holds still damps itself out (heel and toe impacts take about half
the energy of each swing, measured).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike
from ruckig import RuckigError
from scipy.spatial.transform import Rotation

from hoap_actions.controllers.retiming import StreamingRetimer
from hoap_actions.controllers.wholebody_ik import PELVIS, IKResult, IKStatus, WholeBodyIK
from hoap_actions.errors import InvalidInputError

__all__ = ["HAND_LIMITS", "HandController", "HandLimits", "RobotDescription", "StandingRobot", "rest_posture",
           "start_posture"]


class StandingRobot(Protocol):
    """What the hand controller needs of a robot (``hoap_actions.envs.robot.Robot`` is one): its
    joints, measured state and servo targets. A protocol, so that this control layer does not
    import the simulated world that uses it."""

    joint_names: Sequence[str]
    home_posture: Sequence[float]
    fixed_legs: bool
    targets: np.ndarray

    def joint_index(self, name: str) -> int: ...
    def joint_positions(self) -> np.ndarray: ...
    def base_pose(self) -> tuple[np.ndarray, np.ndarray]: ...
    def frame_pose(self, frame: str) -> tuple[np.ndarray, np.ndarray]: ...
    def sole_tilt(self) -> float: ...
    def set_targets(self, q: ArrayLike) -> None: ...


@dataclass(frozen=True)
class HandLimits:
    """Cartesian limits of the smoothed hand reference: m/s, m/s^2, m/s^3 per axis."""

    velocity: float = 0.15
    acceleration: float = 1.0
    jerk: float = 10.0


HAND_LIMITS = HandLimits()
INTEGRAL_GAIN = 2.0  # 1/s: the correction closes a steady error with a 0.5 s time constant
INTEGRAL_LIMIT = 0.005  # m, largest correction per axis: sag is ~1-2 mm; more is a blocked hand
INTEGRAL_MAX_ERROR = 0.004  # m, measured errors beyond this (contact, sway) are not integrated
AT_REST_SPEED = 1e-3  # m/s, reference speed below which the hand counts as at rest
REST = {
    "l_shoulder_pitch": 0.5,  # left upper arm raised, forearm near vertical: elbow 11 cm over the table
    "l_elbow": -1.95,
    "r_elbow": np.radians(-95.0),  # right forearm 20 deg up: clear of the pegs' tops (home's level forearm is not)
}
MAX_LEAD = 0.02  # m, furthest the IK target may go below the measured hand (free motion lags < 1 cm)
UNREACHED_TICKS = 24  # ticks (0.1 s) of IK error above tolerance before the target counts as unreachable
UNREACHED_TICKS_FIXED_LEGS = 240
"""The same for a robot with welded legs (1 s): its waist alone swings the trunk back at the body's
0.3 rad/s (about 0.5 s for a near hole after a far peg), where the legs share the work for the standing
one. With 0.1 s the scripted expert gave up on 4 of 50 validation layouts (all solved given 1 s)."""
BALANCE_TILT = np.radians(0.5)  # rad, sole tilt beyond which a foot rocks (standing still, settled: < 0.1 deg)
BALANCE_HOLD = 0.3  # s the hand keeps yielding after the soles are level again (a rocking swing takes ~0.3 s)
BALANCE_BODY_SPEED = 0.02  # rad/s, IK speed limit of the legs and waist while the hand yields


START = REST | {
    "r_shoulder_pitch": 2.0,  # upper arm swung back, elbow fully bent and turned out: the hand waits
    "r_elbow": -2.0,  # over the table's near right corner, 9 cm up, beside the work area. The overhead
    "r_shoulder_roll": -0.4,  # camera sees none of the arm over the work area (from the rest posture
    "r_shoulder_yaw": 0.4,  # the forearm hid 14 of 300 pegs, seeds 0-99) and it touches nothing (a
}  # hand waiting lower and nearer, at the table's edge, rested on the board in 10 of 100 layouts)


def start_posture(robot: StandingRobot | RobotDescription) -> np.ndarray:
    """The posture ee_delta episodes begin in: :func:`rest_posture` with the right hand pulled back
    beside the work area, out of the overhead camera's view of it."""
    q = rest_posture(robot)
    names = list(robot.joint_names)
    for name, value in START.items():
        q[names.index(name)] = value
    return q


def rest_posture(robot: StandingRobot | RobotDescription) -> np.ndarray:
    """The home posture with the left arm raised and folded (no squat or lean lowers it onto the table)
    and the right forearm tilted up 20 deg (home's level forearm, 4.2 cm over the table at its
    lowest, sweeps through 5 cm pegs)."""
    q = np.array(robot.home_posture, dtype=float)
    names = list(robot.joint_names)
    for name, value in REST.items():
        q[names.index(name)] = value
    return q


@dataclass(frozen=True)
class RobotDescription:
    """A robot's joints (names, in the order of its joint vectors), home posture (rad) and whether its
    legs are welded to a fixed pelvis: what a policy needs to build its own kinematic model of it."""

    joint_names: tuple[str, ...]
    home_posture: tuple[float, ...]
    fixed_legs: bool = False


class HandController:
    """Moves the right hand of ``robot`` to a desired world position with the whole body standing.

    Parameters
    ----------
    robot
        the robot to command (its ``set_targets`` gets the whole posture).
    dt
        tick period (s): one call of :meth:`tick` per physics step.
    ik
        the whole-body IK (default: one built on the robot's joints and :func:`rest_posture`).
    limits
        Cartesian velocity / acceleration / jerk limits of the hand reference.
    integral_gain
        gain (1/s) of the measured-error correction; 0 turns it off.
    ik_period
        ticks per retimer and IK step. Above 1, each step plans the hand's reference that many ticks
        ahead and the joint targets move linearly to the IK's answer over those ticks: the servos get
        a target every tick at a fraction of the solver's cost.
    """

    def __init__(
        self,
        robot: StandingRobot,
        dt: float,
        ik: WholeBodyIK | None = None,
        limits: HandLimits = HAND_LIMITS,
        integral_gain: float = INTEGRAL_GAIN,
        ik_period: int = 1,
    ) -> None:
        if isinstance(ik_period, bool) or not isinstance(ik_period, int) or ik_period < 1:
            raise InvalidInputError(f"ik_period={ik_period!r} must be a whole number of ticks >= 1")
        self.robot = robot
        self.ik_period = ik_period
        self.dt = float(dt) * ik_period  # the retimer's and the IK's step
        self.ik = ik or WholeBodyIK(robot.joint_names, rest_posture(robot), dt=self.dt, fixed_legs=robot.fixed_legs)
        unreached_ticks = UNREACHED_TICKS_FIXED_LEGS if robot.fixed_legs else UNREACHED_TICKS
        self._unreached_limit = -(-unreached_ticks // ik_period)  # in IK steps
        self.integral_gain = float(integral_gain)
        self.retimer = StreamingRetimer(3, self.dt, limits.velocity, limits.acceleration, limits.jerk)
        self._gripper = robot.joint_index("r_gripper")
        self.target = np.zeros(3)
        self.heading: float | None = None  # the hand's heading asked of the IK (rad), None: the IK's choice
        self.reference = np.zeros(3)
        self._velocity = np.zeros(3)
        self._correction = np.zeros(3)
        self._unreached = 0
        self._yield_steps = 0
        self._held = np.zeros(3)
        self.last = IKResult(np.asarray(robot.home_posture, dtype=float), IKStatus.OK, 0.0)
        self._phase = 0  # ticks done of the current IK step
        self._q_from = self._q_to = np.asarray(robot.home_posture, dtype=float)
        self._q_change = np.zeros_like(self._q_to)  # from the last IK step's posture to this one's

    def reset(self) -> None:
        """Start from the robot's measured state, holding the hand where it is."""
        robot = self.robot
        q = robot.joint_positions()
        self.ik.reset(q, *robot.base_pose())
        self.reference = self.ik.hand_position()
        self.target = self.reference.copy()
        self.heading = None
        self.retimer.reset(self.reference)
        self._velocity = np.zeros(3)
        self._correction = np.zeros(3)
        self._unreached = 0
        self._yield_steps = 0
        self.ik.set_body_speed(self.ik.body_speed)
        self.last = IKResult(self.ik.q, IKStatus.OK, 0.0)
        self._phase = 0
        self._q_to = robot.targets.copy()

    def set_target(self, position: ArrayLike, heading: float | None = None) -> None:
        """The world position (3,) the hand should go to (m), reached at the retimer's pace, and the
        hand's ``heading`` about the vertical (rad; None leaves it to the IK)."""
        self.target = np.asarray(position, dtype=float).copy()
        self.heading = None if heading is None else float(heading)

    @property
    def unreachable(self) -> bool:
        """True once the IK has missed its target (or failed) for :data:`UNREACHED_TICKS` ticks in a row
        (:data:`UNREACHED_TICKS_FIXED_LEGS` with welded legs)."""
        return self._unreached >= self._unreached_limit

    @property
    def yielding(self) -> bool:
        """True while the hand yields to balance (a sole tilted, or was within :data:`BALANCE_HOLD`)."""
        return self._yield_steps > 0

    def tick(self) -> IKResult:
        """One physics period: at the start of each IK step, plan it (:meth:`_plan`); then the joint
        targets for this tick, on the line from the last step's posture to this one's."""
        if self._phase == 0:
            self._q_from = self._q_to
            self._q_to = self._plan().q
            self._q_change = self._q_to - self._q_from
        self._phase += 1
        q = self._q_to.copy() if self._phase == self.ik_period else (
            self._q_from + (self._phase / self.ik_period) * self._q_change)
        q[self._gripper] = self.robot.targets[self._gripper]  # the gripper is commanded separately
        self.robot.set_targets(q)
        self._phase %= self.ik_period
        return self.last

    def _plan(self) -> IKResult:
        """One IK step: smooth the target, correct it by the measured error, solve."""
        measured = self.robot.frame_pose("r_tcp")[0]
        if not self.robot.fixed_legs:  # welded soles on a fixed pelvis never tilt
            self._watch_balance(measured)
        target = self._held if self.yielding else self.target
        try:
            step = self.retimer.step(target)
        except RuckigError:
            # ruckig 0.19 rejects ~0.4 % of inputs whose coordinates carry round-off (1e-17 m); the
            # same state rounded to a nanometre always passes (measured on 20 000 random moves)
            self.retimer.reset(np.round(self.reference, 9), np.round(self._velocity, 9))
            step = self.retimer.step(np.round(target, 9))
        self.reference, self._velocity = step.position, step.velocity
        error = self.reference - measured
        speed = step.velocity
        if self.integral_gain > 0.0 and not self.yielding and math.sqrt(speed @ speed) < AT_REST_SPEED:
            if math.sqrt(error @ error) < INTEGRAL_MAX_ERROR:
                self._correction += self.integral_gain * self.dt * error
                np.clip(self._correction, -INTEGRAL_LIMIT, INTEGRAL_LIMIT, out=self._correction)
        target = self.reference + self._correction
        # pressing down on something: the IK target stays within MAX_LEAD below the measured hand
        target[2] = max(target[2], measured[2] - MAX_LEAD)
        result = self.ik.solve(target, self.heading)
        self._unreached = self._unreached + 1 if result.status != IKStatus.OK else 0
        self.last = result
        return result

    def _watch_balance(self, measured: np.ndarray) -> None:
        """Start, extend or end the hand's yielding to balance from the soles' tilt (see the module doc)."""
        if self.robot.sole_tilt() > BALANCE_TILT:
            if not self.yielding:
                self._held = self._held_hand(measured)
                self.retimer.reset(self._held)
                self.reference, self._velocity = self._held.copy(), np.zeros(3)
                self._correction = np.zeros(3)
                self.ik.set_body_speed(BALANCE_BODY_SPEED)
            self._yield_steps = int(round(BALANCE_HOLD / self.dt))  # in IK steps
        elif self._yield_steps > 0:
            self._yield_steps -= 1
            if self._yield_steps == 0:
                self.ik.set_body_speed(self.ik.body_speed)

    def _held_hand(self, measured: np.ndarray) -> np.ndarray:
        """Where the servos actually hold the hand, in the IK's frame: the measured hand (3,) carried
        from the measured pelvis to the IK model's, so a sway of the whole robot does not move it."""
        position, quaternion = self.robot.base_pose()
        offset = Rotation.from_quat(quaternion).inv().apply(measured - position)
        T_pelvis = self.ik.robot.get_T_world_frame(PELVIS)
        return T_pelvis[:3, :3] @ offset + T_pelvis[:3, 3]
