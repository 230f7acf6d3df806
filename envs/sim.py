"""The one PyBullet facade: it owns a physics client and addresses bodies, joints and cameras by name.

Nothing else in the project calls ``pybullet``; every env owns one :class:`Sim`, so several envs in
one process are independent. Quaternions are ``(x, y, z, w)`` as PyBullet gives them.
"""

from __future__ import annotations

import functools
import logging
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hoap_actions.envs.c_output import c_output_silenced
from hoap_actions.envs.camera import Camera, CameraImage
from hoap_actions.envs.display import check_display
from hoap_actions.envs.motors import JointInfo, MotorGroup
from hoap_actions.envs.urdf_merge import merged_urdf_path
from hoap_actions.errors import DisplayUnavailableError, EnvClosedError, InvalidInputError
from hoap_actions.urdf import urdf_path

with c_output_silenced():  # PyBullet's C module prints its build time when imported
    import pybullet
from pybullet_utils.bullet_client import BulletClient

logger = logging.getLogger(__name__)

TIMESTEP = 1.0 / 240.0  # PyBullet's default rate; the controllers tick at this rate


class _Client(BulletClient):
    """A :class:`BulletClient` that builds each bound PyBullet function once: the stock one wraps the
    function anew on every call (an ``inspect`` check and a ``functools.partial``, ~3 us, some 50 times
    an env step). It connects without an options string: given one, even empty, PyBullet prints
    ``argv[0]=`` on stdout."""

    def __init__(self, connection_mode: int) -> None:
        self._shapes: dict = {}
        self._pid = os.getpid()
        self._client = pybullet.connect(connection_mode)

    def __getattr__(self, name: str):
        attribute = super().__getattr__(name)
        if name != "disconnect":
            self.__dict__[name] = attribute
        return attribute


@dataclass(frozen=True)
class FoldedLinks:
    """What merging fixed links folds away: every joint name of the model (in PyBullet's order),
    and each folded link's name, the kept link it now rides on, and its fixed offset from that link."""

    joint_names: tuple[str, ...]
    names: list[str]
    hosts: list[str]
    offsets: list[tuple]


@functools.lru_cache(maxsize=8)
def _folded_links(path: str, scale: float) -> FoldedLinks:
    """Read the model unmerged in a scratch physics server: the joint names and, for every link on a
    fixed joint, the nearest ancestor on a moving joint (or the base) and the pose between the two."""
    scratch = _Client(pybullet.DIRECT)
    try:
        body = scratch.loadURDF(path, useFixedBase=True, flags=pybullet.URDF_USE_INERTIA_FROM_FILE, globalScaling=scale)
        infos = [scratch.getJointInfo(body, j) for j in range(scratch.getNumJoints(body))]
        base_com = scratch.getBasePositionAndOrientation(body)
        inertial = scratch.getDynamicsInfo(body, -1)[3:5]  # the base's centre-of-mass frame in its URDF frame
        frames = {-1: scratch.multiplyTransforms(*base_com, *scratch.invertTransform(*inertial))}
        for j in range(len(infos)):
            state = scratch.getLinkState(body, j, computeForwardKinematics=True)
            frames[j] = (state[4], state[5])
        names, hosts, offsets = [], [], []
        link_name = {j: info[12].decode() for j, info in enumerate(infos)} | {-1: scratch.getBodyInfo(body)[0].decode()}
        for j, info in enumerate(infos):
            if info[2] != pybullet.JOINT_FIXED:
                continue
            host = info[16]  # parent link index
            while host != -1 and infos[host][2] == pybullet.JOINT_FIXED:
                host = infos[host][16]
            inverse = scratch.invertTransform(*frames[host])
            names.append(link_name[j])
            hosts.append(link_name[host])
            offsets.append(scratch.multiplyTransforms(*inverse, *frames[j]))
        return FoldedLinks(tuple(info[1].decode() for info in infos), names, hosts, offsets)
    finally:
        scratch.disconnect()
        scratch._client = -1  # so BulletClient.__del__ does not disconnect again


class Sim:
    """A PyBullet world: load bodies under names, step, save/restore state, render cameras.

    ``gui=True`` opens PyBullet's window (render_mode ``"human"``); otherwise the server is
    ``DIRECT`` and images come from the headless TinyRenderer. PyBullet allows one window per
    process; without a display, or for a second window, ``gui=True`` raises
    :class:`~hoap_actions.errors.DisplayUnavailableError` (PyBullet itself would end the process).
    """

    def __init__(self, gui: bool = False, timestep: float = TIMESTEP, shadows: bool = False) -> None:
        if gui:
            check_display()
        try:
            self._client = _Client(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        except pybullet.error as exc:  # e.g. a second GUI in this process
            raise DisplayUnavailableError(
                f"PyBullet could not open its {'GUI' if gui else 'DIRECT'} server: {exc}"
                + (" Close the other render_mode='human' environment first, or use render_mode='rgb_array'."
                   if gui else "")
            ) from None
        self.timestep = float(timestep)
        self.shadows = shadows
        self.gui = gui
        self._bodies: dict[str, int] = {}
        self._joints: dict[str, list[JointInfo]] = {}
        self._base_offsets: dict[int, tuple] = {}
        self._folded: dict[str, FoldedLinks] = {}
        self._folded_hosts: dict[str, list[int]] = {}  # per body, the link index each folded link rides on
        self._recipe: list[tuple[str, tuple, dict]] = []
        self._sent_max_velocity: dict[int, dict[int, float]] = {}  # per body and joint, the motor's speed cap
        self._sleepers: set[int] = set()  # bodies the engine may put to sleep (let_sleep)
        # calls that may have moved a body other than by stepping (teleports, rebuilds, restores): what a
        # cached pose of a fixed-base body is checked against
        self.placements = 0
        self.cameras: dict[str, Camera] = {}
        self._configure_world()
        p = self._client
        if gui:
            p.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
            p.configureDebugVisualizer(pybullet.COV_ENABLE_SHADOWS, int(shadows))

    def _configure_world(self) -> None:
        p = self._client
        p.setTimeStep(self.timestep)
        p.setGravity(0.0, 0.0, -9.81)
        # Same seed, same episode: make broad-phase pair order independent of insertion history.
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1)

    def _record(self, method: str, *args: object, **kwargs: object) -> None:
        """Note a call that builds the world, for :meth:`rebuild` to make again."""
        self._recipe.append((method, args, kwargs))

    def rebuild(self) -> None:
        """Make the world again from nothing: PyBullet's ``resetSimulation``, then every body, dynamics
        change, colour and velocity limit in the order first made (so with the same ids).

        This, not :meth:`restore_state`, is how an episode starts the same whatever ran before: a
        restored world kept state that no API shows (the broad phase's and the contact solver's), and
        an episode after a long one went differently from the same seed's in a fresh env (measured: a
        PHMM episode from step 193 on). PyBullet is deterministic from a fresh world; rebuilding takes
        about 12 ms. Constraints made with :meth:`attach` are not made again."""
        recipe, self._recipe = self._recipe, []
        self.placements += 1
        try:
            self._p.resetSimulation()
            self._bodies.clear()
            self._joints.clear()
            self._base_offsets.clear()
            self._folded.clear()
            self._folded_hosts.clear()
            self._sent_max_velocity.clear()
            self._sleepers.clear()
            self._configure_world()
            for method, args, kwargs in recipe:
                getattr(self, method)(*args, **kwargs)
        finally:
            # the whole recipe survives an interrupted rebuild (Ctrl-C), so the next one makes the same world
            self._recipe = recipe

    # ----------------------------------------------------------------- lifetime
    @property
    def closed(self) -> bool:
        return self._client is None

    @property
    def _p(self) -> BulletClient:
        if self._client is None:
            raise EnvClosedError("this simulator was closed; create a new environment (or Sim) to continue")
        return self._client

    def close(self) -> None:
        """Disconnect from the physics server; calling it again is harmless."""
        if self._client is not None:
            try:
                self._client.disconnect()
                self._client._client = -1  # so BulletClient.__del__ does not disconnect again at interpreter exit
            finally:
                self._client = None

    # ------------------------------------------------------------------- bodies
    def load_urdf(
        self,
        name: str,
        filename: str | Path,
        position: tuple[float, float, float] = (0.0, 0.0, 0.0),
        orientation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0),
        fixed_base: bool = False,
        self_collision: bool = False,
        scale: float = 1.0,
        implicit_cylinders: bool = False,
        merge_fixed_links: bool = False,
    ) -> int:
        """Load a URDF (a packaged name such as ``"hoap3.urdf"`` or a path) as body ``name``.

        ``implicit_cylinders=True`` collides URDF cylinders as exact cylinders; by default PyBullet
        uses a convex hull that its 1 mm collision margin inflates (a 15 mm peg acts 17 mm wide).
        ``merge_fixed_links=True`` folds every link on a fixed joint into its parent, shapes and mass
        (:mod:`.urdf_merge`: fewer links to step; welded legs cost half a robot's physics step);
        the folded links stay addressable by name (:meth:`link_index`, :meth:`link_poses`) and
        :meth:`joint_names` still lists every joint of the model.
        """
        if name in self._bodies:
            raise InvalidInputError(f"a body named {name!r} already exists; names in use: {sorted(self._bodies)}")
        self._record("load_urdf", name, filename, position, orientation, fixed_base, self_collision, scale,
                     implicit_cylinders, merge_fixed_links)
        path = Path(filename)
        if not path.is_file():
            path = urdf_path(str(filename))
        flags = pybullet.URDF_USE_INERTIA_FROM_FILE
        if self_collision:
            flags |= pybullet.URDF_USE_SELF_COLLISION | pybullet.URDF_USE_SELF_COLLISION_EXCLUDE_PARENT
        if implicit_cylinders:
            flags |= pybullet.URDF_USE_IMPLICIT_CYLINDER
        loaded = merged_urdf_path(str(path)) if merge_fixed_links else path
        body = self._p.loadURDF(
            str(loaded), position, orientation, useFixedBase=fixed_base, flags=flags, globalScaling=scale
        )
        self._bodies[name] = body
        self._joints[name] = self._read_joints(body)
        if merge_fixed_links:
            folded = _folded_links(str(path), float(scale))
            self._folded[name] = folded
            self._folded_hosts[name] = [self.link_index(name, host) for host in folded.hosts]
        return body

    def add_ground_plane(self, name: str = "ground", z: float = 0.0, lateral_friction: float = 1.0) -> int:
        """Add a static infinite plane ``z = const`` (collision only, invisible) as body ``name``.

        A floor for tests and bare setups that need no table scene.
        """
        if name in self._bodies:
            raise InvalidInputError(f"a body named {name!r} already exists; names in use: {sorted(self._bodies)}")
        self._record("add_ground_plane", name, z, lateral_friction)
        shape = self._p.createCollisionShape(pybullet.GEOM_PLANE)
        body = self._p.createMultiBody(0.0, shape, -1, [0.0, 0.0, float(z)])
        self._p.changeDynamics(body, -1, lateralFriction=float(lateral_friction))
        self._bodies[name] = body
        self._joints[name] = []
        return body

    def _read_joints(self, body: int) -> list[JointInfo]:
        infos = []
        for j in range(self._p.getNumJoints(body)):
            info = self._p.getJointInfo(body, j)
            if info[2] in (pybullet.JOINT_REVOLUTE, pybullet.JOINT_PRISMATIC):
                infos.append(
                    JointInfo(j, info[1].decode(), info[12].decode(), info[8], info[9], info[10], info[11])
                )
        return infos

    def body_id(self, name: str) -> int:
        try:
            return self._bodies[name]
        except KeyError:
            raise InvalidInputError(f"no body named {name!r}; bodies: {sorted(self._bodies)}") from None

    @property
    def body_names(self) -> list[str]:
        return list(self._bodies)

    def joints(self, name: str) -> list[JointInfo]:
        """The movable joints of body ``name``, in model order."""
        self.body_id(name)
        return self._joints[name]

    def joint_names(self, name: str) -> list[str]:
        """Every joint of body ``name`` in model order, fixed ones included (:meth:`joints` lists the movable ones)."""
        body = self.body_id(name)
        if name in self._folded:
            return list(self._folded[name].joint_names)
        return [self._p.getJointInfo(body, j)[1].decode() for j in range(self._p.getNumJoints(body))]

    def link_index(self, name: str, link_name: str) -> int:
        """Index of link ``link_name`` of body ``name`` (-1 is the base; below -1, a link folded into
        another by ``merge_fixed_links``, which only :meth:`link_poses` reads)."""
        body = self.body_id(name)
        if self._p.getBodyInfo(body)[0].decode() == link_name:
            return -1
        for j in range(self._p.getNumJoints(body)):
            if self._p.getJointInfo(body, j)[12].decode() == link_name:
                return j
        folded = self._folded.get(name)
        if folded is not None and link_name in folded.names:
            return -2 - folded.names.index(link_name)
        raise InvalidInputError(f"body {name!r} has no link named {link_name!r}")

    def _physical_link(self, name: str, link: int | None) -> int | None:
        """``link`` as PyBullet knows it; a folded link (below -1) has no body of its own to change, touch
        or hold (PyBullet would ignore it or fail), so it is refused with the link to use instead."""
        if link is not None and link < -1:
            folded = self._folded.get(name)
            if folded is None or -2 - link >= len(folded.names):
                raise InvalidInputError(f"body {name!r} has no link {link}; links are -1 (the base) and up")
            raise InvalidInputError(f"link {folded.names[-2 - link]!r} of body {name!r} is folded into "
                                    f"{folded.hosts[-2 - link]!r} (merge_fixed_links): use that link")
        return link

    # -------------------------------------------------------------------- state
    def base_pose(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (3,) and quaternion (x, y, z, w) of the body's base (its centre-of-mass frame)."""
        pos, quat = self._p.getBasePositionAndOrientation(self.body_id(name))
        return np.array(pos), np.array(quat)

    def base_velocity(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        lin, ang = self._p.getBaseVelocity(self.body_id(name))
        return np.array(lin), np.array(ang)

    def set_base_pose(self, name: str, position: np.ndarray, orientation: np.ndarray = (0.0, 0.0, 0.0, 1.0)) -> None:
        """Teleport a body's base (quaternion x, y, z, w) and zero its velocity; a sleeping body wakes
        (:meth:`let_sleep`), or it would hang where it was put."""
        body = self.body_id(name)
        self.placements += 1
        self._p.resetBasePositionAndOrientation(body, list(map(float, position)), list(map(float, orientation)))
        self._p.resetBaseVelocity(body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        if body in self._sleepers:
            self._p.changeDynamics(body, -1, activationState=pybullet.ACTIVATION_STATE_WAKE_UP)

    def link_pose(self, name: str, link: int) -> tuple[np.ndarray, np.ndarray]:
        """URDF-frame position (3,) and quaternion (4,) of one link (``-1`` = base frame); read every
        control tick, so without :meth:`link_poses`' arrays."""
        position, quat = self._link_pose(self.body_id(name), name, link)
        return np.array(position), np.array(quat)

    def link_poses(self, name: str, links: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """URDF-frame positions (L, 3) and quaternions (L, 4) of links (``-1`` = base frame)."""
        body = self.body_id(name)
        positions, quats = np.empty((len(links), 3)), np.empty((len(links), 4))
        for row, link in enumerate(links):
            positions[row], quats[row] = self._link_pose(body, name, link)
        return positions, quats

    def _link_pose(self, body: int, name: str, link: int) -> tuple:
        if link < -1:  # folded into a kept link: that link's frame, then the fixed joints' offset
            host_position, host_quat = self._link_pose(body, name, self._folded_hosts[name][-2 - link])
            return self._p.multiplyTransforms(host_position, host_quat, *self._folded[name].offsets[-2 - link])
        if link == -1:
            # the base's URDF frame differs from its centre-of-mass frame by the inertial offset
            return self._p.multiplyTransforms(*self._p.getBasePositionAndOrientation(body), *self._base_offset(body))
        state = self._p.getLinkState(body, link, computeForwardKinematics=True)
        return state[4], state[5]

    def _base_offset(self, body: int) -> tuple:
        """The base's centre-of-mass frame to its URDF frame; read once per body (its inertial frame
        is fixed at load) instead of on every pose query."""
        offset = self._base_offsets.get(body)
        if offset is None:
            offset = self._base_offsets[body] = self._p.invertTransform(*self._p.getDynamicsInfo(body, -1)[3:5])
        return offset

    def joint_states(self, name: str, indices: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities of the given joints."""
        states = self._p.getJointStates(self.body_id(name), indices)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def reset_joints(self, name: str, indices: list[int], positions: np.ndarray) -> None:
        """Set joint positions instantly (zero velocity), e.g. to pose a robot before the first step."""
        body = self.body_id(name)
        for j, q in zip(indices, positions):
            self._p.resetJointState(body, j, float(q), 0.0)

    def set_joint_targets(self, name: str, indices: list[int], positions: np.ndarray, forces: np.ndarray,
                          max_velocities: np.ndarray, position_gain: float = 0.3, velocity_gain: float = 1.0) -> None:
        """Position control with realistic torque limits (N m) and joint speed limits (rad/s); a robot
        driving the same joints at every tick makes a :class:`MotorGroup` once and calls :meth:`drive`."""
        self.drive(MotorGroup.of(name, indices, forces, max_velocities, position_gain, velocity_gain), positions)

    def drive(self, group: MotorGroup, positions: np.ndarray) -> None:
        """Send position targets (one per joint of ``group``, rad) to its motors.

        URDF velocity limits are ignored by PyBullet unless passed as ``maxVelocity``. PyBullet
        applies it as a cap on the motor's corrective velocity, not a hard bound on the joint: after a
        1 rad target step the right shoulder (limit 5 rad/s) peaked at 11 rad/s. The controllers never
        ask for such steps (joint_delta moves targets at most 1.5 rad/s; the IK plans within 5 rad/s).
        """
        body = self.body_id(group.name)
        positions = np.asarray(positions, dtype=float).tolist()
        if len(positions) != len(group.indices):
            raise InvalidInputError(f"{len(positions)} targets for a group of {len(group.indices)} joints; "
                                    f"expected one per joint")
        # PyBullet's bulk call takes no maxVelocity but keeps the one last set, so the per-joint call
        # is only made for joints whose speed limit changed
        sent = self._sent_max_velocity.setdefault(body, {})
        if list(map(sent.get, group.indices)) != group.max_velocities:  # one comparison where none changed
            for j, q, f, v in zip(group.indices, positions, group.forces, group.max_velocities):
                if sent.get(j) != v:
                    self._p.setJointMotorControl2(
                        body, j, pybullet.POSITION_CONTROL, targetPosition=q, force=f, maxVelocity=v,
                        positionGain=group.position_gains[0], velocityGain=group.velocity_gains[0],
                    )
                    sent[j] = v
        self._p.setJointMotorControlArray(
            body, group.indices, pybullet.POSITION_CONTROL, targetPositions=positions, forces=group.forces,
            positionGains=group.position_gains, velocityGains=group.velocity_gains,
        )

    def set_joint_velocity_limits(self, name: str, indices: list[int], limits: np.ndarray) -> None:
        """Clamp the speed of joints ``indices`` of body ``name`` to ``limits`` (rad/s, > 0) in the solver.

        ``maxVelocity`` in :meth:`set_joint_targets` caps only the motor's corrective velocity: contacts,
        gravity and the motion of the other joints still whipped the 5 rad/s arm joints to 17-23 rad/s
        under random joint_delta actions. PyBullet's ``maxJointVelocity`` (100 rad/s unless set) clamps
        the joint's velocity in every step, as a real servo's top speed does; it is not part of a saved
        state, so it holds across :meth:`restore_state`.
        """
        body = self.body_id(name)
        movable = {joint.index for joint in self._joints[name]}
        unknown = [j for j in indices if j not in movable]
        if unknown:
            raise InvalidInputError(f"joints {unknown} are not movable joints of body {name!r}; its joints: "
                                    f"{sorted(movable)}")
        limits = np.asarray(limits, dtype=float)
        if limits.shape != (len(indices),) or not np.all(np.isfinite(limits)) or np.any(limits <= 0.0):
            raise InvalidInputError(
                f"limits must be {len(indices)} finite speeds > 0 (rad/s), one per joint; got {limits.tolist()}"
            )
        self._record("set_joint_velocity_limits", name, list(indices), limits.copy())
        for joint, limit in zip(indices, limits):
            self._p.changeDynamics(body, int(joint), maxJointVelocity=float(limit))

    def set_dynamics(self, name: str, link: int = -1, **kwargs: float) -> None:
        """Change contact/dynamics properties (``lateralFriction``, ``mass``, ...) of one link."""
        body = self.body_id(name)
        self._physical_link(name, link)
        self._record("set_dynamics", name, link, **kwargs)
        self._p.changeDynamics(body, link, **kwargs)

    def let_sleep(self, name: str) -> None:
        """Let the engine put a body to sleep once it has rested for about 2 s (Bullet's rule); a touch
        wakes it. Three pegs resting on the table took 18 of a 53 us tick with the robot's legs welded."""
        self._record("let_sleep", name)
        body = self.body_id(name)
        self._sleepers.add(body)
        self._p.changeDynamics(body, -1, activationState=pybullet.ACTIVATION_STATE_ENABLE_SLEEPING)

    def set_color(self, name: str, rgba: tuple[float, float, float, float], link: int = -1) -> None:
        body = self.body_id(name)
        self._physical_link(name, link)
        self._record("set_color", name, rgba, link)
        self._p.changeVisualShape(body, link, rgbaColor=list(rgba))

    def mass_properties(self, name: str) -> tuple[float, np.ndarray]:
        """Total mass (kg) and world centre of mass (3,) of a body."""
        body = self.body_id(name)
        masses = [self._p.getDynamicsInfo(body, -1)[0]]
        coms = [self._p.getBasePositionAndOrientation(body)[0]]
        for j in range(self._p.getNumJoints(body)):
            masses.append(self._p.getDynamicsInfo(body, j)[0])
            coms.append(self._p.getLinkState(body, j, computeForwardKinematics=True)[0])
        m = np.array(masses)
        return float(m.sum()), (m[:, None] * np.array(coms)).sum(axis=0) / m.sum()

    def aabb(self, name: str, link: int = -1) -> tuple[np.ndarray, np.ndarray]:
        lo, hi = self._p.getAABB(self.body_id(name), self._physical_link(name, link))
        return np.array(lo), np.array(hi)

    def contacts(self, name_a: str, name_b: str | None = None, link_a: int | None = None) -> list[dict]:
        """Contact points of body ``name_a`` (optionally with ``name_b``, optionally one link of a)."""
        kwargs = {"bodyA": self.body_id(name_a)}
        if name_b is not None:
            kwargs["bodyB"] = self.body_id(name_b)
        if link_a is not None:
            kwargs["linkIndexA"] = self._physical_link(name_a, link_a)
        return [
            {"link_a": c[3], "link_b": c[4], "position": np.array(c[5]), "normal_force": c[9]}
            for c in self._p.getContactPoints(**kwargs)
        ]

    def ray_cast(self, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, list[str | None]]:
        """First hits of the rays ``starts[k] -> ends[k]`` (N, 3): hit points (N, 3), NaN where a ray
        hits nothing, and the hit body's name (None for none). Exact on faces, but a ray passing within
        ~1.5 mm of a tilted box's vertex can report a hit up to ~1.4 mm off (Bullet's GJK cast)."""
        results = self._p.rayTestBatch(np.asarray(starts, float).tolist(), np.asarray(ends, float).tolist())
        names = {body: name for name, body in self._bodies.items()}
        points = np.full((len(results), 3), np.nan)
        for row, hit in enumerate(results):
            if hit[0] >= 0:
                points[row] = hit[3]
        return points, [names.get(hit[0]) for hit in results]

    # ------------------------------------- grasp constraints and proximity (demonstrator, envs/demonstrator.py)
    def closest_distance(self, name_a: str, name_b: str, link_a: int | None = None,
                         max_distance: float = 0.05) -> float:
        """Smallest signed distance (m, negative = penetration) between body ``name_a`` (optionally one
        of its links) and body ``name_b``; ``inf`` when they are farther apart than ``max_distance``.

        Computed from the current poses (no step needed), e.g. to see whether fingers touch an object.
        """
        kwargs = {"bodyA": self.body_id(name_a), "bodyB": self.body_id(name_b), "distance": float(max_distance)}
        if link_a is not None:
            kwargs["linkIndexA"] = self._physical_link(name_a, link_a)
        points = self._p.getClosestPoints(**kwargs)
        return min((c[8] for c in points), default=float("inf"))

    def attach(self, parent: str, parent_link: int, child: str, max_force: float = 50.0) -> int:
        """Hold body ``child`` rigidly at its current pose relative to link ``parent_link`` of ``parent``.

        A fixed constraint (e.g. a grasp once the fingers have closed on an object); returns its id
        for :meth:`detach`. Constraint frames are centre-of-mass frames, as PyBullet defines them;
        ``max_force`` (N) bounds the force the constraint may apply.
        """
        parent_id, child_id = self.body_id(parent), self.body_id(child)
        self._physical_link(parent, parent_link)
        if parent_link == -1:
            parent_pos, parent_quat = self._p.getBasePositionAndOrientation(parent_id)
        else:
            parent_pos, parent_quat = self._p.getLinkState(parent_id, parent_link, computeForwardKinematics=True)[:2]
        child_pos, child_quat = self._p.getBasePositionAndOrientation(child_id)
        inv_pos, inv_quat = self._p.invertTransform(parent_pos, parent_quat)
        rel_pos, rel_quat = self._p.multiplyTransforms(inv_pos, inv_quat, child_pos, child_quat)
        constraint = self._p.createConstraint(
            parent_id, parent_link, child_id, -1, pybullet.JOINT_FIXED, [0.0, 0.0, 0.0],
            parentFramePosition=rel_pos, childFramePosition=[0.0, 0.0, 0.0],
            parentFrameOrientation=rel_quat, childFrameOrientation=[0.0, 0.0, 0.0, 1.0],
        )
        self._p.changeConstraint(constraint, maxForce=float(max_force))
        return constraint

    def detach(self, constraint_id: int) -> None:
        """Remove a constraint made by :meth:`attach`."""
        self._p.removeConstraint(constraint_id)

    # ----------------------------------------------------------------- stepping
    def set_solver_iterations(self, iterations: int) -> None:
        """Cap the constraint solver's iterations per step (PyBullet's default is 50).

        Fewer iterations step faster and hold joints and contacts less stiffly; the environments choose
        by robot model (``envs/core.py``: ``SOLVER_ITERATIONS``). ``benchmarks/physics_floor.py``
        measures what the cap buys.
        """
        if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 1:
            raise InvalidInputError(f"iterations must be an int >= 1, got {iterations!r}")
        self._record("set_solver_iterations", iterations)
        self._p.setPhysicsEngineParameter(numSolverIterations=int(iterations))

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            self._p.stepSimulation()

    def save_state(self) -> int:
        """Snapshot the whole world in memory; :meth:`restore_state` returns to it exactly."""
        return self._p.saveState()

    def restore_state(self, state_id: int) -> None:
        """Return to a :meth:`save_state` snapshot, bit for bit whatever happened since.

        PyBullet restores poses and velocities but keeps the contact manifolds (warm-starting
        caches) of the moment, so the next steps would depend on history. Parking every body far
        apart and running collision detection drops all pairs; the second restore then starts from
        the same empty cache every time.
        """
        self.placements += 1
        self._p.restoreState(stateId=state_id)
        self._sent_max_velocity.clear()
        for k, body in enumerate(self._bodies.values()):
            self._p.resetBasePositionAndOrientation(body, [100.0 + 10.0 * k, 100.0, 100.0], [0.0, 0.0, 0.0, 1.0])
        self._p.performCollisionDetection()
        self._p.restoreState(stateId=state_id)

    # ------------------------------------------------------------------ cameras
    def render(self, camera: Camera | str) -> CameraImage:
        """Render a camera (a :class:`Camera` or the name of one in :attr:`cameras`)."""
        if isinstance(camera, str):
            try:
                camera = self.cameras[camera]
            except KeyError:
                raise InvalidInputError(f"no camera named {camera!r}; cameras: {sorted(self.cameras)}") from None
        renderer = pybullet.ER_BULLET_HARDWARE_OPENGL if self.gui else pybullet.ER_TINY_RENDERER
        width, height, rgba, depth_buffer, seg = self._p.getCameraImage(
            camera.width,
            camera.height,
            viewMatrix=camera.view_matrix().T.ravel().tolist(),
            projectionMatrix=camera.projection_matrix().T.ravel().tolist(),
            renderer=renderer,
            shadow=int(self.shadows),
        )
        rgba = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)
        zbuf = np.asarray(depth_buffer, dtype=np.float64).reshape(height, width)
        n, f = camera.near, camera.far
        depth = (f * n / (f - (f - n) * zbuf)).astype(np.float32)
        seg = np.asarray(seg, dtype=np.int32).reshape(height, width)  # body id per pixel, -1 = background
        return CameraImage(rgb=np.ascontiguousarray(rgba[..., :3]), depth=depth, segmentation=seg)
