"""Action interpretations (``control_mode``): how a bounded action becomes joint targets for the robot."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from hoap_actions.controllers.hand_control import HandController, start_posture
from hoap_actions.envs import world
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.sim import TIMESTEP
from hoap_actions.errors import InvalidInputError

MAX_JOINT_DELTA = 0.05  # rad per action (30 Hz): 1.5 rad/s at full command, under the 5 rad/s servo limit
JOINT_DELTA_JOINTS = (
    "waist_pitch",
    "r_shoulder_pitch",
    "r_shoulder_roll",
    "r_shoulder_yaw",
    "r_elbow",
    "r_wrist_yaw",
    "r_gripper",
)


class JointDeltaController:
    """``"joint_delta"``: action in [-1, 1]^7 moves the waist and right-arm joint targets by up to 0.05 rad.

    Order: waist pitch, right shoulder pitch / roll / yaw, elbow, hand torsion, gripper. Episodes begin
    in :func:`~hoap_actions.controllers.hand_control.start_posture`, as ee_delta ones do (in the home
    posture the right forearm lay on a peg after half the resets); the legs, head and left arm hold it.
    A target beyond a joint's range is held at the range limit, as a servo would, and ``last_clipped``
    (reported as ``info["target_clipped"]``) says so.
    """

    def __init__(self, robot: Robot) -> None:
        self.robot = robot
        names = list(robot.joint_names)
        self._indices = np.array([names.index(n) for n in JOINT_DELTA_JOINTS])
        self.action_space = spaces.Box(-1.0, 1.0, shape=(len(JOINT_DELTA_JOINTS),), dtype=np.float32)
        self.last_clipped = False
        self._start = start_posture(robot)
        self._target = self._start.copy()

    def start_episode(self) -> None:
        """On the freshly restored world, pose the robot in the posture episodes begin in."""
        self.robot.reset(self._start)

    def reset(self) -> None:
        """Controlled joints start where they are; the others hold the start posture."""
        self._target = self._start.copy()
        self._target[self._indices] = self.robot.joint_positions()[self._indices]
        self.last_clipped = False

    def apply(self, action: np.ndarray) -> None:
        wanted = self._target[self._indices] + MAX_JOINT_DELTA * action
        low, high = self.robot.lower[self._indices], self.robot.upper[self._indices]
        clipped = np.clip(wanted, low, high)
        self.last_clipped = bool(np.any(clipped != wanted))
        self._target[self._indices] = clipped
        self.robot.set_targets(self._target)


IK_PERIOD = {"full": 4, "fixed_legs": 4}
"""Physics ticks per retimer and IK step of ee_delta, per robot model (the env's ``ik_period``): the
longest that kept the policies' success on validation layouts (``benchmarks/ik_period.py``); at 8 ticks
a third to a half of those episodes ran out of time. An env may keep its own (``HoapEnv.ik_periods``)."""
MAX_HAND_STEP = 0.005  # m per action and axis (30 Hz): 0.15 m/s, the hand reference's speed limit
HAND_BOX_LOW = np.array([world.WORK_AREA_LOW[0] - 0.04, world.WORK_AREA_LOW[1] - 0.05, 0.015])
HAND_BOX_HIGH = np.array([world.WORK_AREA_HIGH[0] + 0.04, world.WORK_AREA_HIGH[1] + 0.05, 0.16])
"""World box (m) the desired hand position is held in: the work area with room for the holes at its
edges, from just above the table (1.5 cm: the palm reaches 2 cm below the tcp) to 16 cm above it."""


class EEDeltaController:
    """``"ee_delta"``: action in [-1, 1]^4 moves the desired right-hand (tcp) position and works the gripper.

    ``action[:3]`` adds up to :data:`MAX_HAND_STEP` (5 mm) per axis to the desired world position,
    held inside :data:`HAND_BOX_LOW`..:data:`HAND_BOX_HIGH` (``last_clipped`` says when it was held).
    ``action[3]`` is the gripper closure ``clip(a, 0, 1)``: ``<= 0`` open, 1 fully closed; 0.75 just
    touches a 15 mm peg and the squeeze grows with the closure beyond it (0.78 holds a peg firmly).
    Between actions, every ``ik_period`` physics ticks (:data:`IK_PERIOD`) a ruckig retimer smooths the
    desired position under velocity / acceleration / jerk limits and the whole-body IK turns it into
    joint targets for all 28 joints, feet planted, centre of mass inside the support polygon, which the
    servos are led to along a line, tick by tick (:meth:`tick`); while a foot rocks, the
    hand yields to balance and holds where it is. ``hand`` exposes the IK status (``hand.last``),
    whether the target proved unreachable and whether the hand is yielding (``hand.yielding``).

    Episodes start from :func:`~hoap_actions.controllers.hand_control.start_posture` (left arm raised,
    right hand pulled back beside the work area) rather than the home posture, whose level right
    forearm lies across the pegs' tops and hides them from the overhead camera: :meth:`start_episode`
    poses the robot there on the freshly restored world, before the env places the layout.
    """

    def __init__(self, robot: Robot, ik_period: int | None = None) -> None:
        self.robot = robot
        if ik_period is None:
            ik_period = IK_PERIOD["fixed_legs" if robot.fixed_legs else "full"]
        self.hand = HandController(robot, TIMESTEP, ik_period=ik_period)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.last_clipped = False
        self.desired = np.zeros(3)

    def start_episode(self) -> None:
        """On the freshly restored world, pose the robot in the posture episodes begin in."""
        self.robot.reset(start_posture(self.robot))

    def reset(self) -> None:
        """Hold the hand where it is; the gripper keeps its current target."""
        self.hand.reset()
        self.desired = self.hand.reference.copy()
        self.last_clipped = False

    def apply(self, action: np.ndarray) -> None:
        wanted = self.desired + MAX_HAND_STEP * np.asarray(action[:3], dtype=float)
        self.desired = np.clip(wanted, HAND_BOX_LOW, HAND_BOX_HIGH)
        self.last_clipped = bool(np.any(self.desired != wanted))
        self.hand.set_target(self.desired)
        self.robot.set_gripper("right", float(np.clip(action[3], 0.0, 1.0)))

    def tick(self) -> None:
        """One physics period: retimer step, IK step, joint targets."""
        self.hand.tick()


MAX_HEADING_STEP = np.radians(3.0)  # rad per action (30 Hz): 90 deg/s
MAX_HEADING_LEAD = np.radians(30.0)  # rad, the most the desired heading runs ahead of the hand's
HEADING_WEIGHT = 100.0
"""Soft weight (per rad^2) of the hand's heading in the IK of ``ee_heading_delta``: at 1 the tilt task
(weight 1) wins and the hand turns a few degrees; at 100 the IK model turns it 15 degrees to the left
over the block area with the palm 3-4 degrees more tilted (``docs/envs.md``)."""


class EEHeadingDeltaController(EEDeltaController):
    """``"ee_heading_delta"``: ee_delta with the hand's heading about the vertical: action in [-1, 1]^5.

    ``action[:3]`` moves the desired hand position as in ee_delta; ``action[3]`` turns the desired heading
    (the forearm's direction seen from above) by up to :data:`MAX_HEADING_STEP` (3 degrees) to the left
    (positive) or right; ``action[4]`` is the gripper closure. The whole-body IK holds the hand at that
    heading as a soft task (:data:`HEADING_WEIGHT`): HOAP-3's five-joint arm turns its hand by swinging
    the elbow, which tilts the palm, so headings far from the one the IK would choose are reached in
    part. The desired heading is kept within :data:`MAX_HEADING_LEAD` of the IK model's (``last_clipped``
    says when it was held there); it starts at the hand's heading at reset.
    """

    def __init__(self, robot: Robot, ik_period: int | None = None) -> None:
        super().__init__(robot, ik_period)
        self.hand.ik.heading_weight = HEADING_WEIGHT  # read when the first heading is asked
        self.action_space = spaces.Box(-1.0, 1.0, shape=(5,), dtype=np.float32)
        self.desired_heading = 0.0

    def reset(self) -> None:
        """Hold the hand where it is and headed as it is; the gripper keeps its current target."""
        super().reset()
        self.desired_heading = self.hand.ik.hand_heading()

    def apply(self, action: np.ndarray) -> None:
        super().apply(np.asarray(action)[[0, 1, 2, 4]])
        now = self.hand.ik.hand_heading()
        lead = float(np.angle(np.exp(1j * (self.desired_heading + MAX_HEADING_STEP * float(action[3]) - now))))
        held = float(np.clip(lead, -MAX_HEADING_LEAD, MAX_HEADING_LEAD))
        self.last_clipped = self.last_clipped or held != lead
        self.desired_heading = now + held
        self.hand.set_target(self.desired, self.desired_heading)


CONTROL_MODES = {"joint_delta": JointDeltaController, "ee_delta": EEDeltaController,
                 "ee_heading_delta": EEHeadingDeltaController}
HAND_CONTROL_MODES = ("ee_delta", "ee_heading_delta")
"""The control modes whose actions move the hand in space (through the hand controller)."""


def make_controller(control_mode: str, robot: Robot, ik_period: int | None = None
                    ) -> JointDeltaController | EEDeltaController:
    """The controller for ``control_mode`` (one of :data:`CONTROL_MODES`); ``ik_period`` (ticks per IK
    step) is the hand-space modes' alone (:data:`HAND_CONTROL_MODES`)."""
    if control_mode not in HAND_CONTROL_MODES:
        if ik_period is not None:
            raise InvalidInputError(f"ik_period={ik_period!r} applies to control_mode in {list(HAND_CONTROL_MODES)} "
                                    f"only; leave it None for {control_mode!r}")
        return CONTROL_MODES[control_mode](robot)
    return CONTROL_MODES[control_mode](robot, ik_period)
