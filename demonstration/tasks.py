"""What a demonstration is: the tasks the simulated demonstrator performs and what one episode records.

The frame rate, the markers, the phase labels (and the version of that labelling), the push / move /
rotate directions, :class:`DemoTask` and :class:`DemoRecording`. How the demonstrator performs a task
is :mod:`hoap_actions.demonstration.demonstrator`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError

FPS = 100  # Hz, recorded frames (like the VICON system)
MARKER_NAMES = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")
DIRECTIONS = {"left": (0.0, 1.0), "right": (0.0, -1.0), "forward": (1.0, 0.0), "backward": (-1.0, 0.0)}
"""Push/move directions in the scene frame: left = +y, right = -y, forward = +x (away from the
demonstrator; the paper's "up"), backward = -x (towards them; "down")."""
TURNS = {"ccw": 1.0, "cw": -1.0}  # rotate directions, seen from above
ACTIONS = ("push", "move", "rotate", "approach")
PHASE_NAMES = ("approach", *(f"push-{d}" for d in DIRECTIONS), *(f"move-{d}" for d in DIRECTIONS), "rotate", "remove")
"""Phase label table: a frame's label code indexes this tuple."""
LABELS_VERSION = 2
"""Which frames get which phase label (:mod:`hoap_actions.demonstration.demonstrator`). 1 (datasets
without ``labels_version``): the grasp, the hold and release after a carry or turn, the push path's
initial gap and the push's ease-off were labelled with the manipulation. 2: the grasp and the initial
gap are approach, letting go is remove."""


@dataclass(frozen=True)
class DemoTask:
    """One episode to perform: the action, its parameters and where the block starts.

    ``direction`` is a key of :data:`DIRECTIONS` for push/move, of :data:`TURNS` for rotate, ``""`` for
    approach; ``distance`` (m) is for push/move, ``angle`` (rad, > 0) for rotate. ``grid`` and
    ``grid_index`` (row, column) name an approach-grid location, ``repetition`` counts repeats.
    """

    action: str
    object_xy: tuple[float, float]
    object_yaw: float = 0.0
    direction: str = ""
    distance: float = 0.0
    angle: float = 0.0
    repetition: int = 0
    grid: str = ""
    grid_index: tuple[int, int] = (-1, -1)

    def __post_init__(self) -> None:
        if self.action not in ACTIONS:
            raise InvalidInputError(f"action must be one of {ACTIONS}; got {self.action!r}")
        allowed = {"push": DIRECTIONS, "move": DIRECTIONS, "rotate": TURNS, "approach": {"": None}}[self.action]
        if self.direction not in allowed:
            raise InvalidInputError(f"a {self.action} takes direction in {sorted(allowed)}; got {self.direction!r}")
        if self.action in ("push", "move") and not 0.0 < self.distance <= 0.30:
            raise InvalidInputError(f"a {self.action} distance must be in (0, 0.30] m; got {self.distance}")
        if self.action == "rotate" and not 0.0 < self.angle <= np.pi / 2:
            raise InvalidInputError(f"a rotate angle must be in (0, pi/2] rad; got {self.angle}")
        if len(self.object_xy) != 2 or not np.all(np.isfinite(self.object_xy)) or not np.isfinite(self.object_yaw):
            raise InvalidInputError(f"object_xy must be 2 finite numbers; got {self.object_xy}")

    @property
    def phase(self) -> str:
        """The manipulation's phase label (``"push-left"``, ``"rotate"``, ...; ``"approach"`` for a bare approach)."""
        return {"push": f"push-{self.direction}", "move": f"move-{self.direction}", "rotate": "rotate"}.get(
            self.action, "approach"
        )

    def target_pose(self, start: np.ndarray) -> np.ndarray:
        """The block pose (6,) the action aims at from ``start`` (position m + rotation vector rad)."""
        target = np.array(start, float)
        if self.action in ("push", "move"):
            target[:2] += self.distance * np.array(DIRECTIONS[self.direction])
        elif self.action == "rotate":
            turn = Rotation.from_euler("z", TURNS[self.direction] * self.angle)
            target[3:] = (turn * Rotation.from_rotvec(start[3:])).as_rotvec()
        return target


@dataclass(frozen=True)
class DemoRecording:
    """What one performed episode produced (scene frame, SI units).

    ``H`` (T, 6, 3) markers in :data:`MARKER_NAMES` order; ``O`` (T, 6) block position + rotation vector;
    ``labels`` (T,) codes into :data:`PHASE_NAMES`; ``object_target`` (6,) the intended end pose;
    ``hand_rest`` (3,) the palm centre at rest before the approach; ``grasped`` whether a grasp
    constraint was made; ``table_contact_frames`` frames in which the hand touched the table; ``Q``
    (T, J) the joint angles of :data:`RECORDED_JOINTS` (rad), which pose the body for a camera.
    """

    H: np.ndarray
    O: np.ndarray
    labels: np.ndarray
    object_target: np.ndarray
    hand_rest: np.ndarray
    Q: np.ndarray
    grasped: bool = False
    table_contact_frames: int = 0

