"""The demonstrator's kinematics for planning: placo whole-arm IK with its fixed pelvis, and hand geometry.

The demonstrator plans each reach kinematically before PyBullet executes it (module docstring of
:mod:`hoap_actions.demonstration.demonstrator`): a soft position task on a hand site, a soft orientation task,
posture regularisation with a stiffer trunk, joint limits narrowed away from singular poses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import placo
from scipy.spatial.transform import Rotation

from hoap_actions.demonstration.tasks import FPS
from hoap_actions.urdf import urdf_path

BODY_JOINTS = (
    "lumbar_flexion",
    "lumbar_bend",
    "lumbar_rotation",
    "r_shoulder_flexion",
    "r_shoulder_abduction",
    "r_shoulder_rotation",
    "r_elbow",
    "r_forearm_pronation",
    "r_wrist_flexion",
    "r_wrist_deviation",
)
FINGER_JOINTS = ("r_index_mcp", "r_thumb_cmc")
RECORDED_JOINTS = BODY_JOINTS + FINGER_JOINTS  # every joint of the demonstrator that moves, in Q's column order

# Hand geometry in the palm link frame (x radial, y palmar, z from the fingers to the wrist)
SITE_OFFSETS = {"palm_site": np.array([0.0, 0.0, -0.05]), "grasp_site": np.array([0.022, 0.065, -0.066])}
HAND_HULL = np.array(
    [[x, y, z] for x in (-0.0425, 0.0425) for y in (-0.015, 0.015) for z in (0.0, -0.10)]
    + [[x, y, z] for x in (-0.0425, 0.005) for y in (-0.01, 0.01) for z in (-0.10, -0.175)]
    + [[x, y, -0.184] for x in (0.013, 0.031) for y in (-0.009, 0.009)]
)
"""Corners bounding the straight hand's collision shapes (palm, other fingers, index): a pushing hand."""
_FINGER_RADIUS = 0.01  # m, finger radius with a little margin, for the table-clearance check

IK_ITERATIONS = 3
IK_RANGES = {"r_elbow": (0.3, 2.4), "r_shoulder_abduction": (-0.7, 1.3)}
"""rad, joint ranges of the IK narrower than the joints': a locked elbow and a shoulder abducted to 90
degrees (gimbal lock of flexion and rotation) are singular and make the solution jump."""
REGULARISATION = 1e-4  # weight of the IK's joint-velocity penalty, damps null-space drift
WAIST_WEIGHT, ARM_WEIGHT = 3e-3, 1e-4  # posture task weights: the trunk stiffer than the arm


def hand_rotation(fingers: np.ndarray, dorsal: np.ndarray) -> Rotation:
    """Palm-link orientation whose fingers point along ``fingers`` and whose back faces ``dorsal``
    (world vectors; ``dorsal`` is made orthogonal to ``fingers``)."""
    f = np.asarray(fingers, float) / np.linalg.norm(fingers)
    d = np.asarray(dorsal, float) - np.dot(dorsal, f) * f
    d /= np.linalg.norm(d)
    r = np.cross(d, f)  # radial (thumb) side
    return Rotation.from_matrix(np.column_stack([r, -d, -f]))


class ArmIK:
    """placo kinematics of the demonstrator, base fixed at ``base_position`` (scene frame, no rotation).

    One :meth:`solve` call moves the model's joints a few velocity-limited QP steps towards a site
    pose: called once per frame along a smooth path it tracks the path.
    """

    def __init__(self, base_position: np.ndarray, urdf: Path | None = None, trunk_use: float = 1.0) -> None:
        """``urdf``: the demonstrator's body (default the packaged reference); ``trunk_use`` divides the
        trunk's posture weight (more leaning and twisting above 1)."""
        self.base = np.asarray(base_position, float)
        self.robot = placo.RobotWrapper(str(urdf or urdf_path("human_arm.urdf")), placo.Flags.ignore_collisions)
        for name, (low, high) in IK_RANGES.items():
            self.robot.set_joint_limits(name, low, high)
        solver = placo.KinematicsSolver(self.robot)
        solver.mask_fbase(True)
        for name in FINGER_JOINTS:
            solver.mask_dof(name)  # the fingers are scripted, not solved
        solver.enable_velocity_limits(True)
        solver.dt = 1.0 / (FPS * IK_ITERATIONS)
        self.waist_task = solver.add_joints_task()
        self.waist_task.set_joints({name: 0.0 for name in BODY_JOINTS[:3]})
        self.waist_task.configure("waist", "soft", WAIST_WEIGHT / trunk_use)
        self.arm_task = solver.add_joints_task()
        self.arm_task.configure("arm", "soft", ARM_WEIGHT)
        solver.add_regularization_task(REGULARISATION)
        self.position = {site: solver.add_position_task(site, np.zeros(3)) for site in SITE_OFFSETS}
        self.orientation = {site: solver.add_orientation_task(site, np.eye(3)) for site in SITE_OFFSETS}
        self.solver = solver
        self._site = ""

    def set_trunk_target(self, posture: dict[str, float]) -> None:
        """Where the trunk's posture task pulls (lumbar joint name -> rad; missing ones 0)."""
        self.waist_task.set_joints({name: float(posture.get(name, 0.0)) for name in BODY_JOINTS[:3]})

    def reset(self, posture: dict[str, float]) -> None:
        """Put the model in ``posture`` (joint name -> rad; missing joints 0)."""
        self.robot.reset()
        for name, value in posture.items():
            self.robot.set_joint(name, value)
        self.robot.update_kinematics()

    @property
    def q(self) -> np.ndarray:
        """The model's full configuration (a copy), for :meth:`restore`."""
        return self.robot.state.q.copy()

    def restore(self, q: np.ndarray) -> None:
        self.robot.state.q = q
        self.robot.update_kinematics()

    def site_pose(self, site: str) -> tuple[np.ndarray, Rotation]:
        """Scene-frame position and orientation (of the palm link) of ``site`` in the model's posture."""
        T = self.robot.get_T_world_frame(site)
        return T[:3, 3] + self.base, Rotation.from_matrix(T[:3, :3])

    def hand_points(self) -> np.ndarray:
        """Scene-frame points (N, 3) bounding the hand's collision shapes in the model's posture, the
        fingertips widened by their radius."""
        T = self.robot.get_T_world_frame("r_palm")
        palm = HAND_HULL[:16] @ T[:3, :3].T + T[:3, 3]
        tips = np.array([self.robot.get_T_world_frame(f"marker_{name}_tip")[:3, 3] for name in ("index", "thumb")])
        widen = _FINGER_RADIUS * np.vstack([np.eye(3), -np.eye(3)])
        return np.vstack([palm, (tips[:, None, :] + widen).reshape(-1, 3)]) + self.base

    def solve(
        self,
        site: str,
        position: np.ndarray,
        rotation: Rotation,
        orientation_weight: float,
        arm_posture: np.ndarray,
        arm_weight: float,
        fingers: np.ndarray,
    ) -> np.ndarray:
        """Joint angles (10,) of :data:`BODY_JOINTS` moving ``site`` towards ``position`` (scene frame, m)
        with the palm towards ``rotation``; ``arm_posture`` (7,) is the arm's regularisation target and
        ``fingers`` (2,) the finger angles set in the model (for :meth:`hand_points`)."""
        if site != self._site:
            for name in SITE_OFFSETS:
                self.position[name].configure(f"{name}_position", "soft", 1.0 if name == site else 0.0)
                self.orientation[name].configure(f"{name}_orientation", "soft", 0.0)
            self._site = site
        for name, value in zip(FINGER_JOINTS, fingers):
            self.robot.set_joint(name, float(value))
        self.position[site].target_world = np.asarray(position, float) - self.base
        self.orientation[site].R_world_frame = rotation.as_matrix()
        self.orientation[site].configure(f"{site}_orientation", "soft", float(orientation_weight))
        self.arm_task.set_joints(dict(zip(BODY_JOINTS[3:], map(float, arm_posture))))
        self.arm_task.configure("arm", "soft", float(arm_weight))
        for _ in range(IK_ITERATIONS):
            self.solver.solve(True)
            self.robot.update_kinematics()
        return np.array([self.robot.get_joint(name) for name in BODY_JOINTS])

