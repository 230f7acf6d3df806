"""The human demonstrator: a seated adult's right arm that reaches for, pushes, lifts and turns a block,
recorded like a VICON session (6 arm/hand markers and the block's pose at 100 Hz).

Every episode is approach -> one manipulation -> remove (the paper's approach-act-remove cycle), from
and back to rest with the arm hanging beside the chair. This module scripts the episodes and runs
their physics; what a task and a recording are is :mod:`~hoap_actions.demonstration.tasks`, the timing of
every path :mod:`~hoap_actions.demonstration.minimum_jerk`, the planning IK :mod:`~hoap_actions.demonstration.arm_ik`.

Phase labels (hidden ground truth, evaluation only) come from the demonstrator's *plan*, never from
the recorded object trajectory, so evaluating methods that read ``O`` is not circular;
:data:`LABELS_VERSION` names the labelling. The labels, the motion model (minimum-jerk paths with
trial-to-trial variability), the choice of hand posture by comfort, the IK and the physics of pushes and
grasps are described in ``docs/demonstrator.md``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.demonstration.arm_ik import (
    ARM_WEIGHT,
    BODY_JOINTS,
    HAND_HULL,
    RECORDED_JOINTS,
    SITE_OFFSETS,
    ArmIK,
    hand_rotation,
)
from hoap_actions.demonstration.bodies import DEMONSTRATORS, DemonstratorProfile, human_urdf
from hoap_actions.demonstration.minimum_jerk import bezier_length, minimum_jerk, minimum_jerk_curve
from hoap_actions.demonstration.scene import HAND_LINKS, DemoScene
from hoap_actions.demonstration.tasks import DIRECTIONS, FPS, PHASE_NAMES, TURNS, DemoRecording, DemoTask
from hoap_actions.errors import InvalidInputError

logger = logging.getLogger(__name__)

MARKER_LINKS = (
    "marker_shoulder",
    "marker_elbow",
    "marker_wrist",
    "marker_index_tip",
    "marker_index_knuckle",
    "marker_thumb_tip",
)
REST_POSTURE = dict.fromkeys(BODY_JOINTS, 0.0) | {
    "r_shoulder_flexion": -0.1,
    "r_shoulder_abduction": 0.12,
    "r_elbow": 0.3,
}
"""Seated, arm hanging beside the chair, elbow slightly bent, palm towards the thigh."""
WORK_POSTURE = dict.fromkeys(BODY_JOINTS, 0.0) | {
    "r_shoulder_flexion": 0.5,
    "r_shoulder_abduction": 0.3,
    "r_shoulder_rotation": 0.3,
    "r_elbow": 1.3,
    "r_forearm_pronation": 0.6,
}
"""Relaxed working posture the arm is weakly pulled towards at the table (elbow low and bent)."""
LIFT_POSTURE = dict.fromkeys(BODY_JOINTS, 0.0) | {
    "r_shoulder_flexion": 0.3,
    "r_shoulder_abduction": 0.25,
    "r_elbow": 2.2,
    "r_forearm_pronation": 0.3,
}
"""Hand drawn up close to the body, fingers up: how a seated person brings a hanging hand above the
table top (their elbow is at table height) before reaching out; the posture target on the way."""
FINGERS_REST = np.array([0.25, 0.30])  # rad (index flexion, thumb opposition)
FINGERS_OPEN = np.array([0.50, 0.00])  # before a pinch: index half-bent, thumb abducted
FINGERS_PINCH = np.array([np.pi / 2 + 0.1, 1.4865 + 0.1])  # beyond contact on a 5 cm block: the close is guarded
FINGERS_PUSH = np.array([0.05, 0.10])
GRASP_DISTANCE = 0.003  # m, a closing finger stops this close to the block; both stopped -> grasp
PLACE_CLEARANCE = 0.002  # m, the block is set down from this height above the table
HAND_CLEARANCE = 0.015  # m, lowest point of a pushing hand above the table
PUSH_RELAX = 0.008  # m, the hand eases off the block after a push, before it leaves
GRASP_HEIGHT = 0.003  # m, the pinch point sits this far above the block's centre
PUSH_GAP = 0.015  # m, planned gap between hand and block before a push
TABLE_MARGIN = 0.015  # m, a planned reach keeps the hand this far from the table top's edge
BLOCK_MARGIN = 0.005  # m, ... and this far from the block, except near its ends
_SIDE_PUSH = ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -0.08))
"""Push left/right: (fingers, back of the hand, contact point in the palm frame): fingers forward, thumb
up; the palm pushes left, the back of the hand right. The contact point meets the block face's centre."""
_FRONT_PUSHES = (
    ((0.0, 1.0, -0.2), (1.0, 0.0, 0.0), (0.0, 0.0, -0.08)),  # fingers left, palm to the body
    ((0.0, 1.0, -1.0), (1.0, 0.0, 0.0), (-0.01, 0.0, -0.13)),  # fingers left and down, palm to the body
    ((0.0, -1.0, -1.0), (-1.0, 0.0, 0.0), (-0.01, 0.0, -0.13)),  # fingers right and down, palm forward
    ((0.0, -1.0, -0.2), (-1.0, 0.0, 0.0), (0.0, 0.0, -0.08)),  # fingers right, palm forward
)
"""Push forward/backward candidates, thumb up: the one most comfortable where the block is is used
(palm to the body on the left of the shoulder, palm forward on its right, as people do)."""

# Timing: a segment's nominal duration (s), before the episode's and the segment's speed factors
EPISODE_SPEED_RANGE = (0.87, 1.13)  # per-episode speed factor; with +-5 % per segment, about +-15 %
REACH_S, REACH_S_PER_M = 0.75, 0.45  # a reach (approach or remove): 0.75 s plus 0.45 s per metre of path
PUSH_S, PUSH_S_PER_M = 0.5, 3.0  # a push: slower per metre, the hand keeps contact with the block
CARRY_S, CARRY_S_PER_M = 0.7, 2.5  # a carry (move)
TURN_S, TURN_S_PER_RAD = 0.6, 0.5  # a rotate
PINCH_CLOSE_S, PINCH_OPEN_S = 0.35, 0.3  # the fingers closing on and opening off the block
SETTLE_S = 0.15  # hand still on the block after a grasping approach, before the fingers close
LET_GO_S = 0.1  # hand still before and after the fingers open
REST_HOLD_S = 0.25  # at rest after the remove

# Reach geometry (scene frame, m): via points of the Bezier path out of and back to the hanging pose
RISE_FORWARD, RISE_SHARE_OF_Y, RISE_HEIGHT = 0.02, 0.3, 0.25  # first via point: up beside the body, a third across
ABOVE_TARGET = 0.14  # second via point: this high over the target (offset 5 cm along the descent side)
DESCEND_OFFSET = 0.05
_STRAIGHT_DOWN = np.zeros(3)  # default descent side of a reach: none, straight down (only read, never mutated)
LEAVE_AWAY, LEAVE_HEIGHT = 0.03, 0.18  # the remove's first via point: off the block and up
VIA_JITTER, VIA_JITTER_LIMIT = 0.015, 0.03  # trial-to-trial spread of via points (std, clip)
REST_JITTER, REST_JITTER_LIMIT = 0.006, 0.01  # ... of the rest pose the remove returns to
CARRY_LIFT_RANGE = (0.08, 0.11)  # m, how high a carried block is lifted

# Controller and choreography settings
POSITION_GAIN, VELOCITY_GAIN = 0.8, 1.0
ARM_WEIGHT_AT_REST = 3e-3  # arm posture weight once the hand is back at rest (the arm settles there)
ORIENTATION_WEIGHT = 1.0


@dataclass
class _Segment:
    """A stretch of motion with one label: per-frame site targets and IK settings (n frames)."""

    label: str
    site: str
    positions: np.ndarray  # (n, 3)
    rotations: list[Rotation]  # n palm orientations
    fingers: np.ndarray  # (n, 2)
    orientation_weights: np.ndarray  # (n,)
    postures: np.ndarray  # (n, 7) arm regularisation targets
    arm_weights: np.ndarray  # (n,)


@dataclass
class _Tape:
    """The frames recorded so far in one episode."""

    H: list[np.ndarray] = field(default_factory=list)
    O: list[np.ndarray] = field(default_factory=list)
    Q: list[np.ndarray] = field(default_factory=list)
    labels: list[int] = field(default_factory=list)
    table_contacts: int = 0


class Demonstrator:
    """Performs :class:`DemoTask` episodes in a :class:`DemoScene` and records them at :data:`FPS`."""

    def __init__(self, scene: DemoScene, profile: DemonstratorProfile = DEMONSTRATORS["reference"]) -> None:
        """``profile``: who demonstrates (:mod:`~hoap_actions.demonstration.bodies`); its body must be the
        one ``scene`` holds."""
        if profile.height_m != scene.body_height_m:
            raise InvalidInputError(f"the demonstrator {profile.name!r} is {profile.height_m} m tall but the scene "
                                    "holds a "
                                    f"{scene.body_height_m} m body: make the scene with DemoScene(body_height_m=...)")
        self.profile = profile
        self.scene = scene
        self.sim = scene.sim
        sim = self.sim
        self.ik = ArmIK(np.array(scene.config.demonstrator_position), human_urdf(profile.height_m), profile.trunk_use)
        joints = {info.name: info for info in sim.joints("human")}
        names = RECORDED_JOINTS
        self._joint_indices = [joints[name].index for name in names]
        self._forces = np.array([joints[name].max_force for name in names])
        self._max_velocities = np.array([joints[name].max_velocity for name in names])
        self._marker_links = [sim.link_index("human", link) for link in MARKER_LINKS]
        self._hand_links = {link: sim.link_index("human", link) for link in HAND_LINKS}
        self._substeps = int(round(1.0 / (FPS * sim.timestep)))
        if abs(self._substeps * sim.timestep * FPS - 1.0) > 1e-9:
            raise InvalidInputError(f"the physics timestep {sim.timestep} s must divide the frame period 1/{FPS} s")
        self._table_edge = float(sim.aabb("table")[0][0])
        self._rest = np.array([REST_POSTURE[name] for name in BODY_JOINTS])
        self._work_posture = WORK_POSTURE | {
            "r_shoulder_abduction": WORK_POSTURE["r_shoulder_abduction"] + profile.elbow_lift_rad}
        self._work_arm = np.array([self._work_posture[name] for name in BODY_JOINTS[3:]])
        self._profile_work_arm = self._work_arm.copy()
        self._lift_arm = np.array([LIFT_POSTURE[name] for name in BODY_JOINTS[3:]])
        self._phase_codes = {name: code for code, name in enumerate(PHASE_NAMES)}
        self.ik.reset(REST_POSTURE)
        self._rest_sites = {site: self.ik.site_pose(site) for site in SITE_OFFSETS}
        # per-episode state, set by perform()
        self._grasp: int | None = None
        self._grasped = False
        self._q = np.concatenate([self._rest, FINGERS_REST])
        self._site = "palm_site"
        self._target = self._rest_sites[self._site]
        self._tape = _Tape()
        self._rng = np.random.default_rng(0)
        self._speed = 1.0

    # ------------------------------------------------------------------ episode
    def perform(self, task: DemoTask, rng: np.random.Generator) -> DemoRecording:
        """Run one approach -> manipulation -> remove episode and return its recording."""
        self.scene.reset(np.array(task.object_xy), task.object_yaw)
        self._q = np.concatenate([self._rest, FINGERS_REST])
        self.sim.reset_joints("human", self._joint_indices, self._q)
        self.ik.reset(REST_POSTURE)
        self._grasp, self._grasped = None, False
        self._tape = _Tape()
        self._rng = rng
        self._speed = float(rng.uniform(*EPISODE_SPEED_RANGE)) / self.profile.speed
        self._vary_proximal(rng)
        start = self.scene.object_pose()
        self._record("approach")
        away = np.zeros(3)
        if task.action == "push":
            away = self._push(task, start)
        elif task.action == "approach":
            self._reach("grasp_site", *self._grasp_pose(start, 0.0, np.zeros(3), forward=True), FINGERS_OPEN)
            self._hold(SETTLE_S, "approach")
        else:
            self._grasp_and_carry(task, start)
        self._remove(away)
        if self._grasp is not None:  # never left attached across episodes
            self.sim.detach(self._grasp)
            self._grasp = None
        tape = self._tape
        if tape.table_contacts:
            logger.warning("%s: the hand touched the table in %d frames", task, tape.table_contacts)
        return DemoRecording(
            H=np.array(tape.H),
            O=np.array(tape.O),
            Q=np.array(tape.Q),
            labels=np.array(tape.labels, dtype=np.int16),
            object_target=task.target_pose(start),
            hand_rest=self._rest_sites["palm_site"][0],
            grasped=self._grasped,
            table_contact_frames=tape.table_contacts,
        )

    def _vary_proximal(self, rng: np.random.Generator) -> None:
        """This episode's trunk target and elbow height, ``profile.proximal_sd_rad`` off the profile's
        (no draw at all when it is 0, so the reference demonstrator's episodes stay as they were)."""
        sd = self.profile.proximal_sd_rad
        if sd == 0.0:
            return
        lean, twist, elbow = rng.normal(0.0, sd, 3)
        self.ik.set_trunk_target({"lumbar_flexion": float(lean), "lumbar_rotation": float(twist)})
        self._work_arm = self._profile_work_arm.copy()
        self._work_arm[BODY_JOINTS[3:].index("r_shoulder_abduction")] += float(elbow)

    # ------------------------------------------------------------------ phases
    def _push(self, task: DemoTask, start: np.ndarray) -> np.ndarray:
        """Palm (or back of the hand) beside the block, then push it ``distance`` along the direction;
        returns the direction the hand leaves in.

        One minimum-jerk push path covers the measured hand-block gap plus ``distance``. Labels: its
        first ``gap`` metres (the hand closing on the still block) are approach, the rest is the push;
        the hand easing off the block afterwards is remove."""
        rng = self._rng
        u = np.array([*DIRECTIONS[task.direction], 0.0])
        candidates = [_SIDE_PUSH] if task.direction in ("left", "right") else _FRONT_PUSHES
        target, rotation = min((self._push_start(start, u, *c) for c in candidates), key=self._discomfort)
        self.ik.reset(REST_POSTURE)
        tangent = np.array([-u[1], u[0], 0.0])
        target += tangent * np.clip(rng.normal(0.0, 0.005), -0.01, 0.01)  # where on the face: ~1 cm
        target[2] += abs(rng.normal(0.0, 0.002))
        self._reach("palm_site", target, rotation, FINGERS_PUSH, descend_from=-u)
        # push by the measured gap plus the distance: the block travels ``distance``
        gap = self.sim.closest_distance("human", "object", max_distance=0.1)
        if not 0.0 <= gap <= 0.05:
            logger.warning("push: the hand ended its approach %.3f m from the block, not ~%.3f m", gap, PUSH_GAP)
            gap = PUSH_GAP
        travel = gap + task.distance + rng.normal(0.0, 0.001)
        n = self._frames(PUSH_S + PUSH_S_PER_M * travel)
        progress = travel * minimum_jerk(np.arange(1, n + 1) / n)
        path = target + u * progress[:, None]
        touch = int(np.searchsorted(progress, gap, side="right"))  # the first frame past the gap
        for label, part in (("approach", path[:touch]), (task.phase, path[touch:])):
            if len(part):
                self._run(self._segment(label, "palm_site", part, [rotation] * len(part), FINGERS_PUSH))
        n = self._frames(0.15)
        path = path[-1] - u * (PUSH_RELAX * minimum_jerk(np.arange(1, n + 1) / n))[:, None]
        self._run(self._segment("remove", "palm_site", path, [rotation] * n, FINGERS_PUSH))
        return -u

    def _push_start(
        self, start: np.ndarray, u: np.ndarray, fingers: tuple, dorsal: tuple, contact: tuple
    ) -> tuple[np.ndarray, Rotation]:
        """Palm-site position and hand orientation before pushing the block (pose ``start``) along
        ``u``: the pushing face :data:`PUSH_GAP` from the block's, the ``contact`` point (palm frame) in
        line with the face's centre, the hand's lowest point :data:`HAND_CLEARANCE` above the table."""
        rotation = hand_rotation(fingers, dorsal)
        offsets = rotation.apply(HAND_HULL - SITE_OFFSETS["palm_site"])
        contact_offset = rotation.apply(np.array(contact) - SITE_OFFSETS["palm_site"])
        tangent = np.array([-u[1], u[0], 0.0])
        relative_yaw = Rotation.from_rotvec(start[3:]).as_euler("zyx")[0] - np.arctan2(u[1], u[0])
        extent = self.scene.config.object_size / 2.0 * (abs(np.cos(relative_yaw)) + abs(np.sin(relative_yaw)))
        target = start[:3] - u * (extent + (offsets @ u).max() + PUSH_GAP) - tangent * (contact_offset @ tangent)
        target[2] = HAND_CLEARANCE - offsets[:, 2].min()
        return target, rotation

    def _discomfort(self, pose: tuple[np.ndarray, Rotation], site: str = "palm_site") -> float:
        """How hard a static hand pose is to take from the working posture: IK residual (mm + degrees)
        plus torso use (3 per rad). Leaves the IK model wherever it got to."""
        position, rotation = pose
        self.ik.reset(self._work_posture)
        for _ in range(40):
            q = self.ik.solve(site, position, rotation, ORIENTATION_WEIGHT, self._work_arm, ARM_WEIGHT, FINGERS_PUSH)
        reached, turned = self.ik.site_pose(site)
        error = 1000.0 * np.linalg.norm(reached - position) + np.degrees((turned.inv() * rotation).magnitude())
        return float(error + 3.0 * np.abs(q[:3]).sum())

    def _grasp_and_carry(self, task: DemoTask, start: np.ndarray) -> None:
        """Pinch the block, then lift-carry-place it (move) or turn it about the vertical (rotate), release.

        Labels: the pinch (the block still) ends the approach; the carry or turn is the manipulation;
        holding still, the release and the fingers opening (the block still but for settling the 2 mm
        set-down clearance) begin the remove."""
        rng = self._rng
        turn = TURNS[task.direction] * task.angle if task.action == "rotate" else 0.0
        shift = task.distance * np.array([*DIRECTIONS[task.direction], 0.0]) if task.action == "move" else np.zeros(3)
        position, rotation = self._grasp_pose(start, turn, shift)
        self._reach("grasp_site", position, rotation, FINGERS_OPEN)
        self._fingers(FINGERS_OPEN, FINGERS_PINCH, PINCH_CLOSE_S, "approach", watch_grasp=True)
        pinch = self._q[-2:].copy()  # where the guarded close stopped
        if task.action == "move":
            end = position + np.array([*DIRECTIONS[task.direction], 0.0]) * task.distance
            end[:2] += np.clip(rng.normal(0.0, 0.001, 2), -0.002, 0.002)
            end[2] = position[2] + PLACE_CLEARANCE
            lift = np.array([0.0, 0.0, rng.uniform(*CARRY_LIFT_RANGE)])
            n = self._frames(CARRY_S + CARRY_S_PER_M * task.distance)
            path = minimum_jerk_curve([position, position + lift, end + lift, end], n)
            self._run(self._segment(task.phase, "grasp_site", path, [rotation] * n, pinch))
        else:  # rotate: raised 2 mm off the table, turned about the vertical through the block
            n = self._frames(TURN_S + TURN_S_PER_RAD * task.angle)
            tau = np.arange(1, n + 1) / n
            path = position + np.outer(minimum_jerk(4.0 * tau), [0.0, 0.0, PLACE_CLEARANCE])
            turns = Rotation.from_rotvec(np.outer(turn * minimum_jerk(tau), [0.0, 0.0, 1.0])) * rotation
            self._run(self._segment(task.phase, "grasp_site", path, list(turns), pinch))
        self._hold(LET_GO_S, "remove")
        if self._grasp is not None:
            self.sim.detach(self._grasp)
            self._grasp = None
        self._fingers(pinch, FINGERS_OPEN, PINCH_OPEN_S, "remove")
        self._hold(LET_GO_S, "remove")

    def _reach(
        self, site: str, target: np.ndarray, rotation: Rotation, fingers: np.ndarray,
        descend_from: np.ndarray = _STRAIGHT_DOWN,
    ) -> None:
        """Approach from rest: up out of the hanging pose, over the table edge, down onto ``target``
        (from above, offset 5 cm along ``descend_from``: a pushing hand comes down beside the block)."""
        start = self._rest_sites[site][0]
        first = np.array([start[0] + RISE_FORWARD, start[1] + RISE_SHARE_OF_Y * (target[1] - start[1]), RISE_HEIGHT])
        above = target + DESCEND_OFFSET * np.asarray(descend_from) + np.array([0.0, 0.0, ABOVE_TARGET])
        control = np.array([start, first, above, target])
        control[1:3] += np.clip(self._rng.normal(0.0, VIA_JITTER, (2, 3)), -VIA_JITTER_LIMIT, VIA_JITTER_LIMIT)

        def plan(control: np.ndarray) -> _Segment:
            n = self._frames(REACH_S + REACH_S_PER_M * bezier_length(control))
            tau = np.arange(1, n + 1) / n
            blend = minimum_jerk(tau)[:, None]
            segment = _Segment(
                "approach", site, minimum_jerk_curve(control, n), [rotation] * n,
                FINGERS_REST + (fingers - FINGERS_REST) * blend, np.zeros(n),
                self._posture_path(tau, reverse=False), np.full(n, ARM_WEIGHT),
            )
            # the hand turns smoothly from the orientation it takes when free to the one it needs
            natural = self._free_orientations(segment)
            turn = (natural.inv() * rotation).as_rotvec() * minimum_jerk((tau - 0.2) / 0.6)[:, None]
            segment.rotations = list(natural * Rotation.from_rotvec(turn))
            segment.orientation_weights = np.full(n, ORIENTATION_WEIGHT)
            return segment

        self._run_clear(plan, control, body_side=1)

    def _remove(self, away: np.ndarray) -> None:
        """Back to the hanging rest pose (end point jittered ~1 cm), the posture pulled back to rest;
        the hand first rises and leaves along ``away`` (a unit vector; zero after a grasp)."""
        site, (position, rotation) = self._site, self._target
        end = self._rest_sites[site][0] + np.clip(self._rng.normal(0.0, REST_JITTER, 3), -REST_JITTER_LIMIT,
                                                  REST_JITTER_LIMIT)
        first = position + LEAVE_AWAY * away + np.array([0.0, 0.0, LEAVE_HEIGHT])
        second = np.array([end[0] + RISE_FORWARD, end[1] + RISE_SHARE_OF_Y * (position[1] - end[1]), RISE_HEIGHT])
        control = np.array([position, first, second, end])
        control[1:3] += np.clip(self._rng.normal(0.0, VIA_JITTER, (2, 3)), -VIA_JITTER_LIMIT, VIA_JITTER_LIMIT)
        fingers_now = self._q[-2:]

        def plan(control: np.ndarray) -> _Segment:
            n = self._frames(REACH_S + REACH_S_PER_M * bezier_length(control))
            tau = np.arange(1, n + 1) / n
            blend = minimum_jerk(tau)[:, None]
            return _Segment(
                "remove", site, minimum_jerk_curve(control, n), [rotation] * n,
                fingers_now + (FINGERS_REST - fingers_now) * blend,
                ORIENTATION_WEIGHT * (1.0 - minimum_jerk((tau - 0.05) / 0.3)),  # let go of it on the way
                self._posture_path(tau, reverse=True),
                ARM_WEIGHT + (ARM_WEIGHT_AT_REST - ARM_WEIGHT) * minimum_jerk((tau - 0.6) / 0.4),
            )

        self._run_clear(plan, control, body_side=2)
        self._hold(REST_HOLD_S, "remove")

    # ------------------------------------------------------------------ building blocks
    def _grasp_pose(
        self, start: np.ndarray, turn: float, shift: np.ndarray, forward: bool = False
    ) -> tuple[np.ndarray, Rotation]:
        """Pinch pose over the block: palm down, fingers along one of the block's face normals, the one
        that is most comfortable both at the grasp and after turning the hand by ``turn`` (rad) and
        moving it by ``shift`` (m)."""
        block_yaw = Rotation.from_rotvec(start[3:]).as_euler("zyx")[0]
        position = start[:3] + [0.0, 0.0, GRASP_HEIGHT]
        turned = Rotation.from_euler("z", turn)

        def cost(yaw: float) -> float:
            rotation = hand_rotation([np.cos(yaw), np.sin(yaw), 0.0], [0.0, 0.0, 1.0])
            return self._discomfort((position, rotation), "grasp_site") + self._discomfort(
                (position + shift, turned * rotation), "grasp_site"
            )

        candidates = [block_yaw + k * np.pi / 2.0 for k in (-1, 0, 1, 2)]
        if forward:  # the fingers along the face normal that points most away from the body
            yaw = min(candidates, key=lambda y: abs(np.angle(np.exp(1j * y))))
        else:
            yaw = min(candidates, key=cost)
        self.ik.reset(REST_POSTURE)
        rotation = hand_rotation([np.cos(yaw), np.sin(yaw), 0.0], [0.0, 0.0, 1.0])
        return position + np.clip(self._rng.normal(0.0, 0.001, 3), -0.002, 0.002), rotation

    def _fingers(
        self, begin: np.ndarray, end: np.ndarray, duration: float, label: str, watch_grasp: bool = False
    ) -> None:
        """Close or open the fingers, the hand held where it is."""
        n = self._frames(duration)
        position, rotation = self._target
        fingers = begin + (end - begin) * minimum_jerk(np.arange(1, n + 1) / n)[:, None]
        positions = np.repeat(position[None], n, 0)
        self._run(self._segment(label, self._site, positions, [rotation] * n, fingers), watch_grasp)
        if watch_grasp and self._grasp is None:
            logger.warning("the fingers closed without grasping the block")

    def _hold(self, duration: float, label: str) -> None:
        """Keep the current joint targets (the arm at rest, or the hand still on the block)."""
        n = self._frames(duration)
        position, rotation = self._target
        segment = self._segment(label, self._site, np.repeat(position[None], n, 0), [rotation] * n, self._q[-2:])
        self._execute(segment, np.repeat(self._q[None, : len(BODY_JOINTS)], n, 0))

    def _posture_path(self, tau: np.ndarray, reverse: bool) -> np.ndarray:
        """Arm posture targets (n, 7) at normalised times ``tau`` of a reach: rest -> lift (first 40 %)
        -> work (to 80 %); ``reverse`` for the way back (work -> lift -> rest)."""
        t = 1.0 - tau if reverse else tau
        up = minimum_jerk(t / 0.4)[:, None]
        out = minimum_jerk((t - 0.4) / 0.4)[:, None]
        rest = self._rest[3:]
        return rest + (self._lift_arm - rest) * up + (self._work_arm - self._lift_arm) * out

    def _segment(
        self, label: str, site: str, positions: np.ndarray, rotations: list[Rotation], fingers: np.ndarray
    ) -> _Segment:
        """A manipulation segment: strong orientation, the working posture as regulariser."""
        n = len(positions)
        return _Segment(
            label, site, positions, rotations, np.broadcast_to(fingers, (n, 2)),
            np.full(n, ORIENTATION_WEIGHT), np.repeat(self._work_arm[None], n, 0), np.full(n, ARM_WEIGHT),
        )

    def _free_orientations(self, segment: _Segment) -> Rotation:
        """Palm orientations (n) along ``segment`` when the IK leaves them free (the model is restored)."""
        start, rotations = self.ik.q, []
        for k in range(len(segment.positions)):
            self.ik.solve(segment.site, segment.positions[k], segment.rotations[k], 0.0,
                          segment.postures[k], segment.arm_weights[k], segment.fingers[k])
            rotations.append(self.ik.site_pose(segment.site)[1])
        self.ik.restore(start)
        return Rotation.concatenate(rotations)

    def _solve(self, segment: _Segment, check_clear: bool = False) -> tuple[np.ndarray, bool]:
        """IK over a segment: joint angles (n, 10), and whether the hand stays clear of the block and
        (between 20 % and 80 % of the time: at its ends a reach is at rest or on its target) of the
        table's edge; checked on request. The planned end poses keep > BLOCK_MARGIN from the block."""
        n, clear, q = len(segment.positions), True, []
        low, high = self.sim.aabb("object")
        low, high = low - BLOCK_MARGIN, high + BLOCK_MARGIN
        for k in range(n):
            q.append(self.ik.solve(
                segment.site, segment.positions[k], segment.rotations[k], segment.orientation_weights[k],
                segment.postures[k], segment.arm_weights[k], segment.fingers[k],
            ))
            if check_clear and clear:
                points = self.ik.hand_points()
                x, z = points[:, 0], points[:, 2]
                at_edge = (x > self._table_edge - TABLE_MARGIN) & (z < TABLE_MARGIN) & (z > -0.03 - TABLE_MARGIN)
                in_block = np.all((points > low) & (points < high), axis=1)
                clear = not np.any(in_block | (at_edge & (0.2 * n < k < 0.8 * n)))
        return np.array(q), clear

    def _run_clear(self, plan, control: np.ndarray, body_side: int) -> None:
        """Plan a reach with :meth:`_solve`; while the hand would meet the table's edge or the block,
        raise the via points (and draw the one by the body, ``control[body_side]``, back) and plan
        again; then run it."""
        start = self.ik.q
        segment = plan(control)
        q, clear = self._solve(segment, check_clear=True)
        for _ in range(10):
            if clear:
                break
            control = control.copy()
            control[1:3, 2] += 0.03
            control[body_side, 0] -= 0.02
            self.ik.restore(start)
            segment = plan(control)
            q, clear = self._solve(segment, check_clear=True)
        else:
            logger.warning("no reach path clear of the table and block found; using the last one")
        self._execute(segment, q)

    def _run(self, segment: _Segment, watch_grasp: bool = False) -> None:
        """Solve a segment's IK and execute it."""
        self._execute(segment, self._solve(segment)[0], watch_grasp)

    def _execute(self, segment: _Segment, q: np.ndarray, watch_grasp: bool = False) -> None:
        """Position control along planned joint angles (interpolated over the physics sub-steps),
        recording each frame; with ``watch_grasp``, a guarded close: each finger stops where it comes
        within :data:`GRASP_DISTANCE` of the block, and the block is attached once both have."""
        self._site = segment.site
        stopped: dict[int, float] = {}  # finger (0 index, 1 thumb) -> angle it stopped at
        for k in range(len(q)):
            fingers = segment.fingers[k].copy()
            for finger, angle in stopped.items():
                fingers[finger] = angle
            target = np.concatenate([q[k], fingers])
            for j in range(1, self._substeps + 1):
                self.sim.set_joint_targets(
                    "human", self._joint_indices, self._q + (target - self._q) * j / self._substeps,
                    self._forces, self._max_velocities, POSITION_GAIN, VELOCITY_GAIN,
                )
                self.sim.step()
            self._q = target
            self._target = (segment.positions[k], segment.rotations[k])
            if watch_grasp and self._grasp is None:
                self._stop_touching_fingers(stopped)
                if len(stopped) == 2:
                    self._q[-2:] = [stopped[0], stopped[1]]
                    self._grasp = self.sim.attach("human", self._hand_links["r_palm"], "object")
                    self._grasped = True
            self._record(segment.label)

    def _stop_touching_fingers(self, stopped: dict[int, float]) -> None:
        """Add to ``stopped`` each finger now within :data:`GRASP_DISTANCE` of the block, at its angle."""
        angles = self.sim.joint_states("human", self._joint_indices[-2:])[0]
        for finger, link in enumerate(("r_index", "r_thumb")):
            if finger not in stopped:
                gap = self.sim.closest_distance("human", "object", self._hand_links[link], GRASP_DISTANCE + 0.01)
                if gap < GRASP_DISTANCE:
                    stopped[finger] = float(angles[finger])

    def _record(self, label: str) -> None:
        tape = self._tape
        tape.H.append(self.sim.link_poses("human", self._marker_links)[0])
        tape.O.append(self.scene.object_pose())
        tape.Q.append(self.sim.joint_states("human", self._joint_indices)[0])
        tape.labels.append(self._phase_codes[label])
        tape.table_contacts += bool(self.sim.contacts("human", "table"))

    def _frames(self, duration: float) -> int:
        """Frames of a segment of nominal ``duration`` s at this episode's speed (+-5 % per segment)."""
        jitter = 1.0 + 0.05 * (2.0 * self._rng.random() - 1.0)
        return max(2, int(round(duration * self._speed * jitter * FPS)))


