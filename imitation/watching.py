"""What a demonstration did, seen through its camera alone: the action tracker follows the person's arm
with the action models; the block, located by its colour, tells what was done to it.

The tracker (:class:`~hoap_actions.tracking.action_tracker.ActionTracker`, edges, silhouette against the
demonstration's picture of the empty table, and the block's blob) gives every frame's most probable class
and the arm's markers: the recognised class sequence and the manipulation's frames (the first to the
last it gives a manipulation class). The block rests in the first and last frames: its top face there
(:meth:`~hoap_actions.vision.objects.ObjectLocator.top_face`) gives its start, end and turn; a block
turned was rotated. A square face shows its turn modulo a quarter, which is all the cube's symmetry lets
matter. A carried block is told from a pushed one by where its blob, taken onto the plane of a resting
block's centre, goes meanwhile: a raised block's image falls beyond its path on the table, away from the
camera, while a pushed one stays on it. The body model is the reference demonstrator's: the robot is not
told who demonstrates.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.demonstration.bodies import DEMONSTRATORS
from hoap_actions.demonstration.scene import DemoScene, DemoSceneConfig
from hoap_actions.envs.camera import Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.demonstrations import Demonstration
from hoap_actions.imitation.reading import MOVED, STILL_TURN, DemonstrationReading
from hoap_actions.primitives.discovery.estimator import MANIPULATION
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.tracking.action_tracker import ActionTracker, TrackedFrame
from hoap_actions.tracking.tracking_models import TrackingModels
from hoap_actions.vision.body_model import BodyModel
from hoap_actions.vision.edges import edge_image
from hoap_actions.vision.objects import ObjectLocator, TopFace
from hoap_actions.vision.silhouette import BackgroundSubtractor

__all__ = ["CARRIED_SHIFT", "QUARTER_TURNED", "REST_FRAMES", "WatchedDemonstration", "carried_shift", "watch"]

REST_FRAMES = 10  # frames at each end of the demonstration in which the block's top face is looked for
QUARTER_TURNED = np.radians(15.0)  # rad, a turn modulo a quarter this large was a rotate (60 degrees show as 30)
# m, a block whose blob went this far beyond its start-end line, away from the camera, was carried: on the
# validation episodes 90000-90059 pushes went at most 4.2 cm (the hand over the block shifts its blob),
# carries 3.8 to 13.7 cm
CARRIED_SHIFT = 0.04
TABLE_TOP_Z = 0.0  # m, the demonstration table's top: what is below it the camera cannot see


@dataclass(frozen=True)
class WatchedDemonstration:
    """A demonstration watched: the ``reading`` (as :func:`~hoap_actions.imitation.reading.read_markers`
    gives one from markers; ``action`` None when the block's top face was not seen at rest at both ends),
    the tracker's ``frames``, its wall time ``track_s`` and the block's :func:`carried_shift` ``shift_m``."""

    reading: DemonstrationReading
    frames: list[TrackedFrame]
    track_s: float
    shift_m: float


@functools.lru_cache(maxsize=4)
def _torso_base(height_m: float) -> np.ndarray:
    scene = DemoScene(body_height_m=height_m)
    try:
        return scene.torso_base()
    finally:
        scene.close()


def _resting_face(locate: ObjectLocator, frames: np.ndarray) -> TopFace | None:
    """The block's top face over resting frames: the median centre and the circular mean turn (period a
    quarter) of the frames that show it."""
    faces = [face for face in (locate.top_face(frame) for frame in frames) if face is not None]
    if not faces:
        return None
    yaw = float(np.angle(np.mean(np.exp(4j * np.array([face.yaw for face in faces])))) / 4.0)
    return TopFace(np.median([face.centre for face in faces], axis=0), yaw)


def carried_shift(centres: np.ndarray, camera: Camera, rest_frames: int = REST_FRAMES) -> float:
    """How far (m) the block's seen centres ``(T, 2)`` (NaN: not seen) went beyond the line from where it
    rested first to where it rested last, along the camera's horizontal viewing direction."""
    seen = centres[np.isfinite(centres).all(axis=1)]
    if len(seen) < 2 * rest_frames:
        return 0.0
    start, end = seen[:rest_frames].mean(axis=0), seen[-rest_frames:].mean(axis=0)
    line = end - start
    length = float(line @ line)
    along = np.clip((seen - start) @ line / length, 0.0, 1.0) if length > 1e-12 else np.zeros(len(seen))
    away = (np.asarray(camera.target, float) - np.asarray(camera.eye, float))[:2]
    away /= np.linalg.norm(away)
    return float(np.max((seen - (start + along[:, None] * line)) @ away))


def _pose(face: TopFace, half_size: float) -> np.ndarray:
    centre = np.array([face.centre[0], face.centre[1], half_size])
    return np.concatenate([centre, Rotation.from_euler("z", face.yaw).as_rotvec()])


def watch(models: ActionModels, demonstration: Demonstration, particles: int = 400,
          seed: int = 0) -> WatchedDemonstration:
    """Track ``demonstration``'s frames with ``models`` and read what it did (module docstring)."""
    frames = np.asarray(demonstration.frames)
    camera = demonstration.camera
    if frames.ndim != 4 or len(frames) < 2 * REST_FRAMES or frames.shape[1:3] != (camera.height, camera.width):
        raise InvalidInputError(f"a demonstration's frames must be (T, {camera.height}, {camera.width}, 3) with T >= "
                                f"{2 * REST_FRAMES}; got {frames.shape}")
    size = DemoSceneConfig().object_size
    body = BodyModel(models.marker_names_, torso_base=_torso_base(DEMONSTRATORS["reference"].height_m),
                     hidden_below_z=TABLE_TOP_Z)
    tracker = ActionTracker(TrackingModels.from_action_models(models), body, camera, n_particles=particles,
                            random_state=seed)
    subtract = BackgroundSubtractor(demonstration.background)
    locate_centre, locate_top = ObjectLocator(camera, size / 2.0), ObjectLocator(camera, size)
    started = time.perf_counter()
    tracked, centres = [], np.full((len(frames), 2), np.nan)
    for t, frame in enumerate(frames):
        seen = locate_centre(frame)
        if seen is not None:
            centres[t] = seen[:2]
        tracked.append(tracker.step(edge_image(frame), subtract(frame), seen))
    track_s = time.perf_counter() - started
    first, last = _resting_face(locate_top, frames[:REST_FRAMES]), _resting_face(locate_top, frames[-REST_FRAMES:])
    classes = np.array([frame.class_id for frame in tracked])
    manipulations = [c for c, model in models.classes_.items() if model.kind == MANIPULATION]
    moving = np.flatnonzero(np.isin(classes, manipulations))
    manipulation = None if not moving.size else (int(moving[0]), int(moving[-1]) + 1)
    run_classes = tuple(int(c) for i, c in enumerate(classes) if i == 0 or c != classes[i - 1])
    shift = carried_shift(centres, camera)
    if first is None or last is None:
        nan = np.full(6, np.nan)
        return WatchedDemonstration(DemonstrationReading(None, nan, nan, run_classes, manipulation), tracked,
                                    track_s, shift)
    start, end = _pose(first, size / 2.0), _pose(last, size / 2.0)
    turn = abs(float(np.angle(np.exp(4j * (last.yaw - first.yaw))) / 4.0))
    if np.linalg.norm(end[:2] - start[:2]) < MOVED and turn < STILL_TURN:
        action = "approach"
    elif turn >= QUARTER_TURNED:
        action = "rotate"
    elif shift >= CARRIED_SHIFT:
        action = "move"
    else:
        action = "push"
    return WatchedDemonstration(DemonstrationReading(action, start, end, run_classes, manipulation), tracked,
                                track_s, shift)
