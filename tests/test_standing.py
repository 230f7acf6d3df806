"""Physics of the humanoid: it stands still for a minute, its 1-DOF hand holds a peg by friction alone,
and its servo speed limits are set with checked values (the limit held under random actions is
catalogue row 8, tests/test_bad_input_catalogue.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hoap_actions.envs import world
from hoap_actions.envs.robot import Robot
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError

CONTROL_EVERY = 8  # physics steps per command: 30 Hz, as the environments act

# 15 mm x 50 mm, 10 g, friction 1.0: the peg the hand is shaped for
PEG_URDF = """<?xml version="1.0"?>
<robot name="test_peg"><link name="peg">
  <inertial><mass value="0.01"/>
    <inertia ixx="2.224e-06" ixy="0" ixz="0" iyy="2.224e-06" iyz="0" izz="2.8125e-07"/></inertial>
  <collision><geometry><cylinder radius="0.0075" length="0.05"/></geometry></collision>
  <contact><lateral_friction value="1.0"/></contact>
</link></robot>
"""


@pytest.fixture
def standing():
    sim = Sim()
    sim.add_ground_plane(z=world.FLOOR_Z)
    yield sim, Robot(sim)
    sim.close()


def inside(point: np.ndarray, clockwise: np.ndarray) -> bool:
    edges = np.roll(clockwise, -1, axis=0) - clockwise
    to_point = point - clockwise
    return bool(np.all(edges[:, 0] * to_point[:, 1] - edges[:, 1] * to_point[:, 0] <= 0))


def area(clockwise: np.ndarray) -> float:
    """Shoelace area, positive for a clockwise polygon."""
    x, y = clockwise[:, 0], clockwise[:, 1]
    return float(np.sum(np.roll(x, -1) * y - x * np.roll(y, -1)) / 2)


def test_reset_puts_level_soles_on_the_floor(standing):
    sim, robot = standing
    for side in "rl":
        position, quat = robot.frame_pose(f"{side}_sole")
        assert position[2] == pytest.approx(world.FLOOR_Z, abs=1e-6)
        assert Rotation.from_quat(quat).apply([0, 0, 1])[2] == pytest.approx(1.0, abs=1e-9)
    ankles = np.mean([robot.frame_pose(f"{side}_foot")[0][:2] for side in "rl"], axis=0)
    np.testing.assert_allclose(ankles, world.ROBOT_FEET_XY, atol=1e-6)
    np.testing.assert_allclose(robot.joint_positions(), robot.home_posture, atol=1e-6)


def test_stands_still_for_a_minute(standing):
    """60 s holding the home posture: no fall, base drift <= 2 mm, centre of mass over the feet.

    The first second is contact settling (a sway of about 2 mm that decays); after it the base
    must stay within 0.5 mm of where it settled.
    """
    sim, robot = standing
    start, _ = robot.base_pose()
    polygon = robot.support_polygon()
    assert inside(robot.com()[:2], polygon)
    ticks_per_second = 240 // CONTROL_EVERY
    settled, wander = None, 0.0
    for tick in range(60 * ticks_per_second):
        robot.set_targets(robot.home_posture)
        sim.step(CONTROL_EVERY)
        assert not robot.has_fallen(), f"fell after {tick / ticks_per_second:.2f} s"
        if tick == ticks_per_second:
            settled = robot.base_pose()[0]
        elif settled is not None:
            wander = max(wander, np.linalg.norm(robot.base_pose()[0] - settled))
    assert np.linalg.norm(robot.base_pose()[0] - start) <= 0.002
    assert wander <= 0.0005
    assert inside(robot.com()[:2], robot.support_polygon())
    after = robot.support_polygon()  # the feet have not moved: same extent, same area
    extent = [polygon.min(axis=0), polygon.max(axis=0)]
    np.testing.assert_allclose([after.min(axis=0), after.max(axis=0)], extent, atol=0.001)
    assert area(after) == pytest.approx(area(polygon), rel=0.01)
    np.testing.assert_allclose(robot.joint_positions(), robot.home_posture, atol=0.02)


def test_support_polygon_is_the_clockwise_hull_of_both_soles(standing):
    _, robot = standing
    polygon = robot.support_polygon()
    assert polygon.shape == (4, 2)
    assert area(polygon) == pytest.approx(0.108 * (0.078 + 0.073))  # positive: clockwise
    span = polygon.max(axis=0) - polygon.min(axis=0)
    np.testing.assert_allclose(span, [0.108, 0.078 + 0.073], atol=1e-6)


def test_has_fallen_after_a_push_over(standing):
    sim, robot = standing
    assert not robot.has_fallen()
    base, _ = robot.base_pose()
    sim.set_base_pose(robot.name, base, Rotation.from_euler("y", 1.2).as_quat())
    assert robot.has_fallen()


def test_sole_tilt_is_level_standing_and_follows_a_tipped_body(standing):
    sim, robot = standing
    sim.step(480)  # contact settling: the soles rock by up to 0.3 deg in the first second
    assert robot.sole_tilt() < np.radians(0.2)
    base, _ = robot.base_pose()
    sim.set_base_pose(robot.name, base, Rotation.from_euler("y", 0.3).as_quat())
    assert robot.sole_tilt() == pytest.approx(0.3, abs=1e-3)  # plus the little tilt it stood with


@pytest.mark.parametrize("exact_cylinder", [True, False], ids=["implicit-cylinder", "convex-hull"])
def test_hand_holds_a_peg_by_friction(standing, tmp_path, exact_cylinder):
    """Hand a peg into the open right hand, close it, raise the arm 21 cm: the peg follows the tcp."""
    sim, robot = standing
    path = tmp_path / "peg.urdf"
    path.write_text(PEG_URDF)
    sim.load_urdf("peg", path, position=(0.0, 0.5, 0.0), implicit_cylinders=exact_cylinder)
    thumb, palm = (sim.link_index(robot.name, link) for link in ("r_thumb", "r_hand"))

    def peg_in_tcp() -> np.ndarray:
        tcp, quat = robot.frame_pose("r_tcp")
        return Rotation.from_quat(quat).inv().apply(sim.base_pose("peg")[0] - tcp)

    robot.set_gripper("right", 1.0)
    for _ in range(60):  # the hand-over: hold the peg at the tcp until thumb and palm both press it
        sim.set_base_pose("peg", *robot.frame_pose("r_tcp"))
        sim.step()
        pressing = {c["link_b"] for c in sim.contacts("peg", robot.name) if c["normal_force"] > 0}
        if {thumb, palm} <= pressing:
            break
    else:
        pytest.fail("the thumb never closed on the peg")
    sim.step(60)
    grip = sum(c["normal_force"] for c in sim.contacts("peg", robot.name) if c["link_b"] == thumb)
    assert grip > 5.0  # N: 0.36 N m on a 38 mm lever is 9.5 N
    before, peg_z = peg_in_tcp(), sim.base_pose("peg")[0][2]

    q = robot.targets
    k = robot.joint_index("r_shoulder_pitch")
    start, goal = q[k], np.radians(20.0)
    for tick in range(1, 31):  # 1 s ramp at 30 Hz, then 0.5 s hold
        q[k] = start + (goal - start) * tick / 30
        robot.set_targets(q)
        sim.step(CONTROL_EVERY)
    sim.step(120)

    assert sim.base_pose("peg")[0][2] - peg_z > 0.15
    assert {c["link_b"] for c in sim.contacts("peg")} <= {thumb, palm}
    assert np.linalg.norm(peg_in_tcp() - before) <= 0.002
    assert not robot.has_fallen()


@pytest.mark.parametrize(
    "indices, limits, message",
    [([0, 1], [5.0], "one per joint"), ([0], [0.0], "> 0"), ([0], [np.nan], "finite"), ([999], [5.0], "not movable")],
)
def test_joint_velocity_limits_are_validated(standing, indices, limits, message):
    sim, robot = standing
    with pytest.raises(InvalidInputError, match=message):
        sim.set_joint_velocity_limits(robot.name, indices, np.array(limits))


def test_solver_iteration_cap_loosens_the_joints():
    """One solver iteration cannot hold the standing posture as tightly as PyBullet's default 50."""
    sag = {}
    for iterations in (None, 1):
        sim = Sim()
        sim.add_ground_plane(z=world.FLOOR_Z)
        robot = Robot(sim)
        if iterations is not None:
            sim.set_solver_iterations(iterations)
        sim.step(120)
        sag[iterations] = float(np.abs(robot.joint_positions() - robot.targets).max())
        sim.close()
    assert sag[1] > 2 * sag[None], sag


@pytest.mark.parametrize("iterations", [0, -3, 2.5, True, "10"])
def test_solver_iterations_must_be_a_positive_int(standing, iterations):
    sim, _ = standing
    with pytest.raises(InvalidInputError, match="iterations must be an int >= 1"):
        sim.set_solver_iterations(iterations)
