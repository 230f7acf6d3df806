"""The robot, demonstrator and scene models, shipped as package data (URDF, primitive shapes only)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from hoap_actions.errors import DataFileError

LEG_JOINTS = tuple(f"{side}_{joint}" for side in "rl" for joint in (
    "hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll"))
"""The 12 leg joints, right leg first, hip to ankle."""
STANDING_LEGS = {"hip_pitch": -0.2, "knee": 0.4, "ankle_pitch": -0.2}
"""Leg angles (rad, both sides; the others 0) of the standing home posture: knees bent 0.4 rad, hips
over the ankles, soles flat. ``hoap3_fixed_legs.urdf`` welds its legs at these angles."""


def standing_leg_angle(joint: str) -> float:
    """The standing posture's angle (rad) of leg joint ``joint`` (e.g. ``"r_knee"``)."""
    return STANDING_LEGS.get(joint[2:], 0.0)


def urdf_path(name: str) -> Path:
    """Absolute path of the packaged URDF file ``name`` (e.g. ``"hoap3.urdf"``)."""
    path = Path(str(files(__name__).joinpath(name)))
    if not path.is_file():
        available = sorted(p.name for p in path.parent.glob("*.urdf"))
        raise DataFileError(f"no packaged URDF named {name!r}; available: {available}")
    return path
