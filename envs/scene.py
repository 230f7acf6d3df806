"""The table-top scene: floor, table, a hole board and coloured pegs, their random layouts and the success test.

Geometry (SI units; the URDFs in ``urdf/`` carry the same numbers and ``tests/test_scene.py`` measures
them on the loaded bodies): pegs are cylinders 15 mm across and 50 mm long; the board has three square
holes 17 mm wide (1 mm clearance a side), 25 mm deep down to the table top, with a 2.5 mm 45-degree
chamfer at each opening, in a row along the board's own y axis. Hole ``j`` sits at board-local
``y = (j - 1) * HOLE_PITCH``, so with the sampled yaws (within +-30 degrees) hole 0 is the one at the
most negative world y (the robot's right). Quaternions are ``(x, y, z, w)`` as PyBullet gives them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from hoap_actions.envs import world
from hoap_actions.envs.camera import Camera
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError

PEG_RADIUS = 0.0075  # m
PEG_LENGTH = 0.05  # m
PEG_MASS = 0.01  # kg, as in peg.urdf
PEG_LATERAL_FRICTION = 1.0  # the hand holds pegs by friction alone
PEG_SPINNING_FRICTION = 0.002  # a peg spun on its end at 10 rad/s stops in ~0.02 s, as a flat end would
PEG_ROLLING_FRICTION = 0.001  # a fallen peg rolling at 0.1 m/s stops within ~2 cm, not off the table
BOARD_FRICTION = 0.3  # smooth board: a peg that lands on a chamfer slides in rather than tipping over
TABLE_FRICTION = 0.5
PEG_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "red": (0.85, 0.12, 0.10, 1.0),
    "green": (0.10, 0.65, 0.20, 1.0),
    "blue": (0.10, 0.25, 0.85, 1.0),
}

BOARD_SIZE = (0.040, 0.110, 0.025)  # m: across the hole row (x), along it (y), depth (z)
N_HOLES = 3
HOLE_SIZE = 0.017  # m, side of the square hole: 1 mm clearance around a 15 mm peg
HOLE_PITCH = 0.035  # m, hole centre to hole centre
CHAMFER = 0.0025  # m, width (and depth) of the 45-degree chamfer at each opening
HOLE_LOCAL_XY = np.array([[0.0, (j - (N_HOLES - 1) / 2) * HOLE_PITCH] for j in range(N_HOLES)])

BOARD_YAW_RANGE = (-math.pi / 6, math.pi / 6)  # rad; keeps hole 0 on the robot's right
MIN_PEG_SPACING = 0.04  # m, peg centre to peg centre in sampled layouts: room for the hand
MIN_PEG_BOARD_GAP = 0.04  # m, peg centre to the board's outline in sampled layouts
# A peg grasped from above has the forearm behind it, pointing back to world.FOREARM_PIVOT_XY: no
# other peg may stand in that strip (forearm half-width 18 mm + peg radius + 5 mm, widening with the
# heading's 15-degree uncertainty), or the forearm comes down on it.
FOREARM_LENGTH = 0.20  # m, from the grasp point back along the forearm
FOREARM_STRIP_HALF_WIDTH = 0.018 + PEG_RADIUS + 0.005  # m
FOREARM_HEADING_TOLERANCE = math.tan(math.radians(15.0))
TABLE_MARGIN = 0.005  # m, the board stays this far inside the table's edges
PHYSICAL_GAP = 0.001  # m, the least gap :meth:`Scene.apply` accepts between any two objects
MAX_LAYOUT_TRIES = 1000

CAMERAS: dict[str, Camera] = {
    # Straight down from 0.75 m with a narrow lens (nearly orthographic, ~1.2 mm per pixel): sees
    # every board and peg position a layout can produce. Image up is +x (away from the robot).
    "overhead": Camera(
        eye=(0.02, 0.0, 0.75), target=(0.02, 0.0, 0.0), up=(1.0, 0.0, 0.0), fov_deg=22.0, near=0.3, far=1.2
    ),
    # From over the table's far right corner, 48 cm from the work area: close enough to see a grasp
    # and an insertion, beside the arm rather than behind it.
    "closeup": Camera(eye=(0.2, -0.3, 0.3), target=(0.0, 0.0, 0.03), fov_deg=38.0, near=0.05, far=2.0),
    # Across the table, facing the robot: head to feet, both arms, the table top and the board.
    "front": Camera(
        eye=(0.8, world.ROBOT_FEET_XY[1], 0.25), target=(*world.ROBOT_FEET_XY, 0.06), fov_deg=45.0, near=0.1, far=2.0
    ),
}


@dataclass(frozen=True)
class Layout:
    """Where the board and pegs stand: board centre (m) and yaw (rad), peg centres (m), and targets.

    Peg ``i`` belongs in hole ``hole_of_peg[i]`` (distinct holes); tasks may use or ignore it.
    """

    board_xy: tuple[float, float]
    board_yaw: float
    peg_xy: tuple[tuple[float, float], ...]
    hole_of_peg: tuple[int, ...]


DEFAULT_LAYOUT = Layout(
    board_xy=(0.03, 0.0),
    board_yaw=0.0,
    peg_xy=((-0.03, -0.06), (-0.03, 0.0), (-0.03, 0.06)),
    hole_of_peg=(0, 1, 2),
)


class Scene:
    """Loads the floor, table, hole board and ``n_pegs`` pegs (red, green, blue) into ``sim``.

    Also registers the ``"overhead"`` and ``"front"`` cameras in ``sim.cameras``. Bodies are named
    ``"floor"``, ``"table"``, ``"hole_board"`` and ``"peg_<colour>"`` (see :attr:`peg_names`).
    """

    def __init__(self, sim: Sim, n_pegs: int = 3) -> None:
        if not 1 <= int(n_pegs) <= N_HOLES:
            raise InvalidInputError(f"n_pegs={n_pegs!r}; accepted: an integer from 1 to {N_HOLES} (one hole each)")
        self.sim = sim
        self.n_pegs = int(n_pegs)
        self._board: tuple[int, np.ndarray, float, np.ndarray] | None = None  # placements, centre, yaw, holes
        table_centre_x = world.TABLE_NEAR_EDGE_X + world.TABLE_SIZE[0] / 2
        sim.load_urdf("floor", "floor.urdf", (0.0, 0.0, world.FLOOR_Z), fixed_base=True)
        sim.load_urdf("table", "table.urdf", (table_centre_x, 0.0, 0.0), fixed_base=True)
        sim.load_urdf("hole_board", "hole_board.urdf", (0.0, 0.0, BOARD_SIZE[2] / 2), fixed_base=True)
        sim.set_dynamics("table", lateralFriction=TABLE_FRICTION)
        sim.set_dynamics("hole_board", lateralFriction=BOARD_FRICTION)
        self.peg_names: list[str] = [f"peg_{colour}" for colour in list(PEG_COLOURS)[: self.n_pegs]]
        for i, name in enumerate(self.peg_names):
            # exact cylinders: PyBullet's default hull would act 17 mm wide, as wide as the holes
            sim.load_urdf(name, "peg.urdf", (0.0, 0.1 * i, 1.0), implicit_cylinders=True)
            sim.set_color(name, PEG_COLOURS[name.removeprefix("peg_")])
            sim.let_sleep(name)  # a resting peg costs a third of the welded robot's physics
            sim.set_dynamics(
                name,
                lateralFriction=PEG_LATERAL_FRICTION,
                spinningFriction=PEG_SPINNING_FRICTION,
                rollingFriction=PEG_ROLLING_FRICTION,
            )
        sim.cameras.update(CAMERAS)
        n = self.n_pegs
        self.apply(replace(DEFAULT_LAYOUT, peg_xy=DEFAULT_LAYOUT.peg_xy[:n], hole_of_peg=tuple(range(n))))

    # ------------------------------------------------------------------ layouts
    def sample_layout(self, rng: np.random.Generator) -> Layout:
        """Draw a layout: board centre and pegs inside the work area, pegs apart, board on the table,
        every hole within the right hand's reach (``world.HAND_REACH_XY``) and no peg in the strip the
        forearm sweeps when it comes down on another (:func:`in_forearm_strip`): every peg can be
        grasped and put in every hole.

        Rejection sampling whose draws depend on nothing but ``rng``: the same Generator state gives the
        same layout.
        """
        low, high = world.WORK_AREA_LOW, world.WORK_AREA_HIGH
        for _ in range(MAX_LAYOUT_TRIES):
            board_xy = rng.uniform(low, high)
            yaw = float(rng.uniform(*BOARD_YAW_RANGE))
            if not _board_on_table(board_xy, yaw, TABLE_MARGIN):
                continue
            if not np.all(within_reach(_holes_xy(board_xy, yaw))):
                continue
            pegs: list[np.ndarray] = []
            for _ in range(50 * self.n_pegs):
                xy = rng.uniform(low, high)
                if distance_to_board(xy, board_xy, yaw) >= MIN_PEG_BOARD_GAP and all(
                    np.hypot(*(xy - other)) >= MIN_PEG_SPACING
                    and not in_forearm_strip(xy, other)
                    and not in_forearm_strip(other, xy)
                    for other in pegs
                ):
                    pegs.append(xy)
                    if len(pegs) == self.n_pegs:
                        holes = rng.permutation(N_HOLES)[: self.n_pegs]
                        return Layout(
                            board_xy=(float(board_xy[0]), float(board_xy[1])),
                            board_yaw=yaw,
                            peg_xy=tuple((float(x), float(y)) for x, y in pegs),
                            hole_of_peg=tuple(int(j) for j in holes),
                        )
        raise RuntimeError(f"no valid layout in {MAX_LAYOUT_TRIES} board draws; the work area is too small")

    def apply(self, layout: Layout) -> None:
        """Teleport the board and stand every peg upright at its place, all at rest, just touching the table.

        Raises :class:`InvalidInputError` for layouts that would start in collision or off the table.
        """
        problem = self._layout_problem(layout)
        if problem:
            raise InvalidInputError(f"layout cannot be placed: {problem}")
        x, y = layout.board_xy
        self.sim.set_base_pose("hole_board", (x, y, BOARD_SIZE[2] / 2), _yaw_quat(layout.board_yaw))
        for name, (px, py) in zip(self.peg_names, layout.peg_xy):
            self.sim.set_base_pose(name, (px, py, PEG_LENGTH / 2), (0.0, 0.0, 0.0, 1.0))

    def _layout_problem(self, layout: Layout) -> str | None:
        """Why ``layout`` cannot be placed without collisions (None if it can)."""
        if len(layout.peg_xy) != self.n_pegs or len(layout.hole_of_peg) != self.n_pegs:
            counts = f"{len(layout.peg_xy)} pegs and {len(layout.hole_of_peg)} targets"
            return f"it has {counts}; this scene has {self.n_pegs}"
        holes = layout.hole_of_peg
        if len(set(holes)) != len(holes) or not all(0 <= j < N_HOLES for j in holes):
            return f"hole_of_peg={layout.hole_of_peg} must be distinct hole indices in 0..{N_HOLES - 1}"
        values = np.array([*layout.board_xy, layout.board_yaw, *np.ravel(layout.peg_xy)], dtype=float)
        if not np.all(np.isfinite(values)):
            return "it contains NaN or inf"
        board_xy = np.asarray(layout.board_xy, float)
        if not _board_on_table(board_xy, layout.board_yaw, 0.0):
            return f"the board at {layout.board_xy} (yaw {layout.board_yaw:.3f} rad) overhangs the table"
        pegs = np.asarray(layout.peg_xy, float)
        for i, xy in enumerate(pegs):
            if not _on_table(xy, PEG_RADIUS):
                return f"peg {i} at {tuple(xy)} is off the table"
            if distance_to_board(xy, board_xy, layout.board_yaw) < PEG_RADIUS + PHYSICAL_GAP:
                return f"peg {i} at {tuple(xy)} overlaps the board"
            for k in range(i):
                if np.hypot(*(xy - pegs[k])) < 2 * PEG_RADIUS + PHYSICAL_GAP:
                    return f"pegs {k} and {i} overlap"
        return None

    # ------------------------------------------------------------------ queries
    @property
    def board_surface_z(self) -> float:
        """Height (m) of the board's top surface: the plane of the hole openings."""
        return BOARD_SIZE[2]

    def board_pose(self) -> tuple[np.ndarray, float]:
        """Board centre ``(2,)`` in the table plane (m) and yaw (rad), read from the simulator."""
        _, centre, yaw, _ = self._board_state()
        return centre.copy(), yaw

    def hole_positions(self) -> np.ndarray:
        """World centres ``(N_HOLES, 3)`` (m) of the hole openings, on the board's top surface."""
        return self._board_state()[3].copy()

    def _board_state(self) -> tuple[int, np.ndarray, float, np.ndarray]:
        """The board's pose and holes, read again only after something was placed: the board has a fixed
        base, so stepping never moves it (read twice a step before, by the observation and the success test)."""
        if self._board is None or self._board[0] != self.sim.placements:
            pos, quat = self.sim.base_pose("hole_board")
            centre, yaw = pos[:2], 2.0 * math.atan2(quat[2], quat[3])
            holes = np.column_stack([_holes_xy(centre, yaw), np.full(N_HOLES, self.board_surface_z)])
            self._board = (self.sim.placements, centre, yaw, holes)
        return self._board

    def peg_pose(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Centre (3,) and quaternion (x, y, z, w) of peg ``i``; its axis is the quaternion's z axis."""
        return self.sim.base_pose(self.peg_names[i])

    def peg_in_hole(self, i: int, j: int, tilt_tol_deg: float = 10.0, min_depth: float = 0.01) -> bool:
        """Whether peg ``i`` stands in hole ``j``: upright within ``tilt_tol_deg`` with its bottom centre
        inside the hole's square and at least ``min_depth`` (m) below the board surface.

        Cheap enough for every env step: two pose reads and a few arithmetic operations.
        """
        if not (0 <= i < self.n_pegs and 0 <= j < N_HOLES):
            raise InvalidInputError(f"peg {i}, hole {j}; accepted: pegs 0..{self.n_pegs - 1}, holes 0..{N_HOLES - 1}")
        pos, quat = self.sim.base_pose(self.peg_names[i])
        qx, qy, qz, qw = quat
        axis = np.array([2 * (qx * qz + qw * qy), 2 * (qy * qz - qw * qx), 1 - 2 * (qx * qx + qy * qy)])
        if axis[2] < math.cos(math.radians(tilt_tol_deg)):
            return False
        bottom = pos - 0.5 * PEG_LENGTH * axis
        if bottom[2] > self.board_surface_z - min_depth:
            return False
        _, centre, yaw, _ = self._board_state()
        local = _rotation(yaw).T @ (bottom[:2] - centre) - HOLE_LOCAL_XY[j]
        return bool(np.all(np.abs(local) <= HOLE_SIZE / 2))


def within_reach(xy: np.ndarray) -> np.ndarray:
    """Whether points ``(..., 2)`` of the table plane lie inside ``world.HAND_REACH_XY``."""
    xy = np.asarray(xy, dtype=float)
    a = world.HAND_REACH_XY
    edges = np.roll(a, -1, axis=0) - a
    rel = xy[..., None, :] - a  # (..., K, 2)
    cross = edges[:, 0] * rel[..., 1] - edges[:, 1] * rel[..., 0]
    return np.all(cross >= 0.0, axis=-1)


def in_forearm_strip(xy: np.ndarray, grasped: np.ndarray) -> bool:
    """Whether a peg at ``xy`` stands where the forearm comes down when the hand grasps the peg at
    ``grasped`` from above: behind it, towards ``world.FOREARM_PIVOT_XY``, within the strip's width."""
    back = world.FOREARM_PIVOT_XY - np.asarray(grasped, dtype=float)
    back /= np.linalg.norm(back)
    rel = np.asarray(xy, dtype=float) - np.asarray(grasped, dtype=float)
    along = float(rel @ back)
    across = abs(float(rel[0] * back[1] - rel[1] * back[0]))
    return 0.0 < along <= FOREARM_LENGTH and across < FOREARM_STRIP_HALF_WIDTH + FOREARM_HEADING_TOLERANCE * along


def _yaw_quat(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def _rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _holes_xy(board_xy: np.ndarray, yaw: float) -> np.ndarray:
    """Table-plane centres ``(N_HOLES, 2)`` of the holes of a board at ``board_xy`` turned by ``yaw``."""
    return np.asarray(board_xy) + HOLE_LOCAL_XY @ _rotation(yaw).T


def _board_corners(board_xy: np.ndarray, yaw: float) -> np.ndarray:
    half = np.array(BOARD_SIZE[:2]) / 2
    corners = np.array([[1, 1], [1, -1], [-1, -1], [-1, 1]]) * half
    return np.asarray(board_xy) + corners @ _rotation(yaw).T


def _on_table(xy: np.ndarray, margin: float) -> bool:
    x_min = world.TABLE_NEAR_EDGE_X + margin
    x_max = world.TABLE_NEAR_EDGE_X + world.TABLE_SIZE[0] - margin
    y_half = world.TABLE_SIZE[1] / 2 - margin
    return bool(np.all((x_min <= xy[..., 0]) & (xy[..., 0] <= x_max) & (np.abs(xy[..., 1]) <= y_half)))


def _board_on_table(board_xy: np.ndarray, yaw: float, margin: float) -> bool:
    return _on_table(_board_corners(board_xy, yaw), margin)


def distance_to_board(xy: np.ndarray, board_xy: np.ndarray, yaw: float) -> float:
    """Distance (m) from a point in the table plane to the board's rectangular outline (0 inside)."""
    local = _rotation(yaw).T @ (np.asarray(xy) - np.asarray(board_xy))
    outside = np.maximum(np.abs(local) - np.array(BOARD_SIZE[:2]) / 2, 0.0)
    return float(np.hypot(*outside))
