"""The HOAP-3 model against the published figures, and the Robot API around it.

Sizes are measured on the loaded PyBullet model (frames, bounding boxes), not read back from the
generator, and placo must compute the same forward kinematics from the same file.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import placo
import pytest
from scipy.spatial.transform import Rotation

from hoap_actions.envs import world
from hoap_actions.envs.robot import GRIPPER_CLOSED, Robot
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError
from hoap_actions.urdf import urdf_path

URDF = urdf_path("hoap3.urdf")
MM = 1e-3

# Right-side ranges (deg) and peak torques (N m) from the manual; True: the left range is mirrored.
MANUAL = {
    "hip_yaw": ((-91, 31), 3.0, True),
    "hip_roll": ((-31, 21), 4.5, True),
    "hip_pitch": ((-82, 71), 3.0, False),
    "knee": ((-1, 130), 4.5, False),
    "ankle_pitch": ((-61, 61), 4.5, False),
    "ankle_roll": ((-25, 25), 3.0, False),
    "shoulder_pitch": ((-91, 151), 3.0, False),
    "shoulder_roll": ((-96, 1), 3.0, True),
    "shoulder_yaw": ((-91, 91), 3.0, False),
    "elbow": ((-115, 1), 3.0, False),
    "wrist_yaw": ((-90, 90), 0.36, False),
    "gripper": ((-60, 60), 0.36, False),
}
BODY = {
    "waist_pitch": ((-1, 90), 4.5),
    "head_pan": ((-60, 60), 1.12),
    "head_tilt": ((-45, 15), 1.12),
    "head_roll": ((-15, 15), 1.12),
}
FRAMES = ("r_tcp", "l_tcp", "r_sole", "l_sole", "camera")
# x- and z-axis joints change sign in a mirrored pose; the gripper's axis is itself mirrored
MIRROR_SIGN = dict.fromkeys(("hip_yaw", "hip_roll", "ankle_roll", "shoulder_roll", "shoulder_yaw", "wrist_yaw"), -1)


@pytest.fixture(scope="module")
def robot():
    """A robot standing on z = 0 at the origin (no floor needed: nothing here steps the physics)."""
    sim = Sim()
    yield Robot(sim, feet_xy=(0.0, 0.0), floor_z=0.0)
    sim.close()


def straight(robot: Robot) -> None:
    robot.reset(np.zeros(len(robot.joint_names)))


def pos(robot: Robot, frame: str) -> np.ndarray:
    return robot.frame_pose(frame)[0]


def test_total_mass_matches_the_mass_sheet(robot):
    mass, _ = robot.sim.mass_properties(robot.name)
    assert mass == pytest.approx(8.80, abs=0.2)
    assert mass == pytest.approx(8.80, abs=0.01)  # the sheet's parts add up to 8.80 kg


def test_standing_height_and_eye_height(robot):
    straight(robot)
    top = robot.sim.aabb(robot.name, robot.sim.link_index(robot.name, "head"))[1][2]
    assert top == pytest.approx(0.60, abs=0.02)
    assert pos(robot, "camera")[2] == pytest.approx(0.533, abs=MM)


def test_link_lengths_measured_on_the_model(robot):
    straight(robot)
    for p in "rl":
        shoulder, elbow = pos(robot, f"{p}_shoulder_pitch_link"), pos(robot, f"{p}_forearm")
        assert np.linalg.norm(elbow - shoulder) == pytest.approx(0.111, abs=MM)
        assert np.linalg.norm(pos(robot, f"{p}_tcp") - elbow) == pytest.approx(0.171, abs=MM)
        hip, knee, ankle = pos(robot, f"{p}_thigh"), pos(robot, f"{p}_shin"), pos(robot, f"{p}_foot")
        assert np.linalg.norm(knee - hip) == pytest.approx(0.105, abs=MM)
        assert np.linalg.norm(ankle - knee) == pytest.approx(0.105, abs=MM)
        sole = pos(robot, f"{p}_sole")
        assert ankle[2] - sole[2] == pytest.approx(0.040, abs=MM)
        assert sole[0] - ankle[0] == pytest.approx(0.014, abs=MM)  # ankle 68 mm behind the toe
        assert sole[2] == pytest.approx(0.0, abs=1e-6)
        assert shoulder[2] == pytest.approx(0.430, abs=MM)
        assert hip[0] - robot.base_pose()[0][0] == pytest.approx(-0.035, abs=MM)
    shoulders = pos(robot, "r_shoulder_pitch_link") - pos(robot, "l_shoulder_pitch_link")
    assert np.linalg.norm(shoulders) == pytest.approx(0.222, abs=MM)
    assert np.linalg.norm(pos(robot, "r_thigh") - pos(robot, "l_thigh")) == pytest.approx(0.078, abs=MM)
    assert robot.base_pose()[0][2] == pytest.approx(0.305, abs=MM)  # waist-pitch axis


def test_sole_is_108_by_73_mm(robot):
    straight(robot)
    lo, hi = robot.sim.aabb(robot.name, robot.sim.link_index(robot.name, "r_foot"))
    margin = 0.001  # PyBullet pads bounding boxes by its collision margin
    assert hi[0] - lo[0] - 2 * margin == pytest.approx(0.108, abs=MM)
    assert hi[1] - lo[1] - 2 * margin == pytest.approx(0.073, abs=MM)


def test_joint_ranges_and_torques_follow_the_manual(robot):
    names = list(robot.joint_names)
    for joint, ((lo, hi), torque, mirrored) in MANUAL.items():
        for p, (a, b) in (("r", (lo, hi)), ("l", (-hi, -lo) if mirrored else (lo, hi))):
            k = names.index(f"{p}_{joint}")
            assert (robot.lower[k], robot.upper[k]) == pytest.approx(np.radians([a, b]), abs=1e-7), f"{p}_{joint}"
            assert robot.max_force[k] == pytest.approx(torque)
    for joint, ((lo, hi), torque) in BODY.items():
        k = names.index(joint)
        assert (robot.lower[k], robot.upper[k]) == pytest.approx(np.radians([lo, hi]), abs=1e-7), joint
        assert robot.max_force[k] == pytest.approx(torque)
    assert np.all(robot.max_velocity == 5.0)


def test_left_side_mirrors_right_side(robot):
    """A pose and its mirror image (rolls and yaws negated) put every left frame at the right one's y-reflection."""
    rng = np.random.default_rng(0)
    names = list(robot.joint_names)
    links = ["hip_roll_link", "shin", "foot", "sole", "upper_arm", "forearm", "hand", "thumb", "tcp"]
    for _ in range(3):
        q = robot.home_posture.copy()
        for joint in MANUAL:
            r, l = names.index(f"r_{joint}"), names.index(f"l_{joint}")
            q[r] = rng.uniform(robot.lower[r], robot.upper[r])
            q[l] = MIRROR_SIGN.get(joint, 1) * q[r]
        robot.reset(q)
        base, quat = robot.base_pose()
        to_pelvis = Rotation.from_quat(quat).inv()
        for link in links:
            right = to_pelvis.apply(pos(robot, f"r_{link}") - base)
            left = to_pelvis.apply(pos(robot, f"l_{link}") - base)
            np.testing.assert_allclose(left, right * [1, -1, 1], atol=1e-6, err_msg=link)


def test_positive_gripper_angle_closes_both_hands(robot):
    """The thumb swings toward the palm (toward the tcp) as the gripper angle grows, on either side."""
    for p in "rl":
        gaps = []
        for angle in (0.0, GRIPPER_CLOSED):
            q = robot.home_posture.copy()
            q[robot.joint_index(f"{p}_gripper")] = angle
            robot.reset(q)
            lo, hi = robot.sim.aabb(robot.name, robot.sim.link_index(robot.name, f"{p}_thumb"))
            gaps.append(np.linalg.norm((lo + hi) / 2 - pos(robot, f"{p}_tcp")))
        assert gaps[1] < gaps[0] - 0.01, p


def test_urdf_structure_is_28_limited_revolute_joints_with_primitive_shapes():
    root = ET.parse(URDF).getroot()
    joints = root.findall("joint")
    revolute = [j for j in joints if j.get("type") == "revolute"]
    fixed = [j for j in joints if j.get("type") == "fixed"]
    assert len(revolute) == 28 and len(revolute) + len(fixed) == len(joints)
    assert sorted(j.find("child").get("link") for j in fixed) == sorted(FRAMES)
    for j in revolute:
        limit = j.find("limit")
        assert float(limit.get("lower")) < float(limit.get("upper")), j.get("name")
        assert float(limit.get("effort")) > 0 and float(limit.get("velocity")) == 5.0, j.get("name")
    assert not root.findall(".//mesh")
    kinds = {g[0].tag for g in root.iter("geometry")}
    assert kinds <= {"box", "cylinder", "sphere"}
    assert root.findall("link")[0].get("name") == "pelvis"


def test_every_link_has_a_valid_inertial():
    for link in ET.parse(URDF).getroot().findall("link"):
        inertial = link.find("inertial")
        assert inertial is not None, link.get("name")
        assert float(inertial.find("mass").get("value")) > 0, link.get("name")
        i = {k: float(v) for k, v in inertial.find("inertia").attrib.items()}
        matrix = np.array(
            [[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]]
        )
        principal = np.linalg.eigvalsh(matrix)
        assert principal.min() > 0, link.get("name")
        assert principal[0] + principal[1] >= principal[2] * (1 - 1e-9), link.get("name")


def test_named_frames_and_joint_names(robot):
    assert len(robot.joint_names) == 28 and len(set(robot.joint_names)) == 28
    for side in ("right", "left"):
        arm = [robot.joint_names[k] for k in robot.arm_joints(side)]
        joints = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_yaw", "gripper")
        assert arm == [f"{side[0]}_{j}" for j in joints]
    for frame in FRAMES:
        position, quat = robot.frame_pose(frame)
        assert position.shape == (3,) and np.linalg.norm(quat) == pytest.approx(1.0)


def test_placo_computes_the_same_kinematics(robot):
    placo_robot = placo.RobotWrapper(str(URDF))
    assert set(placo_robot.joint_names()) == set(robot.joint_names)
    rng = np.random.default_rng(1)
    frames = [*FRAMES, "l_thumb", "head", "r_upper_arm", "l_shin"]
    for _ in range(4):
        q = rng.uniform(robot.lower, robot.upper)
        robot.reset(q)
        for name, value in zip(robot.joint_names, q):
            placo_robot.set_joint(name, value)
        placo_robot.update_kinematics()
        base, quat = robot.base_pose()
        pelvis_inv = np.linalg.inv(placo_robot.get_T_world_frame("pelvis"))
        for frame in frames:
            expected = Rotation.from_quat(quat).inv().apply(pos(robot, frame) - base)
            got = (pelvis_inv @ placo_robot.get_T_world_frame(frame))[:3, 3]
            np.testing.assert_allclose(got, expected, atol=1e-6, err_msg=frame)


def test_reset_honours_placement_and_heading():
    sim = Sim()
    try:
        robot = Robot(sim, feet_xy=(0.1, -0.2), yaw=0.7, floor_z=-0.3)
        for side in "rl":
            position, quat = robot.frame_pose(f"{side}_sole")
            assert position[2] == pytest.approx(-0.3, abs=1e-6)
            np.testing.assert_allclose(Rotation.from_quat(quat).as_euler("xyz"), [0, 0, 0.7], atol=1e-6)
        ankles = np.mean([robot.frame_pose(f"{side}_foot")[0][:2] for side in "rl"], axis=0)
        np.testing.assert_allclose(ankles, [0.1, -0.2], atol=1e-6)
    finally:
        sim.close()


def test_set_targets_rejects_bad_input_and_clips_to_the_ranges(robot):
    with pytest.raises(InvalidInputError, match="shape"):
        robot.set_targets(np.zeros(27))
    q = robot.home_posture.copy()
    q[robot.joint_index("r_knee")] = np.nan
    with pytest.raises(InvalidInputError, match="r_knee"):
        robot.set_targets(q)
    q = robot.home_posture.copy()
    q[robot.joint_index("l_wrist_yaw")] = -np.inf
    with pytest.raises(InvalidInputError, match="l_wrist_yaw"):
        robot.set_targets(q)
    q = robot.home_posture.copy()
    q[robot.joint_index("r_shoulder_yaw")] = 1e200  # finite, if absurd: clipped like any angle beyond the range
    robot.set_targets(q)
    assert robot.targets[robot.joint_index("r_shoulder_yaw")] == robot.upper[robot.joint_index("r_shoulder_yaw")]
    q = robot.home_posture.copy()
    q[robot.joint_index("r_elbow")] = 3.0
    robot.set_targets(q)
    assert robot.targets[robot.joint_index("r_elbow")] == pytest.approx(np.radians(1.0))
    with pytest.raises(InvalidInputError, match="side"):
        robot.set_gripper("middle", 1.0)
    with pytest.raises(InvalidInputError):
        Robot(robot.sim, name="other", position_gain=2.0)


def test_home_posture_keeps_clear_of_the_table():
    """Hands above the table top; everything lower stays behind its near edge (world.py numbers)."""
    sim = Sim()
    try:
        home = Robot(sim)
        for link in range(-1, len(ET.parse(URDF).getroot().findall("joint"))):
            lo, hi = sim.aabb(home.name, link)
            assert hi[0] < world.TABLE_NEAR_EDGE_X or lo[2] > 0.02, link
        assert home.frame_pose("r_tcp")[0][2] > 0.04
    finally:
        sim.close()


def test_up_z_is_the_rotated_z_axis_height():
    """The closed form against scipy's rotation of the z axis, for random unit quaternions."""
    from scipy.spatial.transform import Rotation

    from hoap_actions.envs.robot import up_z

    quats = Rotation.random(200, random_state=1).as_quat()
    np.testing.assert_allclose(up_z(quats), Rotation.from_quat(quats).apply([0.0, 0.0, 1.0])[:, 2], atol=1e-12)
