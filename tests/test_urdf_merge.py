"""Folding fixed links in the URDF: the merged body has the unmerged one's kinematics, joints, mass and
centre of mass."""

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from hoap_actions.envs.sim import Sim
from hoap_actions.envs.urdf_merge import merge_fixed_links
from hoap_actions.errors import InvalidInputError
from hoap_actions.urdf import urdf_path

TWO_LINKS = """<robot name="r">
  <link name="a"><inertial><origin xyz="0.1 0 0"/><mass value="2"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
  <link name="b"><inertial><mass value="1"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>
    <collision><origin xyz="0.1 0 0.5" rpy="0 0 0"/><geometry><sphere radius="0.1"/></geometry></collision>
    <visual><geometry><mesh filename="part.obj"/></geometry></visual></link>
  <joint name="weld" type="fixed"><parent link="a"/><child link="b"/>
    <origin xyz="0.4 0 0" rpy="0 0 1.5707963267948966"/></joint>
</robot>"""


def test_a_point_mass_folds_by_the_parallel_axis_theorem() -> None:
    robot = ET.fromstring(merge_fixed_links(TWO_LINKS, Path("/models")))
    (link,) = robot.findall("link")
    assert not robot.findall("joint")
    inertial = link.find("inertial")
    assert float(inertial.find("mass").get("value")) == pytest.approx(3.0)
    com = np.array([float(v) for v in inertial.find("origin").get("xyz").split()])
    np.testing.assert_allclose(com, [(2 * 0.1 + 1 * 0.4) / 3, 0, 0], atol=1e-12)
    tensor = inertial.find("inertia")
    # masses 2 and 1 at 0.1 and 0.4 on x: each is 0.2 and 0.1 from the common centre
    assert float(tensor.get("ixx")) == pytest.approx(1.0)
    assert float(tensor.get("iyy")) == pytest.approx(1.0 + 2 * 0.1**2 + 1 * 0.2**2)
    assert float(tensor.get("izz")) == pytest.approx(1.0 + 2 * 0.1**2 + 1 * 0.2**2)
    (collision,) = link.findall("collision")  # the child's sphere, its offset turned by the joint's yaw
    xyz = [float(v) for v in collision.find("origin").get("xyz").split()]
    np.testing.assert_allclose(xyz, [0.4, 0.1, 0.5], atol=1e-12)
    assert link.find("visual/geometry/mesh").get("filename") == str(Path("/models/part.obj").resolve())


@pytest.mark.parametrize("text", [
    "<robot><link name='a'>",  # not XML
    "<robot><link name='a'/><joint name='j' type='fixed'><parent link='a'/></joint></robot>",  # no child
    "<robot><link name='a'/><link name='b'/>"  # a loop of joints
    "<joint name='j' type='fixed'><parent link='a'/><child link='b'/></joint>"
    "<joint name='k' type='fixed'><parent link='b'/><child link='a'/></joint></robot>",
    "<robot><link name='a'/><joint name='j' type='fixed'><parent link='a'/><child link='z'/></joint></robot>",
])
def test_a_file_that_is_not_a_urdf_tree_is_refused(text: str) -> None:
    with pytest.raises(InvalidInputError, match="not a URDF"):
        merge_fixed_links(text, Path("/models"))


def _loaded(merge: bool) -> Sim:
    sim = Sim()
    sim.load_urdf("robot", "hoap3_fixed_legs.urdf", fixed_base=False, merge_fixed_links=merge)
    return sim


def test_the_merged_robot_moves_and_weighs_as_the_unmerged_one() -> None:
    plain, merged = _loaded(False), _loaded(True)
    try:
        names = plain.joint_names("robot")
        assert merged.joint_names("robot") == names
        for sim in (plain, merged):
            joints = sim.joints("robot")
            q = np.random.default_rng(1).uniform([j.lower for j in joints], [j.upper for j in joints])
            sim.reset_joints("robot", [j.index for j in joints], q)
        positions, quats = plain.link_poses("robot", [plain.link_index("robot", n) for n in _link_names()])
        merged_links = [merged.link_index("robot", n) for n in _link_names()]
        assert sum(link < -1 for link in merged_links) == 17  # per leg 6 links and a sole, two tool points, the camera
        merged_positions, merged_quats = merged.link_poses("robot", merged_links)
        np.testing.assert_allclose(merged_positions, positions, atol=1e-6)  # PyBullet keeps link frames in float32
        np.testing.assert_allclose(np.abs(np.sum(merged_quats * quats, axis=1)), 1.0, atol=1e-6)
        mass, com = plain.mass_properties("robot")
        merged_mass, merged_com = merged.mass_properties("robot")
        assert merged_mass == pytest.approx(mass, rel=1e-12)
        np.testing.assert_allclose(merged_com, com, atol=1e-6)
        assert [j.name for j in merged.joints("robot")] == [j.name for j in plain.joints("robot")]
    finally:
        plain.close()
        merged.close()


def _link_names() -> list[str]:
    return [link.get("name") for link in ET.parse(urdf_path("hoap3_fixed_legs.urdf")).getroot().findall("link")]


def _resident_bytes() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="reads Linux's /proc")
def test_rebuilding_a_merged_robot_does_not_grow_the_process() -> None:
    sim = Sim()
    try:
        sim.load_urdf("robot", "hoap3_fixed_legs.urdf", fixed_base=True, merge_fixed_links=True)
        for _ in range(100):
            sim.rebuild()
        before = _resident_bytes()
        for _ in range(300):
            sim.rebuild()
        grown = _resident_bytes() - before
    finally:
        sim.close()
    assert grown < 2 * 2**20, f"{grown / 2**20:.1f} MiB over 300 rebuilds"  # PyBullet's own merge kept 10 MiB
