"""Write ``hoap3.urdf``: a HOAP-3-style humanoid from the published figures (shared/reference/hoap3.md).

Run ``python urdf/make_hoap3.py`` after changing a number here; the generated URDFs are committed and
are what the package loads: ``hoap3.urdf``, the free-standing robot, and ``hoap3_fixed_legs.urdf``, the
same robot with its 12 leg joints welded at the standing posture (:data:`STANDING_LEGS`) and no leg
collision shapes, for a robot bolted to its stand. Writing the model from a table keeps the left side
an exact mirror of the right and every inertia consistent with its shape (positive-definite, triangle
inequality).

Conventions: x forward, y left, z up; at zero the legs are straight, the arms point forward
horizontally (shoulder pitch +90 deg hangs them) and the head is level. The root link is the
pelvis, its frame on the waist-pitch axis 0.305 m above the soles. Both sides use the same joint
axes, so a mirrored pose negates the x- and z-axis joints (rolls, yaws, hand torsion) and keeps the
y-axis ones; the gripper axis is itself mirrored so that a positive gripper angle closes either hand.

Hand: a palm plate on the inner side of the forearm axis and a thumb plate pivoting about the
hand's z axis 0.133 m from the elbow on the outer side. The thumb's face is parallel to the palm,
15 mm from it, at ``GRIP_CONTACT_DEG``: there it squeezes a 15 mm peg centred on the tcp with
0.36 N m / 0.038 m = 9.5 N; at the +60 deg limit its tip reaches the palm (closed on nothing).
"""

from __future__ import annotations

from math import pi, radians
from pathlib import Path

import numpy as np

from hoap_actions.urdf import LEG_JOINTS, STANDING_LEGS, standing_leg_angle

# ------------------------------------------------------------------ published figures (m, kg, deg)
ARM_LINK1, ARM_LINK2, ARM_LINK3 = 0.111, 0.111, 0.171
FINGER_PIVOT = 0.133  # elbow to thumb pivot, along the forearm
BODY_LINK1, BODY_LINK2 = 0.125, 0.035
WAIST_LINK1, WAIST_LINK2 = 0.055, 0.035
HIP_Y = 0.039
LEG_LINK2, LEG_LINK3, LEG_LINK4 = 0.105, 0.105, 0.040
HEAD_LINK1 = 0.103
FOOT = (0.108, 0.073)  # sole length, width
ANKLE_TO_TOE = 0.068
HEIGHT = 0.603  # soles to top of head
VEL = 5.0  # rad/s for every joint: the manual gives none; a HOAP-2 simulator uses 5

# ---------------------------------------------------------------------------- our design numbers
WRIST = 0.070  # elbow to hand-torsion joint (on the forearm axis, so it moves no frame)
PEG_R = 0.0075  # the hand is shaped around a 15 mm peg centred on the tcp
PALM_T = THUMB_T = 0.008  # plate thicknesses
THUMB_X0 = 0.060  # thumb plate's back end, from the hand-torsion joint (pivot at 0.063)
FINGER_TIP = ARM_LINK3 + 0.024 - WRIST  # palm and thumb reach 24 mm past the tcp
THUMB_PIVOT_Y = PEG_R + THUMB_T / 2 + 0.0005  # pivot inside the thumb plate, outer side
GRIP_CONTACT_DEG = 45.0  # thumb angle at which its face is parallel to the palm, touching the peg
FRAME_MASS = 1e-3  # kg given to each fixed frame link (taken from its parent)
FRICTION = 1.0  # feet, palm and thumb; PyBullet friction anchors stop them creeping (mm a minute)

WHITE, GREY, BLUE, BLACK = "white", "grey", "blue", "black"
COLORS = {
    WHITE: (0.92, 0.92, 0.95, 1.0),
    GREY: (0.45, 0.47, 0.50, 1.0),
    BLUE: (0.15, 0.35, 0.75, 1.0),
    BLACK: (0.12, 0.12, 0.12, 1.0),
}
CYL_RPY = {"x": (0.0, pi / 2, 0.0), "y": (pi / 2, 0.0, 0.0), "z": (0.0, 0.0, 0.0)}
AXES = {"x": (1, 0, 0), "y": (0, 1, 0), "z": (0, 0, 1)}


def box(size, xyz=(0, 0, 0), rpy=(0, 0, 0), color=WHITE, collide=True) -> dict:
    """A box shape; ``collide=False`` for joint housings hidden between neighbours (visual only)."""
    return {
        "kind": "box", "size": tuple(size), "xyz": tuple(xyz), "rpy": tuple(rpy), "color": color, "collide": collide,
    }


def cyl(r, length, axis, xyz=(0, 0, 0), color=WHITE, collide=True) -> dict:
    """A cylinder whose length runs along ``axis`` ("x", "y" or "z") of the link."""
    return {
        "kind": "cylinder", "r": r, "length": length, "axis": axis, "xyz": tuple(xyz), "rpy": CYL_RPY[axis],
        "color": color, "collide": collide,
    }


def solid_inertia(mass: float, shape: dict) -> np.ndarray:
    """Principal moments of a solid box or cylinder of ``mass`` about its centre, in the shape's axes."""
    if shape["kind"] == "box":
        x, y, z = shape["size"]
        return mass / 12.0 * np.array([y * y + z * z, x * x + z * z, x * x + y * y])
    r, length = shape["r"], shape["length"]
    across, along = mass * (3 * r * r + length * length) / 12.0, mass * r * r / 2.0
    return np.array([along if a == shape["axis"] else across for a in "xyz"])


def link(name, mass, shapes=(), inertia_shape=None, com=None, inertia=None, friction=None) -> dict:
    """A link whose inertia is the solid ``inertia_shape`` (default: its first shape) of ``mass``.

    Without shapes it is a frame: a 5 mm sphere. ``com`` and ``inertia`` (principal moments) override.
    """
    rpy = (0, 0, 0)
    if inertia is None:
        shape = inertia_shape or (shapes[0] if shapes else None)
        if shape is None:
            inertia, com = np.full(3, 0.4 * mass * 0.005**2), (0, 0, 0)
        else:
            inertia, com = solid_inertia(mass, shape), shape["xyz"]
            rpy = shape["rpy"] if shape["kind"] == "box" else rpy  # cylinder moments are already in link axes
    return {
        "name": name, "mass": mass, "com": tuple(com), "rpy": tuple(rpy), "inertia": np.asarray(inertia),
        "shapes": list(shapes), "friction": friction,
    }


def joint(name, parent, child, xyz=(0, 0, 0), axis=None, deg=None, effort=None) -> dict:
    """A revolute joint (``axis`` and range ``deg`` given) or a fixed one."""
    return {
        "name": name, "parent": parent, "child": child, "xyz": tuple(xyz), "axis": axis, "deg": deg, "effort": effort,
        "rpy": (0.0, 0.0, 0.0),
    }


def welded(joint_: dict, angle: float) -> dict:
    """``joint_`` turned into a fixed joint at ``angle`` (rad) about its axis (a coordinate axis)."""
    rpy = tuple(angle if a == joint_["axis"] else 0.0 for a in "xyz")
    return joint_ | {"axis": None, "deg": None, "effort": None, "rpy": rpy}


def fixed_legs(links: list, joints: list) -> tuple[list, list]:
    """The model with both legs welded at :data:`STANDING_LEGS` and their links without collision shapes."""
    leg_joint_names = set(LEG_JOINTS)
    leg_links = {jt["child"] for jt in joints if jt["name"] in leg_joint_names}
    joints = [
        welded(jt, standing_leg_angle(jt["name"])) if jt["name"] in leg_joint_names else jt for jt in joints
    ]
    links = [
        lk | {"shapes": [s | {"collide": False} for s in lk["shapes"]], "friction": None}
        if lk["name"] in leg_links else lk
        for lk in links
    ]
    return links, joints


def ranges(s: float):
    """Range for side ``s`` (-1 right, +1 left) of a roll/yaw joint given by its right-side range."""
    return (lambda lo, hi: (lo, hi)) if s < 0 else (lambda lo, hi: (-hi, -lo))


def leg(s: float) -> tuple[list, list]:
    """One leg, ``s`` = -1 right, +1 left; hip yaw, roll and pitch axes meet at the hip point."""
    p, mirror = "r" if s < 0 else "l", ranges(s)
    foot_x = ANKLE_TO_TOE - FOOT[0] / 2  # sole centre ahead of the ankle
    plate = box((FOOT[0], FOOT[1], 0.016), (foot_x, 0, -LEG_LINK4 + 0.008), color=BLACK)
    bracket = box((0.04, 0.05, 0.012), (0, 0, -0.022), color=BLUE)
    links = [
        link(f"{p}_hip_yaw_link", 0.0587, [cyl(0.018, 0.02, "z", (0, 0, 0.012), GREY, collide=False)]),
        link(f"{p}_hip_roll_link", 0.210, [box((0.05, 0.04, 0.04), color=GREY, collide=False)]),
        link(f"{p}_thigh", 0.519, [box((0.05, 0.05, LEG_LINK2 - 0.02), (0, 0, -LEG_LINK2 / 2))]),
        link(f"{p}_shin", 0.328, [box((0.045, 0.045, LEG_LINK3 - 0.02), (0, 0, -LEG_LINK3 / 2))]),
        link(f"{p}_ankle_pitch_link", 0.195, [box((0.04, 0.04, 0.03), color=GREY, collide=False)]),
        link(f"{p}_foot", 0.154 - FRAME_MASS, [plate, bracket], friction=FRICTION),
        link(f"{p}_sole", FRAME_MASS),
    ]
    hip = (-WAIST_LINK2, s * HIP_Y, -WAIST_LINK1)
    joints = [
        joint(f"{p}_hip_yaw", "pelvis", f"{p}_hip_yaw_link", hip, "z", mirror(-91, 31), 3.0),
        joint(f"{p}_hip_roll", f"{p}_hip_yaw_link", f"{p}_hip_roll_link", (0, 0, 0), "x", mirror(-31, 21), 4.5),
        joint(f"{p}_hip_pitch", f"{p}_hip_roll_link", f"{p}_thigh", (0, 0, 0), "y", (-82, 71), 3.0),
        joint(f"{p}_knee", f"{p}_thigh", f"{p}_shin", (0, 0, -LEG_LINK2), "y", (-1, 130), 4.5),
        joint(f"{p}_ankle_pitch", f"{p}_shin", f"{p}_ankle_pitch_link", (0, 0, -LEG_LINK3), "y", (-61, 61), 4.5),
        joint(f"{p}_ankle_roll", f"{p}_ankle_pitch_link", f"{p}_foot", (0, 0, 0), "x", (-25, 25), 3.0),
        joint(f"{p}_sole_joint", f"{p}_foot", f"{p}_sole", (foot_x, 0, -LEG_LINK4)),
    ]
    return links, joints


def thumb_plate(inner: float, pivot: np.ndarray) -> dict:
    """The thumb box in the thumb's frame, placed so that at ``GRIP_CONTACT_DEG`` it lies parallel to the palm."""
    closed = np.array([(THUMB_X0 + FINGER_TIP) / 2, -inner * (PEG_R + THUMB_T / 2)])  # centre in the hand frame
    yaw = -inner * radians(GRIP_CONTACT_DEG)  # undoes the closing rotation about (0, 0, inner)
    c, s = np.cos(yaw), np.sin(yaw)
    x, y = closed - pivot[:2]
    return box((FINGER_TIP - THUMB_X0, THUMB_T, 0.03), (c * x - s * y, s * x + c * y, 0.0), (0, 0, yaw), color=GREY)


def arm(s: float) -> tuple[list, list]:
    """One arm, ``s`` = -1 right, +1 left; the hand frame is the forearm frame after the torsion joint."""
    p, mirror = "r" if s < 0 else "l", ranges(s)
    inner = -s  # palm side: +y for the right hand, facing the body's midline
    palm_x0 = 0.050
    palm = box(
        (FINGER_TIP - palm_x0, PALM_T, 0.04), ((palm_x0 + FINGER_TIP) / 2, inner * (PEG_R + PALM_T / 2), 0), color=GREY
    )
    pivot = np.array([FINGER_PIVOT - WRIST, -inner * THUMB_PIVOT_Y, 0.0])
    hand_mass_shape = box((FINGER_TIP, 0.035, 0.04), (FINGER_TIP / 2, inner * 0.004, 0))
    links = [
        link(f"{p}_shoulder_pitch_link", 0.210, [cyl(0.025, 0.03, "y", (0, -s * 0.012, 0), BLUE, collide=False)]),
        link(f"{p}_shoulder_roll_link", 0.234, [box((0.045, 0.04, 0.045), (0.005, 0, 0), color=GREY, collide=False)]),
        link(f"{p}_upper_arm", 0.1965, [cyl(0.02, 0.075, "x", (0.0575, 0, 0))]),
        link(f"{p}_forearm", 0.110, [cyl(0.018, WRIST - 0.004, "x", (WRIST / 2 - 0.002, 0, 0))]),
        link(
            f"{p}_hand", 0.080 - FRAME_MASS, [cyl(0.016, 0.055, "x", (0.0275, 0, 0)), palm],
            inertia_shape=hand_mass_shape, friction=FRICTION,
        ),
        link(f"{p}_thumb", 0.026, [thumb_plate(inner, pivot)], friction=FRICTION),
        link(f"{p}_tcp", FRAME_MASS),
    ]
    shoulder = (-BODY_LINK2, s * ARM_LINK1, BODY_LINK1)
    joints = [
        joint(f"{p}_shoulder_pitch", "trunk", f"{p}_shoulder_pitch_link", shoulder, "y", (-91, 151), 3.0),
        joint(f"{p}_shoulder_roll", f"{p}_shoulder_pitch_link", f"{p}_shoulder_roll_link", (0, 0, 0), "z",
              mirror(-96, 1), 3.0),
        joint(f"{p}_shoulder_yaw", f"{p}_shoulder_roll_link", f"{p}_upper_arm", (0, 0, 0), "x", (-91, 91), 3.0),
        joint(f"{p}_elbow", f"{p}_upper_arm", f"{p}_forearm", (ARM_LINK2, 0, 0), "y", (-115, 1), 3.0),
        joint(f"{p}_wrist_yaw", f"{p}_forearm", f"{p}_hand", (WRIST, 0, 0), "x", (-90, 90), 0.36),
        joint(f"{p}_gripper", f"{p}_hand", f"{p}_thumb", tuple(pivot), (0, 0, inner), (-60, 60), 0.36),
        joint(f"{p}_tcp_joint", f"{p}_hand", f"{p}_tcp", (ARM_LINK3 - WRIST, 0, 0)),
    ]
    return links, joints


def model() -> tuple[list, list]:
    """All links and joints, depth first (this order is PyBullet's joint order)."""
    links = [link("pelvis", 0.417, [box((0.09, 0.13, 0.05), (-0.03, 0, -0.035), color=GREY)])]
    joints = []
    for s in (-1.0, 1.0):
        leg_links, leg_joints = leg(s)
        links, joints = links + leg_links, joints + leg_joints
    chest = box((0.11, 0.16, 0.16), (-0.035, 0, 0.085))
    backpack = box((0.05, 0.12, 0.10), (-0.115, 0, 0.09), color=BLUE)
    # mass sheet: trunk with battery, its centre of mass and principal inertia about it
    trunk_inertia = (12.2e-3, 17.6e-3, 15.7e-3)
    links.append(link("trunk", 3.26, [chest, backpack], com=(-0.0495, 0.0009, 0.0842), inertia=trunk_inertia))
    joints.append(joint("waist_pitch", "pelvis", "trunk", (0, 0, 0), "y", (-1, 90), 4.5))
    for s in (-1.0, 1.0):
        arm_links, arm_joints = arm(s)
        links, joints = links + arm_links, joints + arm_joints
    tilt_z = BODY_LINK1 + HEAD_LINK1  # head tilt and roll axes, above the waist axis
    neck_z = BODY_LINK1 + 0.040
    head_top = HEIGHT - (LEG_LINK4 + LEG_LINK3 + LEG_LINK2 + WAIST_LINK1 + tilt_z)
    head = box((0.09, 0.10, 0.10), (0.0, 0, head_top - 0.05))
    eyes = box((0.01, 0.07, 0.025), (0.046, 0, 0), color=BLACK)
    links += [
        link("neck", 0.060, [cyl(0.015, 0.05, "z", (0, 0, 0.02), GREY, collide=False)]),
        link("head_tilt_link", 0.040, [box((0.03, 0.04, 0.03), color=GREY, collide=False)]),
        link("head", 0.483 - 0.100 - FRAME_MASS, [head, eyes]),
        link("camera", FRAME_MASS),
    ]
    joints += [
        joint("head_pan", "trunk", "neck", (-BODY_LINK2, 0, neck_z), "z", (-60, 60), 1.12),
        joint("head_tilt", "neck", "head_tilt_link", (0, 0, tilt_z - neck_z), "y", (-45, 15), 1.12),
        joint("head_roll", "head_tilt_link", "head", (0, 0, 0), "x", (-15, 15), 1.12),
        joint("camera_joint", "head", "camera", (0.045, 0, 0)),
    ]
    return links, joints


def _f(values) -> str:
    return " ".join(f"{float(v):.7g}" for v in values)


def _geometry(shape: dict) -> str:
    if shape["kind"] == "box":
        return f'<box size="{_f(shape["size"])}"/>'
    return f'<cylinder radius="{shape["r"]:.7g}" length="{shape["length"]:.7g}"/>'


HEADER = """<?xml version="1.0"?>
<!-- HOAP-3-style humanoid, 28 DOF, 8.80 kg, 0.603 m. Generated by make_hoap3.py from the published
     HOAP-3 figures: edit that script, not this file. x forward, z up; zero pose: straight legs, arms
     forward. Positive gripper angles close the thumb onto the palm (a 15 mm peg is met at 45 deg).
     Frames: r_tcp / l_tcp (grasp point), r_sole / l_sole (sole centre), camera (eyes, looks along +x). -->
<robot name="hoap3">"""


FIXED_LEGS_NOTE = (
    "<!-- This variant welds both legs at the standing posture ("
    + ", ".join(f"{name} {angle:g}" for name, angle in STANDING_LEGS.items())
    + " rad)\n     and gives them no collision shapes: load it with a fixed base. 16 DOF. -->"
)


def to_urdf(links: list, joints: list, note: str = "") -> str:
    """The URDF text: materials, then links, then joints."""
    out = [HEADER] + ([note] if note else [])
    out += [f'  <material name="{n}"><color rgba="{_f(c)}"/></material>' for n, c in COLORS.items()]
    for lk in links:
        ixx, iyy, izz = lk["inertia"]
        out.append(f'  <link name="{lk["name"]}">')
        out.append(
            f'    <inertial><origin xyz="{_f(lk["com"])}" rpy="{_f(lk["rpy"])}"/><mass value="{lk["mass"]:.7g}"/>'
            f'<inertia ixx="{ixx:.7g}" ixy="0" ixz="0" iyy="{iyy:.7g}" iyz="0" izz="{izz:.7g}"/></inertial>'
        )
        for shape in lk["shapes"]:
            origin, geometry = f'<origin xyz="{_f(shape["xyz"])}" rpy="{_f(shape["rpy"])}"/>', _geometry(shape)
            material = f'<material name="{shape["color"]}"/>'
            out.append(f"    <visual>{origin}<geometry>{geometry}</geometry>{material}</visual>")
            if shape["collide"]:
                out.append(f"    <collision>{origin}<geometry>{geometry}</geometry></collision>")
        if lk["friction"] is not None:
            out.append(f'    <contact><lateral_friction value="{lk["friction"]:.7g}"/><friction_anchor/></contact>')
        out.append("  </link>")
    for jt in joints:
        kind = "fixed" if jt["axis"] is None else "revolute"
        out.append(f'  <joint name="{jt["name"]}" type="{kind}">')
        out.append(f'    <parent link="{jt["parent"]}"/><child link="{jt["child"]}"/>')
        out.append(f'    <origin xyz="{_f(jt["xyz"])}" rpy="{_f(jt["rpy"])}"/>')
        if kind == "revolute":
            axis = AXES[jt["axis"]] if isinstance(jt["axis"], str) else jt["axis"]
            lo, hi = (radians(d) for d in jt["deg"])
            out.append(f'    <axis xyz="{_f(axis)}"/>')
            limit = f'lower="{lo:.9g}" upper="{hi:.9g}" effort="{jt["effort"]:.7g}" velocity="{VEL:.7g}"'
            out.append(f"    <limit {limit}/>")
        out.append("  </joint>")
    out.append("</robot>")
    return "\n".join(out) + "\n"


def main() -> None:
    here = Path(__file__)
    here.with_name("hoap3.urdf").write_text(to_urdf(*model()))
    here.with_name("hoap3_fixed_legs.urdf").write_text(to_urdf(*fixed_legs(*model()), note=FIXED_LEGS_NOTE))


if __name__ == "__main__":
    main()
