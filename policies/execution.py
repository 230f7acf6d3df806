"""The execution layer every grasp-and-insert policy shares: grasp, carry, release, recover.

A policy built on :class:`GraspAndInsert` says only where its knowledge of the world and its hand
paths come from (the scripted expert: the observation's true poses and straight lines; the PHMM
policy: the overhead camera and the learned models). This layer runs the paper's sequence
(Fig. 9), approach -> grasp -> move -> release -> remove, the same way for both:

- **Paths** are *legs*: points one env step apart (or farther: then the desired hand point steps
  towards them in straight lines at the hand's speed limit), each leg ending when the desired point
  is at its last point and the measured hand has settled within the leg's tolerance (or
  :data:`MOVE_STEPS` after).
- **Grasp**: the hand comes down with the thumb half open (:data:`~hoap_actions.policies.grasp.PRE_CLOSURE`)
  and the palm a few millimetres off the peg, slides until the palm just touches it
  (:data:`~hoap_actions.policies.grasp.PALM_GAP`, along the hand's current heading from its
  forward kinematics) and squeezes (:data:`~hoap_actions.policies.grasp.GRASP_CLOSURE`).
- **Carry**: where the held peg's bottom is relative to the tcp is measured after the lift when the
  policy can measure the peg, else taken from its estimate at the grasp; the move's end puts that
  bottom over (or into) the hole.
- **Release**: the gripper opens over the hole and the peg drops.
- **Recover**: a hand that stops above its reference while coming down has landed on something;
  it backs off and comes again with the next grasp shift along the palm.
- **Checks** end the episode with a reason (:attr:`GraspAndInsert.failure`): ``"unreachable
  layout"``, ``"peg knocked over"``, ``"grasp slipped"``, ``"approach blocked"``, or what the policy
  adds (e.g. ``"not seen"``). The checks that need the peg's pose run when the policy measures it.
"""

from __future__ import annotations

import enum
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np

from hoap_actions.controllers.hand_control import rest_posture
from hoap_actions.controllers.wholebody_ik import WholeBodyIK
from hoap_actions.envs import scene as scene_module
from hoap_actions.envs.controls import HAND_BOX_HIGH, HAND_BOX_LOW, MAX_HAND_STEP
from hoap_actions.errors import InvalidInputError
from hoap_actions.policies.grasp import (
    GRASP_CLOSURE,
    GRASP_SHIFTS,
    PALM_GAP,
    PRE_CLOSURE,
    GraspPlan,
    grasp_xy,
    hand_axes,
    plan_grasp,
)

__all__ = ["GraspAndInsert", "Leg", "WorldEstimate", "straight_leg"]

REACH_TOLERANCE = 0.002  # m, tcp-to-point distance at which a leg counts as done
REFERENCE_ARRIVED = 1e-4  # m, the controller's smoothed reference this near a leg's end has arrived
SETTLE_SPEED = 0.02  # m/s, tcp speed under which the hand counts as settled
CLOSE_STEPS = 9  # steps (0.3 s) for the thumb to close on the peg
OPEN_STEPS = 8  # steps for the thumb to open and the peg to drop
MOVE_STEPS = 90  # steps (3 s) a leg may wait at its end for the hand to settle before moving on regardless
BLOCKED_HEIGHT = 0.008  # m, tcp this far above its reference while coming down: something is under the hand
BLOCKED_STEPS = 3  # steps in a row of a blocked hand before backing off
BACK_OFF_HEIGHT = 0.03  # m, how far a blocked hand rises before it comes again
MIN_LIFT = 0.02  # m, how far the peg must have risen with the hand after the lift
SLIP_DISTANCE = 0.01  # m, drift of the peg relative to the hand that counts as a slipped grasp
KNOCKED_OVER = np.radians(30.0)  # tilt of the target peg before the grasp at which the policy gives up
ALIGN_TOLERANCE = 0.0007  # m, lateral peg-bottom-to-hole error accepted before going down
MAX_CORRECTIONS = 4  # measure-and-correct rounds over the hole before going down regardless
ALIGN_HEIGHT = 0.003  # m, peg bottom over the board surface while it is lined up with the hole
INSERT_DEPTH = 0.008  # m, how far the peg's bottom enters the hole before the hand lets go


@dataclass(frozen=True)
class Leg:
    """Hand points (N, 3) to follow, one per step, and the ``tolerance`` (m) that ends the leg."""

    points: np.ndarray
    tolerance: float = REACH_TOLERANCE


def straight_leg(end: np.ndarray, tolerance: float = REACH_TOLERANCE) -> Leg:
    """A leg that goes straight to ``end`` at the hand's speed limit."""
    return Leg(np.asarray(end, dtype=float).reshape(1, 3), tolerance)


@dataclass(frozen=True)
class WorldEstimate:
    """What a policy knows of the layout at the start: the target ``peg`` centre (3,), the ``others``
    (k, 3), every hole (N_HOLES, 3) and the target ``hole`` (3,) (m)."""

    peg: np.ndarray
    others: np.ndarray
    holes: np.ndarray
    hole: np.ndarray


class Phase(enum.Enum):
    APPROACH = enum.auto()
    BACK_OFF = enum.auto()
    TOUCH = enum.auto()
    CLOSE = enum.auto()
    LIFT = enum.auto()
    MOVE = enum.auto()
    ALIGN = enum.auto()
    INSERT = enum.auto()
    RELEASE = enum.auto()
    REMOVE = enum.auto()
    DONE = enum.auto()


class GraspAndInsert(ABC):
    """``obs -> action`` grasp-and-insert on ``hoap_actions/PegInsert-v0`` with ``control_mode="ee_delta"``
    (the :class:`~hoap_actions.apps.episodes.Policy` protocol); subclasses give the world estimate and the paths.

    It reads the observation through the env's ``parse_observation``, the hand controller's state
    through ``hand_status``, and plans with its own kinematic model of the robot (a
    :class:`~hoap_actions.controllers.wholebody_ik.WholeBodyIK` reset from the observed joints).
    """

    failure: str | None
    control_mode = "ee_delta"  # the env's control mode this policy acts through
    env_ids = ("hoap_actions/PegInsert-v0",)  # the envs whose task it performs

    def __init__(self, env: gymnasium.Env) -> None:
        spec_id = getattr(env.spec, "id", None)
        if spec_id not in self.env_ids:
            raise InvalidInputError(f"{type(self).__name__} performs grasp-and-insert; it needs one of "
                                    f"{list(self.env_ids)}, not {spec_id or type(env).__name__}")
        control_mode = env.get_wrapper_attr("control_mode")
        if control_mode != self.control_mode:
            raise InvalidInputError(f"{type(self).__name__} needs control_mode='ee_delta'; this env uses "
                                    f"{control_mode!r}")
        self.env = env
        self._parse = env.get_wrapper_attr("parse_observation")
        self._fps = float(env.metadata["render_fps"])
        robot = env.get_wrapper_attr("robot_description")
        self.ik = WholeBodyIK(robot.joint_names, rest_posture(robot), fixed_legs=robot.fixed_legs)
        self.failure = None
        self.world: WorldEstimate | None = None
        self.phase = Phase.DONE

    # ------------------------------------------------------------------ what subclasses provide
    @abstractmethod
    def locate(self, obs: dict[str, np.ndarray], fields: dict[str, Any]) -> WorldEstimate | None:
        """The layout at the start of an episode, or None (then :attr:`failure` says why)."""

    def measure_peg(self, fields: dict[str, Any]) -> tuple[np.ndarray, bool] | None:
        """The target peg's measured bottom (3,) and whether it stands upright, this step; None when
        the policy cannot measure it (then the checks that need it do not run)."""
        return None

    @abstractmethod
    def approach_legs(self, start: np.ndarray, grasp: np.ndarray) -> list[Leg]:
        """From the hand's ``start`` to the ``grasp`` tcp point, palm a few mm off the peg."""

    def lift_legs(self, grasp: np.ndarray) -> list[Leg]:
        """Up from the grasp before the move is planned (none: the move lifts)."""
        return []

    @abstractmethod
    def move_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        """Carry the held peg from the tcp at ``start`` to the tcp at ``end``; the executor puts
        ``end`` where the peg's bottom is over the hole (:meth:`move_end`)."""

    def prepare(self) -> str | None:
        """Plan what the paths need once the grasp is planned; a failure reason stops the episode."""
        return None

    def move_bottom_target(self) -> np.ndarray:
        """Where the move leaves the held peg's bottom (3,): 8 mm into the hole. Policies that line
        the peg up first override it."""
        return np.array([*self.world.hole[:2], scene_module.BOARD_SIZE[2] - INSERT_DEPTH])

    def move_end(self) -> np.ndarray:
        """The tcp point (3,) that puts the held peg's bottom at :meth:`move_bottom_target`. The peg
        turns with the hand, and the hand is not held level everywhere (the IK lets it tilt a few
        degrees where a level forearm cannot reach: 5 mm at a held peg's bottom), so the hand's
        orientation there is asked of the IK model (twice: the tcp moves with the answer)."""
        bottom = self.move_bottom_target()
        f = self.fields
        self.ik.reset(f["joint_positions"], f["base_position"], f["base_quaternion"])
        tcp = bottom - self._grip_rotation @ self.peg_in_hand
        for _ in range(2):
            tcp = bottom - self.ik.probe(tcp).rotation @ self.peg_in_hand
        return tcp

    def insert_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        """After the move (and any alignment): into the hole (none: the move ends in it)."""
        return []

    @abstractmethod
    def remove_legs(self, start: np.ndarray, end: np.ndarray) -> list[Leg]:
        """From over the hole back to where the hand started."""

    def back_off_legs(self, start: np.ndarray) -> list[Leg]:
        """A blocked hand's way up before it comes again."""
        return [straight_leg(start + [0.0, 0.0, BACK_OFF_HEIGHT], tolerance=0.005)]

    # ------------------------------------------------------------------ policy protocol
    @property
    def done(self) -> bool:
        """True once the whole sequence has run (whether or not the peg went in)."""
        return self.failure is None and self.phase == Phase.DONE and self.world is not None

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        fields = self._parse(obs)
        self.failure = None
        self.tcp = fields["tcp_position"]
        self.home = self.tcp.copy()
        self.desired = self.tcp.copy()
        self.previous_tcp = self.tcp.copy()
        self.grip = PRE_CLOSURE
        self.corrections = 0
        self.blocked_steps = 0
        self.peg_in_hand = None
        self._enter(Phase.DONE)
        self.ik.reset(fields["joint_positions"], fields["base_position"], fields["base_quaternion"])
        self.world = self.locate(obs, fields)
        if self.world is None:
            self.failure = self.failure or "not seen"
            return
        self.tried_shifts: list[float] = []
        self.plan = plan_grasp(self.ik, self.world.peg, self.world.others, self.world.holes)
        if self.plan is None:
            self.failure = "unreachable layout"
            return
        self.tried_shifts.append(self.plan.shift)
        self.failure = self.prepare()
        if self.failure is None:
            self._enter(Phase.APPROACH, self.approach_legs(self.tcp, self.plan.tcp(self.world.peg)))

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        fields = self._parse(obs)
        self.tcp = fields["tcp_position"]
        self.fields = fields
        speed = np.linalg.norm(self.tcp - self.previous_tcp) * self._fps
        self.previous_tcp = self.tcp.copy()
        self.steps_in_leg += 1
        if self.failure is None:
            self._update(speed, self.measure_peg(fields))
        target = self._target()
        step = (np.clip(target, HAND_BOX_LOW, HAND_BOX_HIGH) - self.desired) / MAX_HAND_STEP
        step /= max(1.0, float(np.max(np.abs(step))))  # uniform scaling: straight moves
        self.desired = np.clip(self.desired + MAX_HAND_STEP * step, HAND_BOX_LOW, HAND_BOX_HIGH)
        return np.array([*step, self.grip], dtype=np.float32)

    # ------------------------------------------------------------------ legs
    def _enter(self, phase: Phase, legs: list[Leg] | None = None) -> None:
        self.phase = phase
        self.legs = list(legs or [])
        self.point = 0
        self.steps_in_leg = 0

    def _target(self) -> np.ndarray:
        if not self.legs:
            return self.desired
        points = self.legs[0].points
        return points[min(self.point, len(points) - 1)]

    def _leg_done(self, speed: float) -> bool:
        """Advance along the current leg; True when the phase's last leg is done. A leg ends when
        the hand controller's reference has reached its end and the measured hand has settled within
        its tolerance: the reference first, or a small correction would end before the hand moved."""
        if not self.legs:
            return True
        leg = self.legs[0]
        end = np.clip(leg.points[-1], HAND_BOX_LOW, HAND_BOX_HIGH)
        if self.point < len(leg.points) - 1:
            if np.allclose(self.desired, np.clip(leg.points[self.point], HAND_BOX_LOW, HAND_BOX_HIGH)):
                self.point += 1
                self.steps_in_leg = 0
            return False
        at_end = np.allclose(self.desired, end) and np.linalg.norm(self._reference - end) < REFERENCE_ARRIVED
        close = np.linalg.norm(self.tcp - leg.points[-1]) < leg.tolerance and speed < SETTLE_SPEED
        if at_end and (close or self.steps_in_leg > MOVE_STEPS):
            self.legs.pop(0)
            self.point, self.steps_in_leg = 0, 0
        return not self.legs

    def hand_rotation_now(self) -> np.ndarray:
        """The hand's rotation (3, 3) from the observed joints (forward kinematics)."""
        f = self.fields
        return self.ik.hand_pose_at(f["joint_positions"], f["base_position"], f["base_quaternion"])[:3, :3]

    def hand_axes_now(self) -> tuple[np.ndarray, np.ndarray]:
        """The hand's horizontal axes from the observed joints."""
        return hand_axes(self.hand_rotation_now())

    def _hold(self, bottom: np.ndarray) -> None:
        """Remember where the held peg's bottom (3,) sits in the hand's frame."""
        self._grip_rotation = self.hand_rotation_now()
        self.peg_in_hand = self._grip_rotation.T @ (bottom - self.tcp)

    # ------------------------------------------------------------------ the sequence
    def _update(self, speed: float, peg: tuple[np.ndarray, bool] | None) -> None:
        status = self.env.get_wrapper_attr("hand_status")
        self._reference = status.reference
        phase = self.phase
        at_leg_end = bool(self.legs) and self.point >= len(self.legs[0].points) - 1
        if status.unreachable and at_leg_end and phase in (Phase.APPROACH, Phase.MOVE, Phase.ALIGN):
            self.failure = "unreachable layout"  # on the way the hand may lag a point it cannot reach; not at the end
            return
        if peg is not None and not peg[1] and phase in (Phase.APPROACH, Phase.BACK_OFF, Phase.TOUCH):
            self.failure = "peg knocked over"
            return
        if phase == Phase.APPROACH:
            # coming down on something: the hand stays above its reference
            low = len(self.legs) == 1 and self.point >= len(self.legs[0].points) - 1
            self.blocked_steps = (self.blocked_steps + 1 if low and self.tcp[2] - status.reference[2] > BLOCKED_HEIGHT
                                  else 0)
            if self.blocked_steps >= BLOCKED_STEPS:
                self._enter(Phase.BACK_OFF, self.back_off_legs(self.tcp.copy()))
            elif self._leg_done(speed):
                self._enter(Phase.TOUCH, [straight_leg(self._touch_point(), tolerance=0.001)])
        elif phase == Phase.BACK_OFF:
            if self._leg_done(speed):
                untried = [s for s in GRASP_SHIFTS if s not in self.tried_shifts]
                if not untried:
                    self.failure = "approach blocked"
                    return
                self.plan = GraspPlan(untried[0], self.plan.z, self.plan.axes)
                self.tried_shifts.append(self.plan.shift)
                self.blocked_steps = 0
                self._enter(Phase.APPROACH, self.approach_legs(self.tcp.copy(), self.plan.tcp(self.world.peg)))
        elif phase == Phase.TOUCH:
            self.legs[0] = straight_leg(self._touch_point(), tolerance=0.001)  # follows the hand's heading
            if self._leg_done(speed):
                self.grip = GRASP_CLOSURE
                self._enter(Phase.CLOSE)
        elif phase == Phase.CLOSE:
            if self.steps_in_leg >= CLOSE_STEPS:
                self.grasp_tcp = self.tcp.copy()
                self._hold(self.world.peg - [0.0, 0.0, scene_module.PEG_LENGTH / 2])
                self._enter(Phase.LIFT, self.lift_legs(self.tcp.copy()))
        elif phase == Phase.LIFT:
            if self._leg_done(speed):
                if peg is not None:
                    if peg[0][2] < MIN_LIFT and self.lift_legs(self.grasp_tcp):
                        self.failure = "grasp slipped"
                        return
                    self._hold(peg[0])
                end = self.move_end()
                self.move_target = end
                self._enter(Phase.MOVE, self.move_legs(self.tcp.copy(), end))
        elif phase == Phase.MOVE:
            self._check_slip(peg)
            if self._leg_done(speed):
                self._after_move(peg)
        elif phase == Phase.ALIGN:
            self._check_slip(peg)
            if self._leg_done(speed):
                self._after_move(peg)
        elif phase == Phase.INSERT:
            if self._leg_done(speed):
                self.grip = 0.0
                self._enter(Phase.RELEASE)
        elif phase == Phase.RELEASE:
            if self.steps_in_leg >= OPEN_STEPS:
                self._enter(Phase.REMOVE, self.remove_legs(self.tcp.copy(), self.home))
        elif phase == Phase.REMOVE:
            if self._leg_done(speed):
                self._enter(Phase.DONE)

    def _touch_point(self) -> np.ndarray:
        return np.array([*grasp_xy(self.world.peg, self.plan.shift, PALM_GAP, self.hand_axes_now()), self.plan.z])

    def _after_move(self, peg: tuple[np.ndarray, bool] | None) -> None:
        """Over the hole: line the peg up by measurement (when measured and asked for), then insert;
        a policy that cannot see the held peg lines up where the hand's measured pose puts it."""
        insert = self.insert_legs(self.tcp.copy(), self.move_target)
        if peg is None and not insert:
            if self._correct_alignment(self.move_bottom_target()[:2] - self._held_bottom()[:2]):
                return
        if peg is not None and insert:
            if self._correct_alignment(self.world.hole[:2] - peg[0][:2]):
                return
            depth = scene_module.BOARD_SIZE[2] - INSERT_DEPTH
            end = np.array([*self._target()[:2], depth + self.tcp[2] - peg[0][2]])
            insert = self.insert_legs(self.tcp.copy(), end)
        if insert:
            self._enter(Phase.INSERT, insert)
        else:
            self.grip = 0.0
            self._enter(Phase.RELEASE)

    def _correct_alignment(self, error: np.ndarray) -> bool:
        """Shift the hand by the peg bottom's lateral ``error`` (2,) (m) and say so, unless it is within
        :data:`ALIGN_TOLERANCE` or the corrections are used up."""
        if np.linalg.norm(error) < ALIGN_TOLERANCE or self.corrections >= MAX_CORRECTIONS:
            return False
        self.corrections += 1
        target = self._target().copy()
        target[:2] += error
        self._enter(Phase.ALIGN, [straight_leg(target, tolerance=0.003)])
        return True

    def _held_bottom(self) -> np.ndarray:
        """Where the held peg's bottom (3,) is now if it turned with the hand since the grasp."""
        return self.tcp + self.hand_rotation_now() @ self.peg_in_hand

    def _check_slip(self, peg: tuple[np.ndarray, bool] | None) -> None:
        if peg is not None and np.linalg.norm(self._held_bottom() - peg[0]) > SLIP_DISTANCE:
            self.failure = "grasp slipped"
