"""The HOAP-3-style humanoid (``urdf/hoap3.urdf``) inside a :class:`~hoap_actions.envs.sim.Sim`.

:class:`Robot` loads the model, stands it on the floor, and drives its joints by position control with
the HOAP-3 torque limits and joint speeds clamped at the URDF's velocity limits (5 rad/s). Two models
(:data:`ROBOT_MODELS`): ``"full"``, free-standing on 28 motorised joints, and ``"fixed_legs"``, the same
robot bolted at the pelvis with its legs welded in the standing posture (16 motors; a PegInsert
physics step costs a quarter as much, with the env's 10 solver iterations for it). Joint vectors are
``(28,)`` float arrays in :attr:`Robot.joint_names` order (radians) for both, so observations and
policies do not depend on the model; quaternions are ``(x, y, z, w)``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from hoap_actions.envs import world
from hoap_actions.envs.motors import MotorGroup
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError
from hoap_actions.urdf import LEG_JOINTS, STANDING_LEGS, standing_leg_angle

ROBOT_MODELS = {"full": "hoap3.urdf", "fixed_legs": "hoap3_fixed_legs.urdf"}
"""Robot model name -> URDF: the free-standing humanoid, or the one whose legs are welded to a fixed pelvis."""
SIDES = ("right", "left")
ARM_JOINTS = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_yaw", "gripper")
FRAMES = ("r_tcp", "l_tcp", "r_sole", "l_sole", "camera")
SOLE_HALF = (0.054, 0.0365)  # m, half length and half width of a 108 x 73 mm sole

GRIPPER_OPEN = 0.0  # rad: 36 mm between thumb and palm at the tcp
GRIPPER_CLOSED = np.radians(60.0)  # rad, the joint's upper limit: the thumb tip reaches the palm
"""Positive gripper angles close either hand; a 15 mm peg is met at 45 deg, so commanding
``GRIPPER_CLOSED`` on a peg squeezes it with the full 0.36 N m (about 9.5 N at the tcp)."""

FALL_HEIGHT = 0.20  # m, pelvis (waist axis) above the floor below which the robot has fallen (0.30 standing)
FALL_TILT = 0.6  # rad, pelvis tilt from vertical beyond which the robot has fallen

# Standing, knees bent 0.4 rad (hips stay above the ankles, soles flat, pelvis upright); upper arms
# 15 deg forward of hanging, forearms horizontal about 6 cm above the table top, hands open.
HOME = STANDING_LEGS | {
    "shoulder_pitch": np.radians(75.0),
    "elbow": np.radians(-75.0),
    "gripper": GRIPPER_OPEN,
}


def up_z(quats: np.ndarray) -> np.ndarray:
    """World z of the frames' z axes, for quaternions ``(..., 4)`` (x, y, z, w): 1 - 2 (x^2 + y^2).

    The closed form costs a microsecond where scipy's ``Rotation`` costs ~30 us, and the balance
    guard reads the soles' tilt at every 240 Hz tick."""
    q = np.asarray(quats, dtype=float)
    return 1.0 - 2.0 * (q[..., 0] ** 2 + q[..., 1] ** 2)


class Robot:
    """The humanoid as body ``name`` of ``sim``, standing with its ankles' midpoint at ``feet_xy``.

    With ``model="full"`` the base floats free (nothing welds it); with ``model="fixed_legs"`` the pelvis
    is fixed where the standing robot's would be and the 12 leg joints are welded at
    :data:`~hoap_actions.urdf.STANDING_LEGS`: they stay in the joint vectors at those angles (speed 0),
    their range is that one angle, and targets for them are held there. Friction (1.0, with anchors
    against creep) on the soles, palms and thumbs comes from the URDF. Self-collision is off: the home
    posture and table-top reaches keep the limbs apart, and whole-body IK (placo) can avoid
    self-contact where it matters.

    Parameters
    ----------
    sim
        the simulator that owns the body.
    name
        body name in ``sim``.
    model
        ``"full"`` or ``"fixed_legs"`` (:data:`ROBOT_MODELS`).
    feet_xy
        (x, y) of the midpoint between the ankles on the floor (m); default
        :data:`~hoap_actions.envs.world.ROBOT_FEET_XY`, or
        :data:`~hoap_actions.envs.world.FIXED_LEGS_FEET_XY` for the welded-legs model.
    yaw
        heading about +z (rad); 0 faces +x.
    floor_z
        height of the floor plane (m); the floor body itself belongs to the scene.
    position_gain, velocity_gain
        PyBullet position-control gains, in [0, 1].
    """

    def __init__(
        self,
        sim: Sim,
        name: str = "robot",
        model: str = "full",
        feet_xy: tuple[float, float] | None = None,
        yaw: float = 0.0,
        floor_z: float = world.FLOOR_Z,
        position_gain: float = 0.3,
        velocity_gain: float = 1.0,
    ) -> None:
        for label, gain in (("position_gain", position_gain), ("velocity_gain", velocity_gain)):
            if not 0.0 <= gain <= 1.0:
                raise InvalidInputError(f"{label}={gain} is outside [0, 1], the range of PyBullet's position gains")
        if model not in ROBOT_MODELS:
            raise InvalidInputError(f"robot model {model!r} is not known; accepted: {list(ROBOT_MODELS)}")
        placement = np.array([*(feet_xy if feet_xy is not None else (0.0, 0.0)), yaw, floor_z], dtype=float)
        if placement.shape != (4,) or not np.all(np.isfinite(placement)):
            raise InvalidInputError(f"feet_xy={feet_xy!r}, yaw={yaw!r}, floor_z={floor_z!r}: expected finite numbers, "
                                    "feet_xy as (x, y) in m")
        self.sim, self.name, self.model = sim, name, model
        self.fixed_legs = model == "fixed_legs"
        if feet_xy is None:
            feet_xy = world.FIXED_LEGS_FEET_XY if self.fixed_legs else world.ROBOT_FEET_XY
        self.feet_xy = (float(feet_xy[0]), float(feet_xy[1]))
        self.yaw, self.floor_z = float(yaw), float(floor_z)
        self.position_gain, self.velocity_gain = float(position_gain), float(velocity_gain)
        sim.load_urdf(name, ROBOT_MODELS[model], fixed_base=self.fixed_legs, merge_fixed_links=self.fixed_legs)
        motors = {j.name: j for j in sim.joints(name)}
        self.joint_names: tuple[str, ...] = tuple(n for n in sim.joint_names(name) if n in motors or n in LEG_JOINTS)
        self._position = {n: i for i, n in enumerate(self.joint_names)}
        self._motorised = np.array([i for i, n in enumerate(self.joint_names) if n in motors])
        """Positions in the joint vector of the joints with a motor (all 28, or 16 with welded legs)."""
        self._indices = [motors[self.joint_names[i]].index for i in self._motorised]
        # joint-vector position -> PyBullet joint
        self._motor_index = dict(zip(self._motorised.tolist(), self._indices))
        welds = {n: standing_leg_angle(n) for n in self.joint_names if n not in motors}
        self.lower = np.array([motors[n].lower if n in motors else welds[n] for n in self.joint_names])
        self.upper = np.array([motors[n].upper if n in motors else welds[n] for n in self.joint_names])
        self.max_velocity = np.array([motors[n].max_velocity if n in motors else 0.0 for n in self.joint_names])
        self.max_force = np.array([motors[n].max_force if n in motors else 0.0 for n in self.joint_names])
        for array in (self.lower, self.upper, self.max_velocity, self.max_force):
            array.flags.writeable = False
        # A servo never turns faster than its top speed, whatever pushes the limb; the motors'
        # maxVelocity alone left contacts and the other joints whipping a joint to 23 rad/s.
        sim.set_joint_velocity_limits(name, self._indices, self.max_velocity[self._motorised])
        self._motors = MotorGroup.of(name, self._indices, self.max_force[self._motorised],
                                     self.max_velocity[self._motorised], self.position_gain, self.velocity_gain)
        self._links = {f: sim.link_index(name, f) for f in FRAMES}
        self._feet = [sim.link_index(name, f"{p}_foot") for p in "rl"]
        self._soles = [self._links["r_sole"], self._links["l_sole"]]
        home = np.zeros(len(self.joint_names))
        for n, value in HOME.items():
            home[[self._position[f"{p}_{n}"] for p in "rl"]] = value
        home = np.clip(home, self.lower, self.upper)  # welded legs: their weld angles
        home.flags.writeable = False
        self.home_posture = home
        self._targets = home.copy()
        self._sole_corners = np.array([[x * SOLE_HALF[0], y * SOLE_HALF[1], 0.0] for x in (1, -1) for y in (1, -1)])
        self.reset()

    # ------------------------------------------------------------------ structure
    def arm_joints(self, side: str) -> tuple[int, ...]:
        """Positions in the joint vector of one arm's 6 joints, shoulder pitch to gripper."""
        p = self._side(side)
        return tuple(self._position[f"{p}_{n}"] for n in ARM_JOINTS)

    def joint_index(self, joint_name: str) -> int:
        """Position of ``joint_name`` in the joint vector."""
        try:
            return self._position[joint_name]
        except KeyError:
            raise InvalidInputError(f"no joint named {joint_name!r}; joints: {list(self.joint_names)}") from None

    @property
    def targets(self) -> np.ndarray:
        """The joint targets last commanded (28,), after clipping to the joint ranges."""
        return self._targets.copy()

    # ------------------------------------------------------------------ commands
    def reset(self, q: np.ndarray | None = None) -> None:
        """Pose the joints at ``q`` (default :attr:`home_posture`), at rest, soles on the floor.

        The base is turned so that the mean sole orientation is level at heading :attr:`yaw`, moved
        so the ankles' midpoint is over :attr:`feet_xy` and the lowest sole corner touches the
        floor; the motors then hold ``q``. Out-of-range values are clipped as in :meth:`set_targets`.
        """
        q = self.home_posture if q is None else self._checked(q, "q")
        self.sim.reset_joints(self.name, self._indices, q[self._motorised])
        self.sim.set_base_pose(self.name, np.zeros(3))  # base (centre-of-mass) frame at the origin
        positions, quats = self.sim.link_poses(self.name, self._soles + self._feet)
        base_rot = Rotation.from_euler("z", self.yaw) * Rotation.from_quat(quats[:2]).mean().inv()
        lowest = base_rot.apply(self._corners(positions[:2], quats[:2]))[:, 2].min()
        ankles = base_rot.apply(positions[2:].mean(axis=0))
        offset = np.array([self.feet_xy[0] - ankles[0], self.feet_xy[1] - ankles[1], self.floor_z - lowest])
        self.sim.set_base_pose(self.name, offset, base_rot.as_quat())
        self.set_targets(q)

    def set_targets(self, q: np.ndarray) -> None:
        """Position targets for all 28 joints, driven with the HOAP-3 peak torques at up to 5 rad/s
        (welded legs hold their angles whatever is asked of them).

        Raises :class:`InvalidInputError` for a wrong shape or NaN/inf. Targets beyond a joint's
        range are clipped to it, as a servo's own limits would (MuJoCo's ``ctrlrange`` behaves the
        same); :attr:`targets` shows what was sent.
        """
        self._targets = self._checked(q, "q")
        self.sim.drive(self._motors, self._targets[self._motorised])

    def set_gripper(self, side: str, closure: float) -> None:
        """Open (0) or close (1) one hand; 1 squeezes a held peg with the full servo torque.

        ``closure`` maps linearly from :data:`GRIPPER_OPEN` to :data:`GRIPPER_CLOSED` and is clipped
        to [0, 1]; the other joints keep their targets.
        """
        closure = float(closure)
        if not np.isfinite(closure):
            raise InvalidInputError(f"closure={closure} must be a finite number in [0, 1] (0 open, 1 closed)")
        k = self._position[f"{self._side(side)}_gripper"]
        self._targets[k] = GRIPPER_OPEN + min(max(closure, 0.0), 1.0) * (GRIPPER_CLOSED - GRIPPER_OPEN)
        self.sim.set_joint_targets(
            self.name, [self._motor_index[k]], self._targets[k : k + 1], self.max_force[k : k + 1],
            self.max_velocity[k : k + 1], self.position_gain, self.velocity_gain,
        )

    # ------------------------------------------------------------------ state
    def joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint angles (28,), rad, and speeds (28,), rad/s (0 for welded joints), from one read."""
        positions, velocities = self.sim.joint_states(self.name, self._indices)
        q = self.lower.copy()  # the welded joints' angles; the motorised ones are overwritten
        q[self._motorised] = positions
        qd = np.zeros(len(self.joint_names))
        qd[self._motorised] = velocities
        return q, qd

    def joint_positions(self) -> np.ndarray:
        """Joint angles (28,), rad."""
        return self.joint_state()[0]

    def joint_velocities(self) -> np.ndarray:
        """Joint speeds (28,), rad/s (0 for welded joints)."""
        return self.joint_state()[1]

    def base_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """World position (3,) and quaternion (x, y, z, w) of the pelvis frame (on the waist-pitch axis)."""
        return self.sim.link_pose(self.name, -1)

    def frame_pose(self, frame: str) -> tuple[np.ndarray, np.ndarray]:
        """World position (3,) and quaternion (x, y, z, w) of a link frame such as ``"r_tcp"``.

        Named frames: ``r_tcp``/``l_tcp`` (grasp point: x along the forearm, z along a held peg's
        axis), ``r_sole``/``l_sole`` (sole centre), ``camera`` (between the eyes, looking along +x);
        any other link name of the URDF works too.
        """
        if frame not in self._links:
            self._links[frame] = self.sim.link_index(self.name, frame)
        return self.sim.link_pose(self.name, self._links[frame])

    def com(self) -> np.ndarray:
        """World centre of mass (3,), m."""
        return self.sim.mass_properties(self.name)[1]

    def support_polygon(self) -> np.ndarray:
        """Convex hull of both soles' corners on the floor, ``(K, 2)`` xy in clockwise order."""
        xy = self._corners(*self.sim.link_poses(self.name, self._soles))[:, :2]
        return xy[ConvexHull(xy).vertices[::-1]]  # scipy lists 2-D hulls counter-clockwise

    def sole_tilt(self) -> float:
        """The larger of the two soles' tilts from level (rad): above ~0 a foot rocks on an edge.
        Read every control tick, so from the quaternions directly (:func:`up_z`)."""
        _, quats = self.sim.link_poses(self.name, self._soles)
        return float(np.arccos(np.clip(up_z(quats).min(), -1.0, 1.0)))

    def has_fallen(self) -> bool:
        """True once the pelvis is lower than :data:`FALL_HEIGHT` above the floor or tilted past :data:`FALL_TILT`."""
        if self.fixed_legs:  # the pelvis is welded where reset put it, standing
            return False
        position, quat = self.base_pose()
        return bool(position[2] - self.floor_z < FALL_HEIGHT or up_z(quat) < np.cos(FALL_TILT))

    # ------------------------------------------------------------------ helpers
    def _corners(self, positions: np.ndarray, quats: np.ndarray) -> np.ndarray:
        """The 8 sole corners (8, 3) from the two sole frames' positions and quaternions."""
        return np.concatenate([p + Rotation.from_quat(q).apply(self._sole_corners) for p, q in zip(positions, quats)])

    def _checked(self, q: np.ndarray, label: str) -> np.ndarray:
        array = np.asarray(q, dtype=np.float64)
        if array.shape != self.lower.shape:
            raise InvalidInputError(
                f"{label} has shape {array.shape}; expected {self.lower.shape}: one angle per joint, joint_names order"
            )
        # a dot product is finite for finite angles (unless one is beyond 1e154: then check each)
        if not math.isfinite(array @ array) and not np.isfinite(array).all():
            bad = [self.joint_names[i] for i in np.flatnonzero(~np.isfinite(array))]
            raise InvalidInputError(f"{label} has NaN or inf for {bad}; expected finite angles (rad)")
        return np.minimum(np.maximum(array, self.lower), self.upper)  # np.clip's, for finite angles, in fewer calls

    @staticmethod
    def _side(side: str) -> str:
        if side not in SIDES:
            raise InvalidInputError(f"side={side!r} is not accepted; use 'right' or 'left'")
        return side[0]
