"""Fold every link on a fixed joint into its parent, in the URDF itself.

PyBullet's own ``URDF_MERGE_FIXED_LINKS`` keeps about 34 kB for every load that no
``resetSimulation`` gives back (an env rebuilds its world at every reset), and it drops the host
link's own inertial offset from the merged centre of mass (the welded robot's hand: 1.3 mm from its
joint instead of 63 mm). A URDF merged here is loaded without that flag: one link per moving joint
(the base included), each carrying its folded links' shapes at their fixed poses and their mass in
one rigid-body inertia.
"""

from __future__ import annotations

import functools
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError
from hoap_actions.outputs import write_bytes

_MERGED_DIR: tempfile.TemporaryDirectory | None = None


def _pose(element: ET.Element | None) -> tuple[np.ndarray, np.ndarray]:
    """The rotation matrix and translation of an ``<origin>`` (identity when absent)."""
    origin = None if element is None else element.find("origin")
    if origin is None:
        return np.eye(3), np.zeros(3)
    xyz = np.array([float(v) for v in origin.get("xyz", "0 0 0").split()])
    rpy = [float(v) for v in origin.get("rpy", "0 0 0").split()]
    return Rotation.from_euler("xyz", rpy).as_matrix(), xyz


def _set_pose(element: ET.Element, rotation: np.ndarray, translation: np.ndarray) -> None:
    origin = element.find("origin")
    if origin is None:
        origin = ET.Element("origin")
        element.insert(0, origin)
    rpy = Rotation.from_matrix(rotation).as_euler("xyz")
    origin.set("xyz", " ".join(repr(float(v)) for v in translation))
    origin.set("rpy", " ".join(repr(float(v)) for v in rpy))


def _inertia(link: ET.Element) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, centre of mass and inertia tensor about it, all in the link's frame."""
    inertial = link.find("inertial")
    if inertial is None:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    rotation, com = _pose(inertial)
    mass = float(inertial.find("mass").get("value"))
    values = inertial.find("inertia")
    get = lambda key: float(values.get(key, "0"))  # noqa: E731
    tensor = np.array([
        [get("ixx"), get("ixy"), get("ixz")],
        [get("ixy"), get("iyy"), get("iyz")],
        [get("ixz"), get("iyz"), get("izz")],
    ])
    return mass, com, rotation @ tensor @ rotation.T


def _write_inertia(link: ET.Element, mass: float, com: np.ndarray, tensor: np.ndarray) -> None:
    inertial = link.find("inertial")
    if inertial is None:
        inertial = ET.SubElement(link, "inertial")
    for child in list(inertial):
        inertial.remove(child)
    ET.SubElement(inertial, "origin", xyz=" ".join(repr(float(v)) for v in com), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=repr(float(mass)))
    keys = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}
    ET.SubElement(inertial, "inertia", {key: repr(float(tensor[i, j])) for key, (i, j) in keys.items()})


def _fold(host: ET.Element, folded: ET.Element, rotation: np.ndarray, translation: np.ndarray) -> None:
    """Move ``folded``'s shapes and mass onto ``host``; ``folded`` sits at (rotation, translation) in it."""
    for kind in ("visual", "collision"):
        for shape in folded.findall(kind):
            shape_rotation, shape_translation = _pose(shape)
            _set_pose(shape, rotation @ shape_rotation, rotation @ shape_translation + translation)
            host.append(shape)
    mass_a, com_a, tensor_a = _inertia(host)
    mass_b, com_b, tensor_b = _inertia(folded)
    if mass_b == 0.0:
        return
    com_b = rotation @ com_b + translation
    tensor_b = rotation @ tensor_b @ rotation.T
    mass = mass_a + mass_b
    com = (mass_a * com_a + mass_b * com_b) / mass
    tensor = np.zeros((3, 3))
    for m, c, t in ((mass_a, com_a, tensor_a), (mass_b, com_b, tensor_b)):
        d = c - com
        tensor += t + m * (d @ d * np.eye(3) - np.outer(d, d))  # parallel-axis theorem
    _write_inertia(host, mass, com, tensor)


def merge_fixed_links(urdf_text: str, base_dir: Path) -> str:
    """The URDF with every fixed joint's child folded into its parent; mesh paths made absolute
    against ``base_dir`` so the result loads from anywhere. A file that is not a URDF tree (bad XML,
    a joint without parent or child, a link named twice or missing, a loop of joints) is an
    :class:`InvalidInputError`."""
    try:
        return _merged(urdf_text, base_dir)
    except (ET.ParseError, AttributeError, KeyError, ValueError, TypeError) as exc:
        raise InvalidInputError(f"not a URDF whose fixed links can be merged: {type(exc).__name__}: {exc}") from None


def _merged(urdf_text: str, base_dir: Path) -> str:
    robot = ET.fromstring(urdf_text)
    links = {link.get("name"): link for link in robot.findall("link")}
    joints = robot.findall("joint")
    parent_of = {joint.find("child").get("link"): joint for joint in joints}
    if len(links) != len(robot.findall("link")) or len(parent_of) != len(joints):
        raise ValueError("a link is named twice, or is the child of two joints")

    def depth(joint: ET.Element) -> int:
        n, link = 0, joint.find("parent").get("link")
        while link in parent_of:
            if n > len(joints):
                raise ValueError(f"the joints loop back through link {link!r}")
            n, link = n + 1, parent_of[link].find("parent").get("link")
        return n

    for joint in sorted((j for j in joints if j.get("type") == "fixed"), key=depth, reverse=True):
        host_name, folded_name = joint.find("parent").get("link"), joint.find("child").get("link")
        rotation, translation = _pose(joint)
        _fold(links[host_name], links[folded_name], rotation, translation)
        for child_joint in robot.findall("joint"):
            if child_joint.find("parent").get("link") == folded_name:
                child_rotation, child_translation = _pose(child_joint)
                _set_pose(child_joint, rotation @ child_rotation, rotation @ child_translation + translation)
                child_joint.find("parent").set("link", host_name)
        robot.remove(links.pop(folded_name))
        robot.remove(joint)
    for mesh in robot.iter("mesh"):
        filename = mesh.get("filename", "")
        if filename and "://" not in filename and not Path(filename).is_absolute():
            mesh.set("filename", str((base_dir / filename).resolve()))
    return ET.tostring(robot, encoding="unicode")


@functools.lru_cache(maxsize=8)
def merged_urdf_path(path: str) -> Path:
    """A file holding :func:`merge_fixed_links` of the URDF at ``path``, written once per process into
    a private temporary folder that is removed at exit."""
    global _MERGED_DIR
    if _MERGED_DIR is None:
        _MERGED_DIR = tempfile.TemporaryDirectory(prefix="hoap_actions_urdf_")
    source = Path(path)
    target = Path(_MERGED_DIR.name) / f"{len(list(Path(_MERGED_DIR.name).iterdir()))}_{source.name}"
    write_bytes(target, merge_fixed_links(source.read_text(), source.parent).encode(), "merged URDF")
    return target
