"""What the physics facade knows of a robot's motors: each joint's static facts and the groups of
joints driven together."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from hoap_actions.errors import InvalidInputError


@dataclass(frozen=True)
class JointInfo:
    """Static facts of one movable joint, read from the loaded model."""

    index: int
    name: str
    link_name: str
    lower: float
    upper: float
    max_force: float
    max_velocity: float


@dataclass(frozen=True)
class MotorGroup:
    """Joints of body ``name`` position-controlled together, with fixed torque limits (N m), speed caps
    (rad/s) and gains: converted once into the lists PyBullet takes, not at every tick."""

    name: str
    indices: list[int]
    forces: list[float]
    max_velocities: list[float]
    position_gains: list[float]
    velocity_gains: list[float]

    @classmethod
    def of(cls, name: str, indices: ArrayLike, forces: ArrayLike, max_velocities: ArrayLike,
           position_gain: float = 0.3, velocity_gain: float = 1.0) -> MotorGroup:
        """The group of joints ``indices`` (PyBullet's) with one force and speed cap each (>= 0, finite)."""
        joints = [int(j) for j in np.asarray(indices).reshape(-1)]
        limits = [np.asarray(values, dtype=float).reshape(-1) for values in (forces, max_velocities)]
        if any(len(values) != len(joints) for values in limits) or not all(
                np.isfinite(values).all() and (values >= 0.0).all() for values in limits):
            raise InvalidInputError(f"a motor group needs one finite force and speed cap >= 0 per joint "
                                    f"({len(joints)}); got {len(limits[0])} forces and {len(limits[1])} caps")
        n = len(joints)
        return cls(name, joints, limits[0].tolist(), limits[1].tolist(), [float(position_gain)] * n,
                   [float(velocity_gain)] * n)
