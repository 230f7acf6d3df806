"""From a desired hand position to joint targets, once per physics tick: ruckig smoothing, then IK.

:class:`HandController` owns a :class:`~hoap_actions.controllers.retiming.StreamingRetimer` (3 DOF,
the hand position) and a :class:`~hoap_actions.controllers.wholebody_ik.WholeBodyIK`. Each
:meth:`HandController.tick` advances the retimer one period towards the desired position, solves
one IK step for the smoothed point and sends the joint targets to the robot.

Two corrections use the measured hand (PyBullet's tcp). While the reference is at rest, a slow
integral term adds the measured error to the IK target, so servo sag under gravity leaves no steady
millimetre offset; it is frozen while the hand moves, because tracking lag and sway are not sag and
winding them up shakes the robot. And the IK target never goes more than :data:`MAX_LEAD` below
the measured hand, so a hand pressed down on an obstacle pushes with a bounded force instead of
tipping the robot over. (Only downwards: capping it sideways too makes the command follow the
robot's own rocking, which grows into a fall.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from ruckig import RuckigError

from hoap_actions.controllers.retiming import StreamingRetimer
from hoap_actions.controllers.wholebody_ik import IKResult, IKStatus, WholeBodyIK
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.sim import TIMESTEP

__all__ = ["HAND_LIMITS", "HandController", "HandLimits", "rest_posture"]


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


def rest_posture(robot: Robot) -> np.ndarray:
    """The home posture with the left arm raised and folded (no squat or lean lowers it onto the table)
    and the right forearm tilted up 20 deg (home's level forearm, 4.2 cm over the table at its
    lowest, sweeps through 5 cm pegs)."""
    q = np.array(robot.home_posture, dtype=float)
    for name, value in REST.items():
        q[robot.joint_index(name)] = value
    return q


class HandController:
    """Moves the right hand of ``robot`` to a desired world position with the whole body standing.

    Args:
        robot: the robot to command (its :meth:`~Robot.set_targets` gets the whole posture).
        ik: the whole-body IK (default: one built on the robot's joints and :func:`rest_posture`).
        limits: Cartesian velocity / acceleration / jerk limits of the hand reference.
        dt: tick period (s): one call of :meth:`tick` per physics step.
        integral_gain: gain (1/s) of the measured-error correction; 0 turns it off.
    """

    def __init__(
        self,
        robot: Robot,
        ik: WholeBodyIK | None = None,
        limits: HandLimits = HAND_LIMITS,
        dt: float = TIMESTEP,
        integral_gain: float = INTEGRAL_GAIN,
    ) -> None:
        self.robot = robot
        self.ik = ik or WholeBodyIK(robot.joint_names, rest_posture(robot), dt=dt)
        self.dt = float(dt)
        self.integral_gain = float(integral_gain)
        self.retimer = StreamingRetimer(3, self.dt, limits.velocity, limits.acceleration, limits.jerk)
        self._gripper = robot.joint_index("r_gripper")
        self.target = np.zeros(3)
        self.reference = np.zeros(3)
        self._velocity = np.zeros(3)
        self._correction = np.zeros(3)
        self._unreached = 0
        self.last = IKResult(np.asarray(robot.home_posture, dtype=float), IKStatus.OK, 0.0)

    def reset(self) -> None:
        """Start from the robot's measured state, holding the hand where it is."""
        robot = self.robot
        q = robot.joint_positions()
        self.ik.reset(q, *robot.base_pose())
        self.reference = self.ik.hand_position()
        self.target = self.reference.copy()
        self.retimer.reset(self.reference)
        self._velocity = np.zeros(3)
        self._correction = np.zeros(3)
        self._unreached = 0
        self.last = IKResult(self.ik.q, IKStatus.OK, 0.0)

    def set_target(self, position: ArrayLike) -> None:
        """The world position (3,) the hand should go to (m); reached at the retimer's pace."""
        self.target = np.asarray(position, dtype=float).copy()

    @property
    def unreachable(self) -> bool:
        """True once the IK has missed its target (or failed) for :data:`UNREACHED_TICKS` ticks in a row."""
        return self._unreached >= UNREACHED_TICKS

    def tick(self) -> IKResult:
        """One period: smooth the target, correct it by the measured error, solve IK, command the joints."""
        try:
            step = self.retimer.step(self.target)
        except RuckigError:
            # ruckig 0.19 rejects ~0.4 % of inputs whose coordinates carry round-off (1e-17 m); the
            # same state rounded to a nanometre always passes (measured on 20 000 random moves)
            self.retimer.reset(np.round(self.reference, 9), np.round(self._velocity, 9))
            step = self.retimer.step(np.round(self.target, 9))
        self.reference, self._velocity = step.position, step.velocity
        measured = self.robot.frame_pose("r_tcp")[0]
        error = self.reference - measured
        if self.integral_gain > 0.0 and np.linalg.norm(step.velocity) < AT_REST_SPEED:
            if np.linalg.norm(error) < INTEGRAL_MAX_ERROR:
                self._correction += self.integral_gain * self.dt * error
                np.clip(self._correction, -INTEGRAL_LIMIT, INTEGRAL_LIMIT, out=self._correction)
        target = self.reference + self._correction
        # pressing down on something: the IK target stays within MAX_LEAD below the measured hand
        target[2] = max(target[2], measured[2] - MAX_LEAD)
        result = self.ik.solve(target)
        self._unreached = self._unreached + 1 if result.status != IKStatus.OK else 0
        q = result.q.copy()
        q[self._gripper] = self.robot.targets[self._gripper]  # the gripper is commanded separately
        self.robot.set_targets(q)
        self.last = result
        return result
