"""Where the hand holds a peg: the hand's footprint over the table and the grasp it plans from it.

The hand is a palm plate and a thumb closing towards it, and the forearm stays about horizontal
(the IK keeps the peg axis, the tcp's z, vertical), so palm, open thumb and forearm sweep a wide
footprint behind the tcp. :func:`plan_grasp` asks the whole-body IK (pure queries,
:meth:`~hoap_actions.controllers.wholebody_ik.WholeBodyIK.probe`) how the hand is headed over the
peg, then picks where along the palm the peg will sit so that the footprint keeps clear of the other
pegs, and how high to hold it so that the palm clears the board. Both policies grasp this way; they
differ in how the hand gets there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hoap_actions.controllers.wholebody_ik import WholeBodyIK
from hoap_actions.envs import scene as scene_module

__all__ = ["GraspPlan", "board_outline", "footprint_clearance", "hand_axes", "plan_grasp", "thumb_outline"]

# ---------------------------------------------------------------------------- grasp
Z_GRASP_LOW = 0.038  # m, tcp z: palm from 1.8 cm, around the peg's upper 3 cm; low, so the hole is within reach
Z_GRASP_HIGH = 0.047  # m, tcp z: palm from 2.7 cm, clears the board's top (2.5 cm) when it lies under the palm
BOARD_CLEARANCE = 0.005  # m, footprint-to-board gap below which the high grasp is used
PRE_CLOSURE = 0.4  # gripper closure while coming down: thumb 21 deg open, a small footprint
GRASP_CLOSURE = 0.78  # 2 deg past contact (0.75): PyBullet squeezes in proportion; more pushes the peg out
PALM_CLEARANCE = 0.004  # m, peg centre off the palm line (towards the thumb) while coming down
PALM_GAP = 0.0005  # m, gap left between palm and peg before the thumb closes
GRASP_SHIFTS = (0.0, -0.006, 0.006)  # m, peg along the palm (tcp x); further out the grip is poor
CLEARANCE_GOAL = 0.006  # m, footprint-to-peg gap beyond which a grasp shift is good enough
REACH_PROBE_TOLERANCE = 0.0015  # m, IK hand error accepted at a planned point

# ---------------------------------------------------------------------------- hand footprint
# Outlines in the tcp frame (u along the forearm, v towards the palm; m), measured on hoap3.urdf.
PALM = np.array([[-0.051, 0.0075], [0.024, 0.0075], [0.024, 0.0155], [-0.051, 0.0155]])
FOREARM = np.array([[-0.19, -0.018], [-0.046, -0.018], [-0.046, 0.018], [-0.19, 0.018]])  # wrist to elbow
THUMB_CLOSED = np.array([[-0.041, -0.0155], [0.024, -0.0155], [0.024, -0.0075], [-0.041, -0.0075]])
THUMB_PIVOT = np.array([-0.038, -0.012])
THUMB_CONTACT_CLOSURE = 0.75  # closure at which the thumb lies parallel to the palm (on a 15 mm peg)
THUMB_RANGE = np.radians(60.0)  # rad of thumb rotation from open (0) to closed (1)


def thumb_outline(closure: float) -> np.ndarray:
    """The thumb plate's outline (4, 2) in the tcp frame at a gripper closure in [0, 1]."""
    angle = -(THUMB_CONTACT_CLOSURE - closure) * THUMB_RANGE  # outwards, about the hand's z
    c, s = np.cos(angle), np.sin(angle)
    return THUMB_PIVOT + (THUMB_CLOSED - THUMB_PIVOT) @ np.array([[c, s], [-s, c]])


def _distance_to_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance (m) from each point (N, 2) to a convex polygon (K, 2); 0 inside."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    ab = b - a
    ap = points[:, None, :] - a[None]
    t = np.clip((ap * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    distance = np.linalg.norm(ap - t[..., None] * ab, axis=-1).min(axis=1)
    cross = ab[:, 0] * ap[..., 1] - ab[:, 1] * ap[..., 0]
    inside = np.all(cross >= 0.0, axis=1) | np.all(cross <= 0.0, axis=1)
    return np.where(inside, 0.0, distance)


def footprint_clearance(points_uv: np.ndarray, radius: float, closure: float = PRE_CLOSURE) -> float:
    """Least gap (m) between the hand's footprint and discs of ``radius`` at ``points_uv`` (N, 2),
    given in the tcp frame; ``inf`` for no points."""
    if len(points_uv) == 0:
        return np.inf
    parts = (PALM, FOREARM, thumb_outline(closure))
    return float(np.min([_distance_to_polygon(points_uv, part) for part in parts]) - radius)


def hand_axes(rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal unit vectors along the forearm (tcp x) and from thumb to palm (tcp y), from the
    tcp's rotation matrix (3, 3)."""
    x = rotation[:2, 0] / np.linalg.norm(rotation[:2, 0])
    return x, np.array([-x[1], x[0]])


def board_outline(holes: np.ndarray, spacing: float = 0.005) -> np.ndarray:
    """Points (N, 2) every ``spacing`` m along the board's outline, from its hole centres (N_HOLES, 3)."""
    centre = holes[:, :2].mean(axis=0)
    along = holes[-1, :2] - holes[0, :2]
    along /= np.linalg.norm(along)
    across = np.array([-along[1], along[0]])
    half = np.array(scene_module.BOARD_SIZE[:2]) / 2  # (across, along) in the board's frame
    corners = [centre + sx * half[0] * across + sy * half[1] * along for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
    points = []
    for a, b in zip(corners, corners[1:] + corners[:1]):
        n = max(2, int(np.linalg.norm(b - a) / spacing))
        points += [a + (b - a) * t for t in np.linspace(0.0, 1.0, n, endpoint=False)]
    return np.array(points)


def grasp_xy(peg: np.ndarray, shift: float, clearance: float, axes: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Tcp xy that puts the peg ``shift`` along the palm (tcp x) and ``clearance`` off it, thumb-wards."""
    x, y = axes
    return np.asarray(peg, dtype=float)[:2] - shift * x + clearance * y


@dataclass(frozen=True)
class GraspPlan:
    """Where the peg will sit in the hand: ``shift`` along the palm (m), the tcp height ``z`` (m) to
    grasp at, and the hand's ``axes`` over the peg (forearm, thumb-to-palm; from the IK)."""

    shift: float
    z: float
    axes: tuple[np.ndarray, np.ndarray]

    def tcp(self, peg: np.ndarray, clearance: float = PALM_CLEARANCE) -> np.ndarray:
        """The tcp position (3,) over ``peg`` with the palm ``clearance`` off it."""
        return np.array([*grasp_xy(peg, self.shift, clearance, self.axes), self.z])


def plan_grasp(ik: WholeBodyIK, peg: np.ndarray, others: np.ndarray, holes: np.ndarray,
               shifts: tuple[float, ...] = GRASP_SHIFTS) -> GraspPlan | None:
    """The grasp of the peg at ``peg`` (3,) whose footprint keeps clearest of the ``others`` (k, 3)
    and of the board (from its ``holes``), trying ``shifts`` in order; None if the IK cannot bring
    the hand down to it."""
    probe = ik.probe([*peg[:2], Z_GRASP_LOW])
    if probe.error > REACH_PROBE_TOLERANCE:
        return None
    axes = hand_axes(probe.rotation)
    x, y = axes
    board = board_outline(holes)
    best = None
    for shift in shifts:
        tcp = grasp_xy(peg, shift, PALM_CLEARANCE, axes)
        rel_pegs, rel_board = np.asarray(others, float).reshape(-1, 3)[:, :2] - tcp, board - tcp
        gap = footprint_clearance(np.c_[rel_pegs @ x, rel_pegs @ y], scene_module.PEG_RADIUS)
        board_gap = footprint_clearance(np.c_[rel_board @ x, rel_board @ y], 0.0)
        if best is None or min(gap, CLEARANCE_GOAL) > min(best[1], CLEARANCE_GOAL):
            best = (shift, gap, board_gap)
        if gap >= CLEARANCE_GOAL:
            break
    shift, _, board_gap = best
    return GraspPlan(shift=shift, z=Z_GRASP_HIGH if board_gap < BOARD_CLEARANCE else Z_GRASP_LOW, axes=axes)
