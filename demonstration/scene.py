"""The human-scale demonstration scene: a table with the paper's 80 x 30 cm active region, one 5 cm
block on it, and the seated demonstrator (``human_arm.urdf``) at its near edge.

Scene frame (the frame of every recorded marker and object pose): z up, origin on the table top at
the centre of the active region, x away from the demonstrator, y to their left. The mapping to the
robot's scene (one scale, one offset) lives in :mod:`hoap_actions.envs.world`.

Friction: PyBullet multiplies the two bodies' coefficients, so block-table sliding friction is
``table_friction * object_friction`` (0.4 by default: pushes slide the block and it stops when the hand
stops) and hand-block friction ``hand_friction * object_friction`` (0.5).
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.demonstration.bodies import REFERENCE_HEIGHT_M, human_urdf
from hoap_actions.envs.camera import Camera, CameraImage
from hoap_actions.envs.sim import Sim
from hoap_actions.envs.world import HUMAN_ACTIVE_REGION_SIZE, HUMAN_TO_ROBOT_OFFSET, HUMAN_TO_ROBOT_SCALE
from hoap_actions.errors import InvalidInputError

logger = logging.getLogger(__name__)

ACTIVE_REGION_LOW = -0.5 * np.array(HUMAN_ACTIVE_REGION_SIZE)  # m, (x, y) corner of the active region
ACTIVE_REGION_HIGH = 0.5 * np.array(HUMAN_ACTIVE_REGION_SIZE)
HAND_LINKS = ("r_palm", "r_index", "r_thumb")  # the only links of the demonstrator with collision shapes
DEMONSTRATOR_CAMERA = Camera(eye=(0.75, -0.45, 0.55), target=(-0.30, 0.05, 0.10), fov_deg=55.0, width=320, height=240)
"""A monocular camera across the table from the demonstrator and to their right (the paper's Fig. 12
view): the reaching arm is seen from the front-side, so the target's depth shows in the image."""
DEMONSTRATOR_SIDE_CAMERA = Camera(eye=(-0.2, -0.9, 0.45), target=(-0.30, 0.05, 0.10), fov_deg=55.0, width=320,
                                  height=240)
"""An optional second view, on the demonstrator's right, looking across the reach: what is depth for
:data:`DEMONSTRATOR_CAMERA` moves across this image (the tracker's eq. 9 scores both)."""
OUT_OF_VIEW_M = np.array([0.0, 0.0, -50.0])  # where a body goes while the empty scene is pictured
CLUTTER = (  # (name, urdf, position m, scale, colour): what else lies on a real table
    ("clutter_box", "demo_object.urdf", (0.25, -0.30, 0.05), 2.0, (0.2, 0.4, 0.9, 1.0)),
    ("clutter_block", "demo_object.urdf", (-0.30, -0.35, 0.025), 1.0, (0.95, 0.85, 0.2, 1.0)),
    ("clutter_peg", "peg.urdf", (0.22, 0.35, 0.04), 1.6, (0.1, 0.7, 0.3, 1.0)),
    ("clutter_board", "hole_board.urdf", (0.30, 0.05, 0.0), 1.0, (0.55, 0.35, 0.2, 1.0)),
)


@dataclass(frozen=True)
class DemoSceneConfig:
    """Numbers of the human scene that are not in its URDFs (all SI units)."""

    demonstrator_position: tuple[float, float, float] = (-0.47, 0.25, -0.20)
    """Pelvis (mid-point of the hip joints) in the scene frame: seated 0.54 m above the floor at a 0.74 m
    table, the chest 18 cm behind its edge (the hanging hand must rise behind the edge; the torso leans
    in for far targets), 0.25 m left of the region's centre line so the right shoulder is on it."""
    object_size: float = 0.05  # m, edge of the cube (must match demo_object.urdf)
    table_friction: float = 0.8
    object_friction: float = 0.5
    hand_friction: float = 1.0
    timestep: float = 1.0 / 200.0  # s, physics step: 2 steps per 100 Hz recorded frame


class DemoScene:
    """A PyBullet world (one :class:`Sim`) holding the table, the block (``"object"``) and the
    demonstrator (``"human"``, fixed pelvis, ``body_height_m`` tall: :mod:`~hoap_actions.demonstration.bodies`).
    :meth:`reset` returns to the state saved after loading, so each episode starts identically whatever
    ran before."""

    def __init__(self, config: DemoSceneConfig | None = None, body_height_m: float = REFERENCE_HEIGHT_M) -> None:
        self.config = config or DemoSceneConfig()
        self.body_height_m = body_height_m
        self.sim = Sim(timestep=self.config.timestep)
        sim = self.sim
        sim.load_urdf("table", "demo_table.urdf", fixed_base=True)
        sim.load_urdf("human", human_urdf(body_height_m), position=self.config.demonstrator_position, fixed_base=True)
        half = self.config.object_size / 2.0
        sim.load_urdf("object", "demo_object.urdf", position=(0.0, 0.0, half))
        sim.set_dynamics("table", -1, lateralFriction=self.config.table_friction)
        sim.set_dynamics("object", -1, lateralFriction=self.config.object_friction)
        for link in HAND_LINKS:
            sim.set_dynamics("human", sim.link_index("human", link), lateralFriction=self.config.hand_friction)
        lo, hi = sim.aabb("object")
        if not np.allclose(hi - lo, self.config.object_size, atol=2e-3):
            raise InvalidInputError(
                f"object_size={self.config.object_size} m does not match demo_object.urdf ({(hi - lo).round(4)} m)"
            )
        self._initial_state = sim.save_state()
        self._human_joints = {j.name: j.index for j in sim.joints("human")}

    def reset(self, object_xy: np.ndarray, object_yaw: float = 0.0) -> None:
        """Restore the initial world and put the block, resting, at ``object_xy`` (m) turned by ``object_yaw`` (rad)."""
        xy = np.asarray(object_xy, float)
        if xy.shape != (2,) or not np.all(np.isfinite(xy)) or not np.isfinite(object_yaw):
            raise InvalidInputError(
                f"object_xy must be 2 finite numbers and object_yaw finite; got {object_xy}, {object_yaw}"
            )
        self.sim.restore_state(self._initial_state)
        quat = Rotation.from_euler("z", float(object_yaw)).as_quat()  # (x, y, z, w)
        self.sim.set_base_pose("object", [xy[0], xy[1], self.config.object_size / 2.0], quat)

    def pose(self, joint_names: tuple[str, ...], q: np.ndarray, object_pose: np.ndarray) -> None:
        """Put the demonstrator at joint angles ``q`` (rad, by ``joint_names``) and the block at
        ``object_pose`` (6,): one recorded frame (``Episode.Q``, ``Episode.O``), for a camera."""
        joints = self._human_joints
        unknown = [name for name in joint_names if name not in joints]
        q, object_pose = np.asarray(q, float), np.asarray(object_pose, float)
        if unknown or q.shape != (len(joint_names),) or object_pose.shape != (6,):
            raise InvalidInputError(f"a frame needs one angle per joint of the demonstrator ({sorted(joints)}) and a "
                                    f"6-D object pose; got joints {list(joint_names)}, q {q.shape}, object "
                                    f"{object_pose.shape}")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(object_pose))):
            raise InvalidInputError("joint angles and object pose must be finite")
        self.sim.reset_joints("human", [joints[name] for name in joint_names], q)
        self.sim.set_base_pose("object", object_pose[:3], Rotation.from_rotvec(object_pose[3:]).as_quat())

    def add_clutter(self) -> None:
        """Objects that have nothing to do with the task, for a camera to see: two blocks, a peg and a
        board on the table outside the active region (fixed; for rendering, not for recording)."""
        for name, urdf, position, scale, rgba in CLUTTER:
            self.sim.load_urdf(name, urdf, position=position, fixed_base=True, scale=scale)
            self.sim.set_color(name, rgba)

    def torso_base(self) -> np.ndarray:
        """The demonstrator's lumbar joint (m, scene frame): the fixed bottom of the trunk, which leans about it."""
        return self.sim.link_poses("human", [self.sim.link_index("human", "thorax")])[0][0].copy()

    def render(self, camera: Camera = DEMONSTRATOR_CAMERA) -> CameraImage:
        """What ``camera`` sees of the scene as posed."""
        return self.sim.render(camera)

    def render_background(self, camera: Camera = DEMONSTRATOR_CAMERA) -> CameraImage:
        """What ``camera`` sees of the scene without the demonstrator and the block: the picture of the empty
        table that background subtraction compares each frame with. The bodies are put back, at rest."""
        saved = {name: self.sim.base_pose(name) for name in ("human", "object")}
        try:
            for name, (position, orientation) in saved.items():
                self.sim.set_base_pose(name, position + OUT_OF_VIEW_M, orientation)
            return self.sim.render(camera)
        finally:
            for name, (position, orientation) in saved.items():
                self.sim.set_base_pose(name, position, orientation)

    def object_pose(self) -> np.ndarray:
        """The block's pose (6,): centre position (m) and rotation vector (rad, scipy ``as_rotvec``)."""
        pos, quat = self.sim.base_pose("object")
        return np.concatenate([pos, Rotation.from_quat(quat).as_rotvec()])

    def parameters(self) -> dict:
        """The scene as plain numbers (stored with every dataset); table extents read from the loaded model."""
        lo, hi = self.sim.aabb("table")
        return {
            "frame": "z up; origin on the table top at the centre of the active region; x away from the demonstrator",
            **asdict(self.config),
            "table_aabb_low": lo.round(4).tolist(),
            "table_aabb_high": hi.round(4).tolist(),
            "active_region_low": ACTIVE_REGION_LOW.tolist(),
            "active_region_high": ACTIVE_REGION_HIGH.tolist(),
            "object_mass": self.sim.mass_properties("object")[0],
            "human_to_robot_scale": HUMAN_TO_ROBOT_SCALE,
            "human_to_robot_offset": HUMAN_TO_ROBOT_OFFSET.tolist(),
        }

    def close(self) -> None:
        self.sim.close()


def active_region_grid(rows: int, cols: int) -> np.ndarray:
    """``rows x cols`` evenly spread (x, y) locations covering the active region edge to edge, shape
    (rows * cols, 2), row-major with rows along x (depth) and columns along y (width): the paper's 2x2
    training grid is the four corners, its 5x7 test grid is ``active_region_grid(5, 7)``."""
    if rows < 2 or cols < 2:
        raise InvalidInputError(f"a grid needs at least 2 rows and 2 columns; got {rows} x {cols}")
    xs = np.linspace(ACTIVE_REGION_LOW[0], ACTIVE_REGION_HIGH[0], rows)
    ys = np.linspace(ACTIVE_REGION_LOW[1], ACTIVE_REGION_HIGH[1], cols)
    return np.array([(x, y) for x in xs for y in ys])
