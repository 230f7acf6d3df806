"""Hand paths for the robot from the learned action models: approach, move and remove (the paper's Fig. 9).

Each primitive is synthesised by its whole-action PHMM (:meth:`ActionModels.synthesize_action`) in
the human demonstrator's scene, turned into a path of the robot's tcp and rescaled onto the exact
start and end the robot needs:

- **Which actions.** Approach and remove are the models' two hand-only actions; *move* is the
  manipulation action that lifts the object highest (:attr:`ActionModels.action_lifts_`): the one
  that carries rather than pushes. All three come out of the unsupervised pipeline.
- **Effect parameters** (human scene, m). Approach: the wrist's start (the models never saw it vary,
  the arm always starts from rest) and its end, the grasp point. Move: the object's start
  and end. Remove: the wrist's start, where the move left it, and its end at rest.
- **Hand point.** The robot's tcp is the point between its palm and thumb where a peg is held; its
  human counterpart is taken to be the wrist marker, the marker on which the approach's and the
  remove's effects are defined, so the one whose path the models learned best: the fingers' and
  knuckle's places around it depend on which of the block's faces the hand took, which the pooled
  models average (at the end of a synthesised approach the wrist holds still within 3 mm while the
  knuckle swings by 6 cm, measured). Its offset from the pinch is absorbed by the rescaling onto the
  endpoints. The hand's orientation is not transferred: the robot's whole-body IK keeps its tcp's
  z (the held peg's axis) vertical and chooses the heading (the human hand turns to a block's faces,
  the robot's hand holds a round peg from whatever side its arm reaches).
- **Over the table only.** The demonstrator's arm starts and ends hanging beside the chair, below
  the table top; a robot's hand rests above it. An approach is taken from where the hand point
  first rises over the table's height, a remove up to where it last sinks under it.
- **Scene map** (:class:`SceneMap`): one scale and one offset per axis,
  ``p_robot = scale * p_human + offset``. Across the table, the map of
  :func:`~hoap_actions.envs.world.human_to_robot` (the active region's width onto the work area's).
  Vertically, the learned carry's lift is mapped onto the lift the robot needs to pass a held peg's
  bottom over the board (:data:`CARRY_CLEARANCE` above its top): the human lifts a block off a bare
  table only as high as comfort asks, while the robot must clear a 2.5 cm board with a 5 cm peg, so
  a uniform 0.225 would lift the peg 1.6 cm and drive it into the board.
- **Rescaling onto the endpoints** (:func:`warp`). The synthesised path ends within a centimetre or
  two of the desired ones (a PHMM's state means follow phi only linearly); the robot needs them to
  a millimetre. The start error is faded out and the end error faded in along the normalised arc
  length with a quintic blend whose slope is zero at both ends, so the shape is kept, the ends are
  exact, and the path leaves and reaches them in its own directions (a carry's lift straight up, an
  approach's last descent straight down: a linear blend tilted them, and a peg whose bottom was
  dragged sideways over the table while the lift began tilted in the hand by 9 degrees, measured).
- **Smoothing.** Linearly interpolated state means have corners where the path turns; a Gaussian
  filter (:data:`SMOOTHING_S`) rounds them before the path is retimed under the hand's velocity,
  acceleration and jerk limits (:func:`~hoap_actions.controllers.retiming.retime_path`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d

from hoap_actions.controllers.hand_control import HAND_LIMITS, HandLimits
from hoap_actions.controllers.retiming import retime_path
from hoap_actions.envs import scene as scene_module
from hoap_actions.envs import world
from hoap_actions.errors import ExtrapolationWarning, InvalidInputError
from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION, REMOVE
from hoap_actions.primitives.models.action_models import ActionModels

__all__ = ["CARRY_CLEARANCE", "PHMMPaths", "SceneMap", "carry_action", "resample", "warp"]

CARRY_CLEARANCE = 0.01  # m, how far the learned carry's lift takes a held peg's bottom over the board's top
SMOOTHING_S = 0.05  # s, standard deviation of the Gaussian that rounds the interpolated state means
# m of arc length between the points a path is retimed through: the retimed path stays within 0.7 mm
# of the synthesised one (measured); closer points keep millimetre wiggles whose curvature sets the pace
RESAMPLE_SPACING = 0.02
DEMONSTRATION_FPS = 100.0  # Hz, the recordings' frame rate (the PHMM's time step)
HAND_MARKER = "wrist"


@dataclass(frozen=True)
class SceneMap:
    """``p_robot = scale * p_human + offset`` per axis (module docstring)."""

    scale: np.ndarray  # (3,)
    offset: np.ndarray  # (3,)

    @classmethod
    def for_models(cls, models: ActionModels) -> SceneMap:
        """Across the table the world's map; vertically the carry's learned lift onto the lift that
        takes a held peg's bottom :data:`CARRY_CLEARANCE` over the board."""
        lift = models.action_lifts_[carry_action(models)]
        needed = scene_module.BOARD_SIZE[2] + CARRY_CLEARANCE
        if lift <= 0:
            raise InvalidInputError("these models' manipulations never lift the object: none can carry a peg")
        xy = world.HUMAN_TO_ROBOT_SCALE
        return cls(scale=np.array([xy, xy, needed / lift]), offset=np.asarray(world.HUMAN_TO_ROBOT_OFFSET, float))

    def to_robot(self, points: np.ndarray) -> np.ndarray:
        return self.scale * np.asarray(points, float) + self.offset

    def to_human(self, points: np.ndarray) -> np.ndarray:
        return (np.asarray(points, float) - self.offset) / self.scale


def carry_action(models: ActionModels) -> int:
    """The manipulation action that lifts the object highest."""
    manipulations = [a for a, m in models.actions_.items() if m.kind == MANIPULATION]
    if not manipulations:
        raise InvalidInputError("these models have no manipulation action")
    return max(manipulations, key=lambda a: models.action_lifts_[a])


def _action_of_kind(models: ActionModels, kind: str) -> int:
    found = [a for a, m in models.actions_.items() if m.kind == kind]
    if not found:
        raise InvalidInputError(f"these models have no {kind} action")
    return found[0]


def over_the_table(path: np.ndarray, first: bool) -> np.ndarray:
    """The part of ``path`` (T, 3) after it first rises over the table's height (``first``), or before
    it last sinks under it; the whole path if it never crosses."""
    above = path[:, 2] > 0.0
    if above.all() or not above.any():
        return path
    if first:
        return path[int(np.argmax(above)):]
    return path[: len(path) - int(np.argmax(above[::-1]))]


def resample(path: np.ndarray, spacing: float, min_points: int = 2) -> np.ndarray:
    """``path`` (T, n) resampled at equal steps of arc length no longer than ``spacing``."""
    travelled = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    s = np.linspace(0.0, travelled[-1], max(min_points, int(np.ceil(travelled[-1] / spacing)) + 1))
    return np.stack([np.interp(s, travelled, path[:, i]) for i in range(path.shape[1])], axis=1)


def warp(path: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """``path`` (T, 3) moved onto ``start`` and ``end``: the start error fades out and the end error
    fades in along the normalised arc length ``u`` with the blend ``10 u^3 - 15 u^4 + 6 u^5``."""
    path = np.asarray(path, float)
    travelled = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    u = travelled / travelled[-1] if travelled[-1] > 0 else np.linspace(0.0, 1.0, len(path))
    w = u**3 * (10.0 - 15.0 * u + 6.0 * u**2)
    return path + (1.0 - w)[:, None] * (np.asarray(start) - path[0]) + w[:, None] * (np.asarray(end) - path[-1])


class PHMMPaths:
    """The robot's approach, move and remove hand paths from fitted action models (module docstring).

    Parameters
    ----------
    models
        fitted :class:`ActionModels` with an action level.
    limits
        the hand's Cartesian limits the paths are retimed under.
    dt
        the period the retimed paths are sampled at (s): one point per env step.
    """

    def __init__(self, models: ActionModels, limits: HandLimits = HAND_LIMITS,
                 dt: float = 1.0 / 30.0) -> None:
        if not models.actions_:
            raise InvalidInputError("the PHMM paths need models with an action level (hoap-actions learn makes them)")
        self.models = models
        self.map = SceneMap.for_models(models)
        self.limits, self.dt = limits, float(dt)
        self.approach_id = _action_of_kind(models, APPROACH)
        self.remove_id = _action_of_kind(models, REMOVE)
        self.move_id = carry_action(models)
        self._hand = models.marker_names_.index(HAND_MARKER)
        self._rest = self._training_mean(self.approach_id)[:3]  # where the demonstrator's wrist starts

    def _training_mean(self, action: int) -> np.ndarray:
        model = self.models.actions_[action]
        return model.centre + model.phmm.train_phi_.mean(axis=0) @ model.basis.T

    def _synthesize(self, action: int, phi: np.ndarray) -> np.ndarray:
        with warnings.catch_warnings():  # a layout's corner may lie a little beyond the demonstrations
            warnings.simplefilter("ignore", ExtrapolationWarning)
            return self.models.synthesize_action(action, phi)

    def _robot_path(self, markers: np.ndarray, start: np.ndarray, end: np.ndarray,
                    trim: bool | None = None) -> np.ndarray:
        """Hand-point path smoothed, cut to its part over the table (``trim``: True from where it
        rises, False up to where it sinks), mapped to the robot and warped onto ``start`` and ``end``."""
        human = gaussian_filter1d(markers[:, self._hand], SMOOTHING_S * DEMONSTRATION_FPS, axis=0, mode="nearest")
        if trim is not None:
            human = over_the_table(human, first=trim)
        return warp(self.map.to_robot(human), start, end)

    # ------------------------------------------------------------------ the three primitives (geometric)
    def approach(self, start: np.ndarray, grasp: np.ndarray) -> np.ndarray:
        """Tcp path (T, 3) from ``start`` to ``grasp`` (m), shaped by the approach action."""
        markers = self._synthesize(self.approach_id, np.r_[self._rest, self.map.to_human(grasp)])
        return self._robot_path(markers, start, grasp, trim=True)

    def move(self, start: np.ndarray, end: np.ndarray, object_start: np.ndarray, object_end: np.ndarray) -> np.ndarray:
        """Tcp path (T, 3) from ``start`` to ``end`` (m) carrying an object from ``object_start`` to
        ``object_end`` (m; they set the effect), shaped by the carry action."""
        z = self._training_mean(self.move_id)[[2, 5]]  # the demonstrations' object height
        a, b = self.map.to_human(object_start), self.map.to_human(object_end)
        markers = self._synthesize(self.move_id, np.r_[a[:2], z[0], b[:2], z[1]])
        return self._robot_path(markers, start, end)

    def remove(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Tcp path (T, 3) from ``start`` to ``end`` (m), shaped by the remove action."""
        markers = self._synthesize(self.remove_id,
                                   np.r_[self.map.to_human(start), self._training_mean(self.remove_id)[3:]])
        return self._robot_path(markers, start, end, trim=False)

    def timed(self, path: np.ndarray, limits: HandLimits | None = None) -> np.ndarray:
        """The path retimed under the hand's limits, one point (3,) per env step, ending at rest.
        It is first resampled every :data:`RESAMPLE_SPACING` of arc length: millimetre wiggles
        where the state means crowd would otherwise set a crawling pace for the whole path."""
        if np.allclose(path, path[-1]):
            return np.asarray(path[-1:], dtype=float)
        points = resample(path, RESAMPLE_SPACING, min_points=4)
        limits = limits or self.limits
        v, a, j = limits.velocity, limits.acceleration, limits.jerk
        return np.asarray(retime_path(points, v, a, j, dt=self.dt).position)
