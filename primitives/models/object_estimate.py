"""The object's trajectory estimated from the arm markers while the hand moves it.

Discovery names a manipulation piece by what the object did (its pose relative to where it rested,
:class:`~hoap_actions.primitives.discovery.estimator.PrimitiveDiscovery`), so a recogniser that sees only the
arm can ask the same question of an estimate: between the end of the approach and the start of the
remove the hand carries, pushes or turns the object, which then moves as if fixed to the hand. The
hand's frame comes from three markers (wrist, index knuckle, thumb tip); the object sits at a fixed
offset in that frame, learned as the median over the training demonstrations' manipulation frames.
Before the manipulation the object rests where the hand first takes it, after it where the hand
leaves it.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError

__all__ = ["HAND_FRAME_MARKERS", "fit_grasp_offset", "hand_frames", "object_poses"]

HAND_FRAME_MARKERS = ("wrist", "index_knuckle", "thumb_tip")
"""Markers spanning the hand's frame: origin at the wrist, x towards the knuckle, y towards the thumb."""


def hand_frames(H: np.ndarray, marker_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The hand's rotation ``(T, 3, 3)`` (columns: its axes in the world) and origin ``(T, 3)`` (m) per
    frame of the markers ``H`` ``(T, M, 3)`` named ``marker_names``."""
    H = np.asarray(H, dtype=float)
    missing = [m for m in HAND_FRAME_MARKERS if m not in marker_names]
    if missing:
        raise InvalidInputError(f"the hand's frame needs the markers {list(HAND_FRAME_MARKERS)}; "
                                f"{missing} are not among {list(marker_names)}")
    if H.ndim != 3 or H.shape[1:] != (len(marker_names), 3):
        raise InvalidInputError(f"markers must be (T, {len(marker_names)}, 3); got shape {H.shape}")
    if not np.all(np.isfinite(H)):
        raise InvalidInputError("markers must be finite (no NaN or inf); bridge occlusion gaps first with "
                                "hoap_actions.primitives.pipelines.mocap_cleaning.fill_gaps")
    wrist, knuckle, thumb = (H[:, list(marker_names).index(m)] for m in HAND_FRAME_MARKERS)
    x = knuckle - wrist
    y = thumb - wrist
    x_norm = np.linalg.norm(x, axis=1, keepdims=True)
    y = y - np.sum(y * x, axis=1, keepdims=True) * x / np.maximum(x_norm, 1e-12) ** 2
    y_norm = np.linalg.norm(y, axis=1, keepdims=True)
    if np.any(x_norm < 1e-6) or np.any(y_norm < 1e-6):
        raise InvalidInputError("the wrist, index knuckle and thumb tip markers coincide or lie on one line "
                                "in some frame: they span no hand frame")
    x, y = x / x_norm, y / y_norm
    return np.stack([x, y, np.cross(x, y)], axis=2), wrist


def fit_grasp_offset(movements: Sequence[tuple[np.ndarray, np.ndarray]], marker_names: Sequence[str]) -> np.ndarray:
    """The object's centre in the hand's frame (3,), m: the median over every frame of the
    ``movements``, pairs of markers ``(T, M, 3)`` and object poses ``(T, 6)`` of the frames in which
    the hand moves the object."""
    offsets = []
    for H, O in movements:
        rotation, origin = hand_frames(H, marker_names)
        offsets.append(np.einsum("tji,tj->ti", rotation, np.asarray(O, float)[:, :3] - origin))
    if not offsets:
        raise InvalidInputError("no manipulation frames to learn the grasp offset from")
    return np.median(np.concatenate(offsets), axis=0)


def object_poses(H: np.ndarray, marker_names: Sequence[str], start: int, end: int, offset: np.ndarray) -> np.ndarray:
    """The object's estimated poses ``(T, 6)`` (position m, rotation vector rad relative to its
    orientation at ``start``) over the markers ``H`` ``(T, M, 3)``: fixed to the hand at ``offset``
    (its frame, m) over frames ``[start, end)``, at rest before and after."""
    T = len(H)
    if not (0 <= start < end <= T):
        raise InvalidInputError(f"the manipulation frames [start, end) must lie within the {T} frames with "
                                f"start < end; got [{start}, {end})")
    offset = np.asarray(offset, dtype=float)
    if offset.shape != (3,) or not np.all(np.isfinite(offset)):
        raise InvalidInputError(f"offset must be 3 finite numbers (m, in the hand's frame); got {offset!r}")
    rotation, origin = hand_frames(H, marker_names)
    position = origin + np.einsum("tij,j->ti", rotation, offset)
    turned = (Rotation.from_matrix(rotation[start:end]) * Rotation.from_matrix(rotation[start]).inv()).as_rotvec()
    poses = np.zeros((T, 6))
    poses[:start, :3] = position[start]
    poses[start:end] = np.hstack([position[start:end], turned])
    poses[end:] = poses[end - 1]
    return poses
