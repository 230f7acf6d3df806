"""What discovery finds and reads: primitive classes of arm movements with their segments and effects,
and the demonstrations it is given (object poses and arm markers), checked and split."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hoap_actions.demonstration.datasets import MAX_COORDINATE_M
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.hmm import hmm_math

__all__ = ["APPROACH", "HAND_DIM", "MANIPULATION", "MAX_ROTATION_ANGLE_RAD", "N_MARKERS", "OBJECT_DIM", "REMOVE",
           "UNKNOWN", "PrimitiveClass", "Segment", "effect_track", "split_demonstrations", "xyz"]

OBJECT_DIM = 6
N_MARKERS = 6
HAND_DIM = 3 * N_MARKERS
APPROACH, MANIPULATION, REMOVE = "approach", "manipulation", "remove"
UNKNOWN = -1  # the class id of frames that start no known primitive
# Longest object rotation vector accepted (rad): any rotation, from a quaternion of either sign, is
# within 2 pi; far longer ones are corrupt values on which scipy's rotations break down.
MAX_ROTATION_ANGLE_RAD = 2.0 * math.pi


@dataclass(frozen=True)
class Segment:
    """One demonstration's frames ``[start, end)`` that perform a primitive, with its effect phi.

    ``initial`` and ``final`` are world-frame 3-D locations (m) at the first and last frame: of the
    object for manipulation primitives, of the hand marker for approach and remove (or of the object
    when no hand trajectories were given; ``source`` says which).
    """

    demo: int
    start: int
    end: int
    initial: tuple[float, float, float]
    final: tuple[float, float, float]
    source: str

    @property
    def phi(self) -> np.ndarray:
        """The effect phi = (initial, final), shape ``(6,)``, metres."""
        return np.array(self.initial + self.final)


@dataclass(frozen=True)
class PrimitiveClass:
    """An equivalence class of arm movements that have the same effect on the object (one primitive)."""

    primitive_id: int
    kind: str
    states: tuple[int, ...]
    segments: tuple[Segment, ...]

    @property
    def phis(self) -> np.ndarray:
        """The effect phi of every segment, shape ``(n_segments, 6)``: initial then final location (m)."""
        return np.array([s.phi for s in self.segments]).reshape(-1, 6)

    def movements(self, H: np.ndarray, lengths: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
        """The class's arm movements as ``(X, lengths)``, one sequence per segment in order, ready for
        :meth:`ParametricHMM.fit <hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM.fit>` with :attr:`phis`.

        ``H`` and ``lengths`` are the concatenated arm markers ``(N, 18)`` and per-demonstration frame
        counts given to :meth:`PrimitiveDiscovery.fit` (or any per-frame features of those frames).
        """
        H, lengths = hmm_math.validate_sequences(H, lengths)
        for s in self.segments:
            if s.demo >= len(lengths) or s.end > lengths[s.demo]:
                known = f"{lengths[s.demo]} frames" if s.demo < len(lengths) else f"only {len(lengths)} demonstrations"
                raise InvalidInputError(f"the class has frames [{s.start}, {s.end}) of demonstration {s.demo} but "
                                        f"lengths gives {known}; give the H and lengths of the demonstrations fit was "
                                        "given")
        offsets = np.cumsum(lengths) - lengths
        pieces = [H[offsets[s.demo] + s.start : offsets[s.demo] + s.end] for s in self.segments]
        return np.concatenate(pieces), np.array([s.end - s.start for s in self.segments])


def effect_track(kind: str, objects: np.ndarray, hand: np.ndarray | None) -> tuple[np.ndarray, str]:
    """The positions ``(T, 3)`` a primitive's effect phi is read from, and their source: the object's for a
    manipulation, the hand marker's (``hand``, ``(T, 3)``) for approach and remove, the object's when no
    hand is given. phi of frames ``[start, end)`` is the track at ``start`` and at ``end - 1``."""
    if kind != MANIPULATION and hand is not None:
        return hand, "hand"
    return objects[:, :3], "object"


def xyz(point: np.ndarray) -> tuple[float, float, float]:
    """A 3-D location as a tuple of Python floats (hashable, JSON-ready)."""
    return float(point[0]), float(point[1]), float(point[2])


def split_demonstrations(
    X: np.ndarray, lengths: Sequence[int], H: np.ndarray | None = None
) -> tuple[list[np.ndarray], list[np.ndarray] | None]:
    """Validate concatenated object poses ``X`` ``(N, 6)``, ``lengths`` and optional arm markers ``H``
    ``(N, 18)``, and split them per demonstration.

    Positions and markers must lie within :data:`MAX_COORDINATE_M` and rotation vectors within
    :data:`MAX_ROTATION_ANGLE_RAD`, so a corrupt frame is named here, not deep inside scipy.
    """
    if isinstance(X, (list, tuple)) and X and all(np.ndim(x) == 2 for x in X):
        raise InvalidInputError(f"X must be the demonstrations' object poses concatenated, (N, {OBJECT_DIM}), with "
                                "lengths; got a list of per-demonstration arrays: pass np.concatenate(trajectories) "
                                "and [len(t) for t in trajectories]")
    X, lengths = hmm_math.validate_sequences(X, lengths)
    if X.shape[1] != OBJECT_DIM:
        raise InvalidInputError(f"X must have {OBJECT_DIM} columns (object position in m, rotation vector in rad); "
                                f"got shape {X.shape}")
    _check_bound("X", np.abs(X[:, :3]).max(axis=1), lengths, MAX_COORDINATE_M, "an object coordinate of", "m",
                 "positions within +-{limit:g} m of the scene origin")
    with np.errstate(over="ignore"):
        angle = np.linalg.norm(X[:, 3:], axis=1)
    _check_bound("X", angle, lengths, MAX_ROTATION_ANGLE_RAD, "a rotation vector of angle", "rad",
                 "rotation vectors of angle <= {limit:.4g} rad (2 pi)")
    cuts = np.cumsum(lengths)[:-1]
    if H is None:
        return np.split(X, cuts), None
    try:
        H = np.asarray(H, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"H must be a numeric array of shape (N, {HAND_DIM}); got {exc}") from exc
    if H.shape != (len(X), HAND_DIM):
        raise InvalidInputError(f"H must have shape (N, {HAND_DIM}) = ({len(X)}, {HAND_DIM}), the arm markers "
                                f"(6 x xyz, m) of every frame of X; got shape {H.shape}")
    if not np.isfinite(H).all():
        raise InvalidInputError(f"H contains NaN or inf (first at row {np.argwhere(~np.isfinite(H))[0][0]}); "
                                "only finite values are accepted")
    _check_bound("H", np.abs(H).max(axis=1), lengths, MAX_COORDINATE_M, "a marker coordinate of", "m",
                 "marker positions within +-{limit:g} m of the scene origin")
    return np.split(X, cuts), np.split(H, cuts)


def _check_bound(name: str, size: np.ndarray, lengths: np.ndarray, limit: float, what: str, unit: str,
                 accepted: str) -> None:
    """Raise InvalidInputError naming the demonstration, frame and row of the first row of ``name`` whose
    ``size`` (N,) exceeds ``limit``.

    ``accepted`` says what is accepted, with ``{limit}`` standing for the limit.
    """
    rows = np.flatnonzero(size > limit)
    if len(rows):
        row = int(rows[0])
        starts = np.cumsum(lengths) - lengths
        demo = int(np.searchsorted(starts, row, side="right")) - 1
        raise InvalidInputError(f"{name} demonstration {demo} frame {row - starts[demo]} (row {row}) has {what} "
                                f"{size[row]:.3g} {unit} ({len(rows)} such frame(s)); "
                                f"accepted: {accepted.format(limit=limit)}")
