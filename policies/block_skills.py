"""The robot's hand skills on the block of ``Imitate-v0``: approach, place (grasp, slide, let go) and push.

The hand's heading about the vertical is, in ``ee_delta``, the whole-body IK's choice, a function of
where the hand is (3 to 4 degrees more per centimetre to the left, from the IK model's probes of both
robots; none of it depends on the path there). So the palm can only press on the block at the heading of
where it stands, and a grasp turns the block to it (the squeeze lays a face flat on the palm). The thumb
is the one face whose heading the policy sets: it pivots on the hand, from 45 degrees open to 15 degrees
past parallel with the palm, and the closure turns it (:func:`thumb_angle`). Its outer face pushes the
block away from the hand's thumb side, and a cube pushed by a flat face turns until a face lies flat on
it: a push with the thumb held at the target's heading (the closure servoed against the hand's measured
heading, every step) moves the block along the face's normal and leaves it turned as the target. That
push is the skill every block target ends with; where the block is not already behind its target on that
line, a grasp first slides it there (:meth:`BlockHand.place`). Where the outer face would need the thumb
at its open stop and the target is near square, the thumb's inner face pushes instead (the block between
thumb and palm, pushed the other way), its hand standing further right and so headed less to the left
(:meth:`BlockHand.inner_face`). In ``ee_heading_delta`` (the imitation policies' mode) the hand's heading
is asked too: a push whose face lies past the thumb's closed stop turns the hand left, up to 25 degrees,
instead (:meth:`BlockHand.hand_turn`). Where no heading the thumb reaches is the target's, a turn through
(:meth:`BlockHand.turn_through`) pushes the block past that heading first and then back through it.

Skills are generators: each ``next()`` gives the action for the current step, the hand's fields
having been updated by :meth:`BlockHand.observe`. Hand paths are legs of the execution layer
(:mod:`~hoap_actions.policies.execution`): the desired point steps at the hand's speed limit (or a
fraction of it), and a leg ends when the controller's reference has arrived and the measured hand has
settled within the leg's tolerance.

Where the block is comes from the overhead camera (:func:`~hoap_actions.vision.block.locate_block`): at
the start, after each skill, and every few steps during a push (at a quarter of the resolution, where
the hand hides least of it), never from the simulator.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass

import gymnasium
import numpy as np

from hoap_actions.controllers.hand_control import rest_posture
from hoap_actions.controllers.wholebody_ik import WholeBodyIK
from hoap_actions.envs.controls import HAND_BOX_HIGH, HAND_BOX_LOW, MAX_HAND_STEP, MAX_HEADING_STEP
from hoap_actions.imitation.imitate_env import BLOCK_SIZE
from hoap_actions.policies.execution import MOVE_STEPS, REACH_TOLERANCE, REFERENCE_ARRIVED, SETTLE_SPEED
from hoap_actions.policies.grasp import THUMB_CONTACT_CLOSURE, THUMB_RANGE, thumb_outline
from hoap_actions.vision.block import BlockDetection, locate_block

__all__ = ["BlockHand", "BlockPose", "PushPlan", "closure_for", "run_up", "thumb_angle", "wrap_quarter"]

logger = logging.getLogger(__name__)

CAMERA = "overhead"
LOOK_SIZE = (320, 240)  # px, a look with the hand away: 0.3 mm on the block's centre, 3 degrees on its turn
SERVO_LOOK_SIZE = (160, 120)  # px, the looks during a push: a quarter of the rendering cost
MIN_HELD_PIXELS = 100  # top-face pixels (at LOOK_SIZE) of a grasped block seen well enough to say where it sits
SERVO_LOOK_STEPS = 3  # env steps between looks during a push
HALF = BLOCK_SIZE / 2.0
TRAVEL_Z = 0.075  # m, tcp height between skills: the palm (2 cm below the tcp) clears the 5 cm pegs by 0.5 cm
RETREAT = 0.045  # m, how far back along the forearm the hand goes for the camera to see the block
HOVER_Z = 0.05  # m, tcp height over the block: the palm 1 cm over its top
PUSH_Z = 0.026  # m, tcp height while the thumb pushes: its plate (tcp +- 1.5 cm) covers the cube's upper half
GRASP_Z = 0.024  # m, tcp height of a grasp: the palm's lower edge just over the table (the hand leans ~10 deg)
OPEN = 0.25  # closure of a hand coming down over the block: the thumb 30 deg open, a 29 mm gap at the block
LET_GO = 0.35  # closure that lets go of the set-down cube (at 0.5 the thumb still held it: lifted with the hand)
SQUEEZE = 0.64  # closure that holds the cube: the thumb meets a 20 mm cube at about 0.6
PALM_INNER_V = 0.0075  # m, the palm's inner face off the tcp, thumb-wards negative (grasp.PALM)
PALM_GAP = 0.0035  # m, gap left between the palm and the block while coming down
PALM_PUSH = 0.004  # m, how far the palm slides past touching the block: a cube turned 30 deg to it sticks out 3.7 mm
GRASP_MISALIGNED = np.radians(8.0)  # rad, a block turned more than this counter-clockwise to the palm is turned first
SQUEEZE_STEPS = 10  # steps (0.33 s) for the thumb to close on the block
RELEASE_STEPS = 8  # steps for the thumb to open off the set-down block
PUSH_SPEED = 0.3  # of the hand's speed limit while pushing: 4.5 cm/s
HAND_OFF = 0.035  # m, about how far the tcp stands from the block's centre while the thumb pushes it
PUSH_GAP = 0.004  # m, gap between the thumb and the block before the push
PUSH_ALONG = 0.03  # m, where along the thumb's outer face (from its back end) it meets the block
PUSH_OVERSHOOT = 0.004  # m, a push ends once the block is this far past its target along the push
MAX_PUSH = 0.08  # m, the longest push
ON_LINE = 0.003  # m, a block this near the push's line through the target is pushed from where it is
TURNED = np.radians(5.0)  # rad, a block turned this near its target needs no run-up to turn on the way
RUN_UP = 0.012  # m, how far behind its target a block is placed for a push that must also turn it ...
RUN_UP_PER_RADIAN = 0.03  # m, ... and this much further per radian it must turn (0.5 mm a degree) ...
MAX_RUN_UP = 0.035  # m, ... up to this
TURN_REACH = np.radians(6.0)  # rad, a target heading further than this past the thumb's reach is turned through ...
OVERTURN = np.radians(15.0)  # rad, ... by a first push aimed to leave the block this far past it ...
MIN_PAST = np.radians(8.0)  # rad, ... leaving it at least this far past (room for the turn back to cross) ...
MAX_PAST = np.radians(33.0)  # rad, ... and at most this (36-38 degrees past, pushed back, it missed on validation)
CROSSING = 0.006  # m, ... this far short of the target on the second push's line (where that push turns it back)
SLOW_PUSH = 0.1  # of the hand's speed limit: the pushes of a turn through (0.5 mm a step, 1.5 mm between looks)
LATERAL_GAIN = 0.7  # of the block's lateral error the hand moves per look: the thumb holds the block by friction
INNER_ALONG = 0.05  # m, where along the thumb's inner face (from its back end) it meets the block ...
INNER_HAND_OFF = 0.025  # m, ... the first guess of how far the tcp stands from the block's centre, palm-wards ...
INNER_THUMB_HIGH = np.radians(-20.0)  # rad, ... the thumb at least this open, so the block clears the palm (5 mm)
OPEN_STOP_MARGIN = np.radians(10.0)  # rad, an outer face this near the thumb's open stop (or past it) ...
INNER_GAIN = np.radians(5.0)  # rad, ... is pushed by the inner face if that leaves the thumb this much further in
INNER_SQUARE = np.radians(15.0)  # rad, ... and only for a target this near square (turned ones it lost held-out)
INNER_STEER = 0.005  # m, the most the looks shift an inner push towards the thumb's tip: the block sits 5 mm from it
THUMB_LOW = -THUMB_CONTACT_CLOSURE * THUMB_RANGE  # rad, the thumb's angle to the palm fully open (closure 0)
THUMB_HIGH = (1.0 - THUMB_CONTACT_CLOSURE) * THUMB_RANGE  # rad, fully closed (closure 1)
TURNING_MODE = "ee_heading_delta"  # the control mode in which the hand's heading is asked, not the IK's choice
MAX_LEFT_TURN = np.radians(25.0)  # rad, the most a push turns the hand left of the IK's heading there
THUMB_MARGIN = np.radians(5.0)  # rad, a turning hand keeps the thumb this far inside its closed stop (the servo's room)
REACH_SLACK = np.radians(1.0)  # rad, a turning hand's face this near the asked one is reached


def thumb_angle(closure: float) -> float:
    """The thumb's angle (rad) to the palm about the hand's vertical at a gripper closure in [0, 1]:
    0 parallel (closure 0.75), negative open (:func:`~hoap_actions.policies.grasp.thumb_outline`)."""
    return float((closure - THUMB_CONTACT_CLOSURE) * THUMB_RANGE)


def closure_for(angle: float) -> float:
    """The closure that sets the thumb at ``angle`` (rad) to the palm, held within [0, 1]."""
    return float(np.clip(THUMB_CONTACT_CLOSURE + angle / THUMB_RANGE, 0.0, 1.0))


def wrap_quarter(angle: float) -> float:
    """An angle (rad) modulo a quarter turn, in [-pi/4, pi/4): a cube's turn as it looks."""
    return float((angle + np.pi / 4) % (np.pi / 2) - np.pi / 4)


def run_up(turn: float) -> float:
    """How far (m) behind its target a block is placed for a push that must turn it by ``turn`` (rad) on
    the way: a pushed cube turns to the face gradually, so a larger turn needs a longer push."""
    return float(min(RUN_UP + RUN_UP_PER_RADIAN * abs(turn), MAX_RUN_UP))


def _unit(angle: float) -> np.ndarray:
    return np.array([np.cos(angle), np.sin(angle)])


def _short_of(target_xy: np.ndarray, face: float) -> np.ndarray:
    """Where a turn through's first push leaves the block: :data:`CROSSING` short of ``target_xy`` (2,) on
    the line of the second push, whose face is at ``face`` (rad)."""
    return target_xy - CROSSING * _unit(face - np.pi / 2)


def _rotation2(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


@dataclass(frozen=True)
class BlockPose:
    """The block on the table: its centre ``xy`` (2,) (m) and its turn ``yaw`` about the vertical (rad,
    modulo a quarter turn), with whether the camera saw its whole top face."""

    xy: np.ndarray
    yaw: float
    whole: bool = True

    @classmethod
    def from_detection(cls, found: BlockDetection) -> BlockPose:
        return cls(found.position_m[:2].copy(), found.yaw_rad, found.whole)


@dataclass(frozen=True)
class PushPlan:
    """A thumb push: the face's heading ``face`` (rad, world), the push ``direction`` (unit (2,), the
    pushing face's normal: the outer face's away from the palm, the ``inner`` face's towards it), the
    thumb's angle to the palm at the end (rad), the tcp points (3,) where the thumb comes down
    (``start``) and, ahead of it, that put the block at the target (``end``), and the hand's ``turn``."""

    face: float
    direction: np.ndarray
    thumb: float
    start: np.ndarray
    end: np.ndarray
    inner: bool = False
    turn: float = 0.0  # rad, the hand's turn beyond the IK model's heading (a turning hand only)


class BlockHand:
    """The hand of a robot in an ``Imitate-v0`` env (``control_mode`` ``"ee_delta"`` or ``"ee_heading_delta"``)
    and its skills on the block.

    It reads the hand through the observation (``parse_observation``), the controller's reference through
    ``hand_status``, the block through the overhead camera (``capture``), and asks its own whole-body IK
    model how the hand will be headed where it plans to put it.
    """

    def __init__(self, env: gymnasium.Env) -> None:
        self.env = env
        self._parse = env.get_wrapper_attr("parse_observation")
        self._capture = env.get_wrapper_attr("capture")
        self._fps = float(env.metadata["render_fps"])
        robot = env.get_wrapper_attr("robot_description")
        self.ik = WholeBodyIK(robot.joint_names, rest_posture(robot), fixed_legs=robot.fixed_legs)
        self.turns = env.get_wrapper_attr("control_mode") == TURNING_MODE
        self.fields: dict = {}
        self.start_fields: dict = {}
        self.desired = np.zeros(3)
        self.desired_heading = 0.0
        self.leg_heading: tuple[float, float, np.ndarray, float] | None = None
        self.turn = 0.0  # rad, the turn asked of the hand beyond the IK model's heading (turning mode)
        self.grip = OPEN
        self.looks = 0
        self.seen: BlockDetection | None = None
        self.skills: list[str] = []  # the skills run since :meth:`start`, in order

    # ------------------------------------------------------------------ state
    def start(self, obs: dict[str, np.ndarray]) -> None:
        """A new episode: the hand holds where it is, the thumb opens."""
        self.fields = self._parse(obs)
        self.start_fields = self.fields
        self.tcp = self.fields["tcp_position"]
        self.previous_tcp = self.tcp.copy()
        self.desired = self.tcp.copy()
        self.turn, self.leg_heading = 0.0, None
        self.grip = OPEN
        self.looks = 0
        self.skills = []
        f = self.fields
        self.ik.reset(f["joint_positions"], f["base_position"], f["base_quaternion"])
        if self.turns:
            self.desired_heading = float(np.arctan2(*self.hand_rotation()[1::-1, 0]))

    def observe(self, obs: dict[str, np.ndarray]) -> None:
        """This step's observation: the hand's position and joints."""
        self.fields = self._parse(obs)
        self.previous_tcp = self.tcp
        self.tcp = self.fields["tcp_position"]

    @property
    def speed(self) -> float:
        """The hand's measured speed (m/s)."""
        return float(np.linalg.norm(self.tcp - self.previous_tcp) * self._fps)

    def look(self, size: tuple[int, int] = LOOK_SIZE) -> BlockPose | None:
        """The block as the overhead camera sees it now, or None when it does not."""
        view = self._capture(CAMERA, *size)
        self.looks += 1
        found = locate_block(view.rgb, view.depth, view.camera, BLOCK_SIZE)
        self.seen = found
        return None if found is None else BlockPose.from_detection(found)

    def hand_rotation(self) -> np.ndarray:
        """The hand's rotation (3, 3) now, from the observed joints (forward kinematics)."""
        f = self.fields
        return self.ik.hand_pose_at(f["joint_positions"], f["base_position"], f["base_quaternion"])[:3, :3]

    def heading_at(self, point: np.ndarray) -> float:
        """The hand's heading (rad) about the vertical where the IK model puts it at ``point`` (3,). A hand
        that turns is asked its heading on every leg, so its model starts where the episode did: without a
        heading asked, the IK leaves the elbow where a turn swung it, and the headings would carry the turns
        before."""
        f = self.start_fields if self.turns else self.fields
        self.ik.reset(f["joint_positions"], f["base_position"], f["base_quaternion"])
        rotation = self.ik.probe(point).rotation
        return float(np.arctan2(rotation[1, 0], rotation[0, 0]))

    # ------------------------------------------------------------------ legs
    def _action(self, target: np.ndarray, speed: float) -> np.ndarray:
        """The action that steps the desired hand point towards ``target`` (straight, at ``speed`` of the
        limit) with the current grip; a turning hand's heading goes with it (:meth:`_heading_step`)."""
        step = (np.clip(target, HAND_BOX_LOW, HAND_BOX_HIGH) - self.desired) / MAX_HAND_STEP
        step /= max(1.0, float(np.max(np.abs(step))) / speed)
        self.desired = np.clip(self.desired + MAX_HAND_STEP * step, HAND_BOX_LOW, HAND_BOX_HIGH)
        if not self.turns:
            return np.array([*step, self.grip], dtype=np.float32)
        return np.array([*step, self._heading_step(), self.grip], dtype=np.float32)

    def still(self) -> np.ndarray:
        """The action that leaves the hand, its heading and the thumb as they are wanted now."""
        return np.array([0.0, 0.0, 0.0, *([0.0] if self.turns else []), self.grip], dtype=np.float32)

    def _start_leg(self, point: np.ndarray) -> None:
        """A turning hand's heading over a leg to ``point`` (3,): from the one asked now to the IK model's
        heading there plus :attr:`turn`, in step with the desired point's progress."""
        if self.turns:
            self.leg_heading = (self.desired_heading, self.heading_at(point) + self.turn, self.desired.copy(),
                                float(np.linalg.norm(point - self.desired)))

    def _heading_step(self) -> float:
        """The heading channel's action: towards the leg's heading for the desired point's progress."""
        if self.leg_heading is None:
            return 0.0
        start, end, origin, length = self.leg_heading
        progress = 1.0 if length < 1e-6 else min(1.0, float(np.linalg.norm(self.desired - origin)) / length)
        goal = start + float(np.angle(np.exp(1j * (end - start)))) * progress
        step = float(np.clip(np.angle(np.exp(1j * (goal - self.desired_heading))) / MAX_HEADING_STEP, -1.0, 1.0))
        self.desired_heading += MAX_HEADING_STEP * step
        return step

    def go(self, point: np.ndarray, grip: float | Callable[[], float] | None = None, speed: float = 1.0,
           tolerance: float = REACH_TOLERANCE) -> Iterator[np.ndarray]:
        """A straight leg to ``point`` (3,), ending as the execution layer's legs end; ``grip`` is a
        closure held (None: the current one) or a function called every step (a servo)."""
        point = np.clip(np.asarray(point, dtype=float), HAND_BOX_LOW, HAND_BOX_HIGH)
        self._start_leg(point)
        waited = 0
        while True:
            if grip is not None:
                self.grip = float(grip() if callable(grip) else grip)
            yield self._action(point, speed)
            reference = self.env.get_wrapper_attr("hand_status").reference
            if np.allclose(self.desired, point) and np.linalg.norm(reference - point) < REFERENCE_ARRIVED:
                waited += 1
                if (np.linalg.norm(self.tcp - point) < tolerance and self.speed < SETTLE_SPEED) or waited > MOVE_STEPS:
                    return

    def hold(self, steps: int, grip: float | None = None) -> Iterator[np.ndarray]:
        """Keep the hand where it is wanted for ``steps`` steps (the thumb moving to ``grip``)."""
        if grip is not None:
            self.grip = float(grip)
        for _ in range(steps):
            yield self._action(self.desired, 1.0)

    def travel(self, point: np.ndarray, grip: float | None = None) -> Iterator[np.ndarray]:
        """Up to :data:`TRAVEL_Z` (unless higher already), across, and down to ``point``."""
        up = max(TRAVEL_Z, self.tcp[2])
        if self.tcp[2] < up - 0.005:
            yield from self.go([*self.tcp[:2], up], grip, tolerance=0.005)
        if np.linalg.norm(self.tcp[:2] - point[:2]) > 0.005:
            yield from self.go([*point[:2], up], grip, tolerance=0.004)
        yield from self.go(point, grip)

    # ------------------------------------------------------------------ skills
    def approach(self, point_xy: np.ndarray) -> Iterator[np.ndarray]:
        """Point at ``point_xy`` (2,): the tcp over it, the palm a centimetre over the block's top."""
        self.skills.append("approach")
        yield from self.travel(np.array([*point_xy, HOVER_Z]), OPEN)
        yield from self.hold(int(self._fps))  # held there: the hand settles on the point

    def place(self, block: BlockPose, target_xy: np.ndarray) -> Iterator[np.ndarray]:
        """Grasp the block and slide it over the table to ``target_xy`` (2,), let go and back away.

        The hand comes down beside the block with the thumb open, slides until the palm touches it and
        squeezes. The lowest the hand gets (the palm's lower edge on the table, the hand leaning ~10
        degrees) leaves the tcp 1.4 cm over the block's centre, so the thumb (3 cm tall) holds only the
        cube's upper edge: a block lifted 4 mm in it pivoted out of the hand, so it is slid, not lifted,
        and keeps its turn on the way within a few degrees. Where it sits in the hand is looked at after
        the squeeze (which moves it), and the tcp's end is where that puts the block over the target
        (the hand's heading there asked of the IK model)."""
        self.skills.append("place")
        heading = self.heading_at(np.array([*block.xy, GRASP_Z]))
        if wrap_quarter(block.yaw - heading) > GRASP_MISALIGNED:
            yield from self.align(block)
            seen = self.look()
            if seen is None:
                return
            block = seen
            heading = self.heading_at(np.array([*block.xy, GRASP_Z]))
        y_axis = _unit(heading + np.pi / 2)  # from the thumb to the palm
        over = block.xy - (PALM_INNER_V - PALM_GAP - HALF) * y_axis  # the block thumb-wards, a gap off the palm
        yield from self.travel(np.array([*over, HOVER_Z]), OPEN)
        yield from self.go([*over, GRASP_Z], OPEN, speed=0.5)
        touch = block.xy - (PALM_INNER_V - HALF + PALM_PUSH) * y_axis  # the palm a few mm into it: lays it flat
        yield from self.go([*touch, GRASP_Z], speed=0.2, tolerance=0.001)
        yield from self.hold(SQUEEZE_STEPS, SQUEEZE)
        rotation = self.hand_rotation()
        held = self.look()
        if held is None:  # its top face is not at a resting cube's height: wedged up in the hand, let it drop
            yield from self.hold(RELEASE_STEPS, 0.0)
            yield from self.retreat()
            return
        held_xy = held.xy if self.seen.top_pixels >= MIN_HELD_PIXELS else block.xy
        in_hand = rotation.T @ np.array([*(held_xy - self.tcp[:2]), HALF - self.tcp[2]])
        end = np.array([*target_xy, GRASP_Z])
        for _ in range(2):  # the hand turns on the way: its heading at the end, then the end again
            f = self.fields
            self.ik.reset(f["joint_positions"], f["base_position"], f["base_quaternion"])
            end[:2] = target_xy - (self.ik.probe(end).rotation @ in_hand)[:2]
        yield from self.go(end, speed=0.5)
        yield from self.hold(RELEASE_STEPS, LET_GO)
        yield from self.retreat()

    def align(self, block: BlockPose) -> Iterator[np.ndarray]:
        """Turn the block with a thumb push to the heading the hand will have when it grasps it, where the
        push leaves it: a squeeze on a cube turned counter-clockwise to the palm by more than
        :data:`GRASP_MISALIGNED` wedged it up between the thumb and the palm (the thumb reaches only its
        upper edge); turned the other way, the closing thumb laid it flat on the palm (validation)."""
        where = block.xy
        for _ in range(2):  # the push moves the block, and the hand's heading over it with it
            yaw = self.heading_at(np.array([*where, GRASP_Z]))
            face = self.push_face(where, yaw)
            turn = wrap_quarter(block.yaw - face)
            where = block.xy + run_up(turn) * _unit(face - np.pi / 2)
        yield from self.push(self.plan_push(block, where, face), where)

    def push_face(self, target_xy: np.ndarray, yaw: float) -> float:
        """The heading (rad, world) of the thumb's outer face that leaves the block at ``target_xy`` (2,)
        turned ``yaw`` (rad, modulo a quarter turn): of the four headings a cube face can have, the one
        the thumb reaches nearest the middle of its range where the hand stands for the push (on the
        thumb's side of the block, about 3.5 cm off)."""
        best = None
        for k in range(-2, 3):
            face = wrap_quarter(yaw) + k * np.pi / 2
            if self.turns:  # where the turn is reached depends on where the turned hand stands: plan the contact
                tcp, thumb, turn = self.contact_tcp(target_xy, face, 0.0)
                needed = face - self.heading_at(tcp)
                miss = abs(needed - turn - thumb)  # within a degree: the planned and the probed tcp's headings
                key = (miss if miss > REACH_SLACK else 0.0, abs(needed - (THUMB_LOW + THUMB_HIGH) / 2))
            else:
                heading = self.heading_at(np.array([*(target_xy + HAND_OFF * _unit(face + np.pi / 2)), PUSH_Z]))
                thumb = face - heading
                key = (max(THUMB_LOW - thumb, thumb - THUMB_HIGH, 0.0), abs(thumb - (THUMB_LOW + THUMB_HIGH) / 2))
            if best is None or key < best[0]:
                best = (key, face)
            if key[0] == 0.0 and abs(face) <= np.pi / 4:  # the face whose push goes to the hand's right: the usual
                break
        return best[1]

    def hand_turn(self, thumb: float, high: float = THUMB_HIGH) -> float:
        """The turn (rad) to the left a turning hand takes so that a thumb needing ``thumb`` (rad, to the IK
        model's heading) past its closed stop ``high`` (or within :data:`THUMB_MARGIN` of it) has the
        margin; 0 for a hand that does not turn, a thumb inside it, or a turn beyond :data:`MAX_LEFT_TURN`
        (the push then goes as the unturned hand's, through the turn through). Turning right tilts the palm
        far more than turning left (``docs/envs.md``)."""
        if not self.turns or thumb <= high - THUMB_MARGIN:
            return 0.0
        turn = thumb - high + THUMB_MARGIN
        return float(turn) if turn <= MAX_LEFT_TURN else 0.0

    def contact_tcp(self, block_xy: np.ndarray, face: float, gap: float, inner: bool = False,
                    turn: float | None = None) -> tuple[np.ndarray, float, float]:
        """The tcp point (3,) at push height whose thumb, its outer (or ``inner``) face at heading ``face``,
        stands ``gap`` (m) off the block at ``block_xy`` (2,), the thumb's angle to the palm there (rad) and
        the hand's turn (``turn`` if given, else :meth:`hand_turn`): the hand's heading is the IK model's
        where the tcp then is, so they are found together (three rounds)."""
        tcp = block_xy + (INNER_HAND_OFF if inner else HAND_OFF) * _unit(face + np.pi / 2)
        high = INNER_THUMB_HIGH if inner else THUMB_HIGH
        fixed = turn
        for _ in range(3):
            heading = self.heading_at(np.array([*tcp, PUSH_Z]))
            turn = self.hand_turn(face - heading, high) if fixed is None else fixed
            thumb = float(np.clip(face - heading - turn, THUMB_LOW, high))
            tcp = self.tcp_for_contact(block_xy, heading + turn, thumb, gap, inner)
        return np.array([*tcp, PUSH_Z]), thumb, turn

    def plan_push(self, block: BlockPose, target_xy: np.ndarray, face: float,
                  overshoot: float = PUSH_OVERSHOOT, inner: bool = False) -> PushPlan:
        """A push of the block from ``block`` to ``target_xy`` (2,) by the thumb's outer (or ``inner``) face
        at heading ``face`` (rad), along the face's normal, to ``overshoot`` (m) past the target; a turning
        hand keeps the turn the push's end needs all along."""
        end, _, turn = self.contact_tcp(target_xy, face, -overshoot, inner)
        start, thumb, _ = self.contact_tcp(block.xy, face, PUSH_GAP, inner, turn)
        direction = _unit(face + np.pi / 2) if inner else _unit(face - np.pi / 2)
        return PushPlan(face, direction, thumb, start, end, inner, turn)

    @staticmethod
    def tcp_for_contact(block_xy: np.ndarray, heading: float, thumb: float, gap: float,
                        inner: bool = False) -> np.ndarray:
        """The tcp's xy (2,) that puts the thumb's outer face (or its ``inner`` one, the block then between
        thumb and palm), at ``thumb`` rad to the palm, the hand headed ``heading``, ``gap`` (m) short of the
        side of a block centred at ``block_xy``, meeting it :data:`PUSH_ALONG` (inner: :data:`INNER_ALONG`)
        from the thumb's back end."""
        outline = thumb_outline(closure_for(thumb))  # tcp frame: back-outer, front-outer, front-inner, back-inner
        back, front = (outline[3], outline[2]) if inner else (outline[0], outline[1])
        along = (front - back) / np.linalg.norm(front - back)
        normal = np.array([-along[1], along[0]]) if inner else np.array([along[1], -along[0]])  # out of the face
        contact = back + (INNER_ALONG if inner else PUSH_ALONG) * along
        return block_xy - _rotation2(heading) @ (contact + (HALF + gap) * normal)

    def thumb_needed(self, target_xy: np.ndarray, face: float, inner: bool = False) -> float:
        """The thumb's angle to the palm (rad, not held within its range) that sets its outer (or ``inner``)
        face at ``face`` (rad) for a push that leaves the block at ``target_xy`` (2,)."""
        tcp, _, _ = self.contact_tcp(target_xy, face, 0.0, inner)
        return face - self.heading_at(tcp)

    def face_reached(self, target_xy: np.ndarray, face: float) -> float:
        """The heading (rad) the thumb's outer face takes for a push that leaves the block at ``target_xy``
        (2,) with the face asked at ``face`` (rad): ``face`` within the thumb's reach there (a turning hand's
        included), else the stop nearest it."""
        tcp, thumb, turn = self.contact_tcp(target_xy, face, 0.0)
        return self.heading_at(tcp) + turn + thumb

    def inner_face(self, target_xy: np.ndarray, yaw: float, face: float) -> float | None:
        """The heading (rad) of the thumb's inner face for the push that leaves the block at ``target_xy``
        (2,) turned ``yaw`` (rad) within :data:`INNER_SQUARE` of square, where the outer face's push (at
        ``face``) would hold the thumb within :data:`OPEN_STOP_MARGIN` of its open stop or past it, and the
        inner face keeps it at least :data:`INNER_GAIN` further in; None otherwise. The inner face pushes the
        other way, its hand standing over the block rather than beside it: 2 to 3 cm further right, where the
        hand is headed 7 to 10 degrees less to the left."""
        square = wrap_quarter(yaw)
        if abs(square) > INNER_SQUARE:
            return None
        outer = self.thumb_needed(target_xy, face)
        if outer > THUMB_LOW + OPEN_STOP_MARGIN:
            return None
        best = None
        for k in range(-2, 3):
            candidate = square + k * np.pi / 2
            thumb = self.thumb_needed(target_xy, candidate, inner=True)
            reached = THUMB_LOW <= thumb <= INNER_THUMB_HIGH and thumb >= outer + INNER_GAIN
            if reached and (best is None or thumb > best[0]):
                best = (thumb, candidate)
        return None if best is None else best[1]

    def push_to(self, block: BlockPose, target_xy: np.ndarray, face: float, overshoot: float = PUSH_OVERSHOOT,
                speed: float = PUSH_SPEED, inner: bool = False) -> Generator[np.ndarray, None, bool]:
        """Push the block to ``target_xy`` (2,) with the outer (or ``inner``) face at ``face`` (rad), first
        sliding it behind the target on the push's line (:meth:`place`, :func:`run_up` behind) when it is
        off that line or too close to turn on the way. Returns False when the camera loses the block."""
        plan = self.plan_push(block, target_xy, face, overshoot, inner)
        offset = target_xy - block.xy
        ahead, aside = float(offset @ plan.direction), float(offset @ np.array([-plan.direction[1], plan.direction[0]]))
        turn = abs(wrap_quarter(block.yaw - face))
        if abs(aside) > ON_LINE or ahead < (0.0 if turn < TURNED else run_up(turn)):
            yield from self.place(block, target_xy - run_up(turn) * plan.direction)
            block = self.look()
            if block is None:
                return False
            plan = self.plan_push(block, target_xy, face, overshoot, inner)
        yield from self.push(plan, target_xy, overshoot, speed)
        return True

    def overturn_face(self, target_xy: np.ndarray, yaw: float, face: float) -> float | None:
        """The face (rad) of the first push of a turn through (:meth:`turn_through`) to ``target_xy`` (2,)
        turned ``yaw`` (rad), ``face`` being the push's face there; None when the thumb's stop leaves
        ``yaw`` within :data:`TURN_REACH` or no face it reaches leaves the block between
        :data:`MIN_PAST` and :data:`MAX_PAST` past ``yaw`` (then the usual push is the better try)."""
        miss = wrap_quarter(yaw - self.face_reached(target_xy, face))
        if abs(miss) <= TURN_REACH:
            return None
        side = float(np.sign(miss))
        short = _short_of(target_xy, face)
        first = self.push_face(short, yaw + side * OVERTURN)
        past = side * wrap_quarter(self.face_reached(short, first) - yaw)
        return first if MIN_PAST <= past <= MAX_PAST else None

    def turn_through(self, block: BlockPose, target_xy: np.ndarray, face: float,
                     first: float) -> Generator[np.ndarray, None, bool]:
        """Leave the block at ``target_xy`` (2,) turned a heading the thumb cannot hold its face at (``face``,
        the push's face, lies past the thumb's stop): a first push, with its face at ``first``
        (:meth:`overturn_face`), leaves the block turned past the target's heading, :data:`CROSSING` short
        of the target on the second push's line; the second, with the thumb at its stop, turns it back
        towards the stop's heading, through the target's on the way, while it carries it onto the target.
        Returns False when the camera loses the block."""
        self.skills.append("turn through")
        short = _short_of(target_xy, face)
        if not (yield from self.push_to(block, short, first, overshoot=0.0, speed=SLOW_PUSH)):
            return False
        block = self.look()
        if block is None:
            return False
        yield from self.push(self.plan_push(block, target_xy, face), target_xy, speed=SLOW_PUSH)
        return True

    def push(self, plan: PushPlan, target_xy: np.ndarray, overshoot: float = PUSH_OVERSHOOT,
             speed: float = PUSH_SPEED) -> Iterator[np.ndarray]:
        """Run a :class:`PushPlan`: the thumb set, down beside the block, then along the push (at ``speed``
        of the hand's limit) with the thumb's closure servoed to keep the face at its heading and the hand
        steered sideways by what the camera sees of the block, until the block is ``overshoot`` (m) past
        the target."""
        self.skills.append("inner push" if plan.inner else "push")
        direction = plan.direction
        side = np.array([-direction[1], direction[0]])

        def servo() -> float:
            rotation = self.hand_rotation()
            return closure_for(plan.face - float(np.arctan2(rotation[1, 0], rotation[0, 0])))

        self.turn = plan.turn
        yield from self.travel(np.array([*plan.start[:2], HOVER_Z]), closure_for(plan.thumb))
        yield from self.go(plan.start, servo, speed=0.5, tolerance=0.003)
        self._start_leg(plan.end)
        line = plan.start[:2].copy()  # the tcp's path: along the push, shifted sideways by the looks
        travelled = 0.0
        full = float((plan.end[:2] - plan.start[:2]) @ direction)
        while travelled < min(full, MAX_PUSH):
            travelled += SERVO_LOOK_STEPS * speed * MAX_HAND_STEP
            point = np.array([*(line + travelled * direction), PUSH_Z])
            for _ in range(SERVO_LOOK_STEPS):
                self.grip = servo()
                yield self._action(point, speed)
            seen = self.look(SERVO_LOOK_SIZE)
            logger.debug("push: tcp %s travelled %.4f of %.4f, block seen %s", np.round(self.tcp, 4), travelled, full,
                         None if seen is None else np.round(seen.xy, 4))
            if seen is None:
                continue
            error = target_xy - seen.xy
            if error @ direction < -overshoot:
                break
            line = line + LATERAL_GAIN * float(error @ side) * side
            if plan.inner:  # the hand goes back along the block (it slides tipwards on the thumb) only so far
                line = line - max(0.0, float((line - plan.start[:2]) @ side) - INNER_STEER) * side
            full = travelled + float(error @ direction) + overshoot
        yield from self.go([*(self.desired[:2] - PUSH_GAP * direction), PUSH_Z], speed=0.5, tolerance=0.004)
        yield from self.retreat()

    def retreat(self) -> Iterator[np.ndarray]:
        """Up off the block, then back along the forearm out of the overhead camera's view of it."""
        yield from self.go([*self.tcp[:2], HOVER_Z], speed=0.5, tolerance=0.005)
        self.turn = 0.0  # off the block: the hand may turn back
        rotation = self.hand_rotation()
        back = self.tcp[:2] - RETREAT * rotation[:2, 0] / np.linalg.norm(rotation[:2, 0])
        yield from self.go([*back, TRAVEL_Z], OPEN, tolerance=0.005)
