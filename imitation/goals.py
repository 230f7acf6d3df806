"""What counts as doing what was shown: the goal vectors of ``Imitate-v0`` and its success test.

A goal is a (10,) vector: the block's centre (3, m) and quaternion (4, x y z w), the hand's pointing
position on the table (2, m: the right tcp's x y), and a flag that is 1 for an approach (the hand
must point at the block, which must stay put) and 0 for a push, move or rotate (the block must reach
its target). The flag is the same in the achieved and the desired goal of an episode, so goals
relabelled from the same episode (HER) keep their meaning.

The block is a uniformly coloured cube: poses that differ by one of the cube's 24 rotations look and
behave the same, so orientations are compared up to them (a block turned 60 degrees one way is the
block turned 30 degrees the other).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["GOAL_SIZE", "POSITION_TOLERANCE", "ANGLE_TOLERANCE", "STILL_TOLERANCE", "POINT_TOLERANCE",
           "block_angle", "block_turn", "goal_distance", "goal_errors", "goal_reached", "goal_vector", "yaw_of"]

GOAL_SIZE = 10
POSITION_TOLERANCE = 0.005  # m, block centre to its target (push, move, rotate)
ANGLE_TOLERANCE = np.radians(10.0)  # rad, block orientation to its target, up to the cube's symmetries
STILL_TOLERANCE = 0.001  # m, how far an approached block may move and still count as not moved
POINT_TOLERANCE = 0.005  # m, the hand's pointing position to an approach's target, in the table plane
METRES_PER_RADIAN = POSITION_TOLERANCE / ANGLE_TOLERANCE
"""Weight of the angle in the dense distance: a tolerance's worth of turn counts as a tolerance's worth of shift."""
_CUBE_ROTATIONS = Rotation.create_group("O").as_quat()  # (24, 4) x y z w: the rotations that map a cube onto itself


def yaw_of(rotation_vector: np.ndarray) -> float:
    """The heading (rad) about the vertical of an orientation given as a rotation vector (3,)."""
    return float(Rotation.from_rotvec(rotation_vector).as_euler("zyx")[0])


def block_turn(start: np.ndarray, end: np.ndarray) -> float:
    """The block's turn (rad, in [-pi, pi]) about the vertical from pose ``start`` to pose ``end`` (6,:
    centre m and rotation vector rad)."""
    return float(np.angle(np.exp(1j * (yaw_of(end[3:]) - yaw_of(start[3:])))))


def goal_vector(block_position: np.ndarray, block_quaternion: np.ndarray, point_xy: np.ndarray,
                approach: bool) -> np.ndarray:
    """The (10,) goal of a block pose (centre m, quaternion x y z w), a pointing position (2, m) and the flag."""
    return np.concatenate([block_position, block_quaternion, point_xy, [float(approach)]]).astype(float)


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products of quaternions (x, y, z, w), broadcast over leading axes."""
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def block_angle(quaternion: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Angle (rad) between block orientations (..., 4) and targets (..., 4), quaternions x y z w, up to
    the cube's symmetries: the smallest over the 24 of the rotation taking one onto the other."""
    q = np.asarray(quaternion, float)
    t = np.asarray(target, float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    symmetric = _product(t[..., None, :], _CUBE_ROTATIONS)  # (..., 24, 4)
    cosine = np.abs(np.einsum("...k,...sk->...s", q, symmetric)).max(axis=-1)
    return 2.0 * np.arccos(np.clip(cosine, 0.0, 1.0))


def goal_errors(achieved: np.ndarray, desired: np.ndarray) -> dict[str, np.ndarray]:
    """The block's ``position_error`` (m) and ``angle_error`` (rad), the hand's ``point_error`` (m, in the
    table plane) and the ``approach`` flags, of goal batches (..., 10)."""
    a, d = np.asarray(achieved, float), np.asarray(desired, float)
    return {
        "position_error": np.linalg.norm(a[..., :3] - d[..., :3], axis=-1),
        "angle_error": block_angle(a[..., 3:7], d[..., 3:7]),
        "point_error": np.linalg.norm(a[..., 7:9] - d[..., 7:9], axis=-1),
        "approach": d[..., 9] > 0.5,
    }


def goal_reached(achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
    """Vectorised success of goal batches (..., 10). Push, move, rotate: the block's centre within
    :data:`POSITION_TOLERANCE` and its orientation within :data:`ANGLE_TOLERANCE` of the target.
    Approach: the hand points within :data:`POINT_TOLERANCE` of the target and the block has not moved
    (centre within :data:`STILL_TOLERANCE`, turned less than :data:`ANGLE_TOLERANCE`)."""
    e = goal_errors(achieved, desired)
    tolerance = np.where(e["approach"], STILL_TOLERANCE, POSITION_TOLERANCE)
    block = (e["position_error"] <= tolerance) & (e["angle_error"] <= ANGLE_TOLERANCE)
    return block & (~e["approach"] | (e["point_error"] <= POINT_TOLERANCE))


def goal_distance(achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
    """Dense distance (m) of goal batches: the block's shift, its turn at :data:`METRES_PER_RADIAN`, and for
    an approach the hand's distance from where it should point."""
    e = goal_errors(achieved, desired)
    return e["position_error"] + METRES_PER_RADIAN * e["angle_error"] + np.where(e["approach"], e["point_error"], 0.0)
