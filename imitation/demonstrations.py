"""The demonstrations ``Imitate-v0`` shows: drawn and performed at reset, or replayed from a recording,
and seen through the demonstration world's camera.

A drawn demonstration is one of the paper preset's kinds of episode (push or move 5, 10 or 15 cm
left, right, forward or backward; rotate 60 degrees either way) or an approach to the block, by one of
the project's demonstrators (:data:`~hoap_actions.demonstration.bodies.DEMONSTRATORS`), every draw from
the generator it is given. Performing it runs the demonstration world's physics (a fraction of a
second); its camera frames, some 400 an episode, are rendered only when asked for (what each costs:
``benchmarks/imitate_env.py``).
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.demonstration.arm_ik import RECORDED_JOINTS
from hoap_actions.demonstration.bodies import DEMONSTRATORS, DemonstratorProfile
from hoap_actions.demonstration.datasets import Demonstrations, load_demonstrations
from hoap_actions.demonstration.demonstrator import Demonstrator
from hoap_actions.demonstration.recording import DISTANCES, ROTATE_ANGLE
from hoap_actions.demonstration.scene import ACTIVE_REGION_HIGH, ACTIVE_REGION_LOW, DEMONSTRATOR_CAMERA, DemoScene
from hoap_actions.demonstration.tasks import ACTIONS, DIRECTIONS, FPS, PHASE_NAMES, TURNS, DemoTask
from hoap_actions.envs.camera import Camera
from hoap_actions.errors import InvalidInputError

__all__ = ["YAW_SPREAD", "Demonstration", "DemonstrationWorld", "ShownEpisode", "as_intended", "draw_task"]

logger = logging.getLogger(__name__)

YAW_SPREAD = np.radians(5.0)  # rad, the block's start yaw is drawn within +- this, as in the paper preset
INTENT_POSITION = 0.02  # m, a drawn demonstration's block ends within this of where its task aimed ...
INTENT_ANGLE = np.radians(10.0)  # rad, ... and turned within this of the aimed turn, or it is drawn again
MAX_DEMONSTRATION_TRIES = 10
_LOADED_FILES = 2  # recordings kept loaded, so replaying the episodes of one file reads it once


@dataclass(frozen=True)
class Demonstration:
    """A demonstration as a person hands it to a robot: what the camera filmed and how.

    ``frames`` (T, H, W, 3) uint8 at ``fps`` Hz; ``camera`` the camera's pose and intrinsics (eye, target,
    up, vertical field of view, image size: :class:`~hoap_actions.envs.camera.Camera`); ``background``
    (H, W, 3) uint8 the same camera's picture of the table without the person and the block, taken
    before the demonstration (for background subtraction). No markers, labels or object poses."""

    frames: np.ndarray
    camera: Camera
    fps: float
    background: np.ndarray


@dataclass(frozen=True)
class ShownEpisode:
    """The truth of one demonstration (evaluation only): what was asked (``action``, ``direction``,
    ``distance`` m, ``angle`` rad), who did it (``demonstrator`` name and ``height_m``), the markers ``H``
    (T, 6, 3) m, the block ``O`` (T, 6) (centre m + rotation vector rad), the demonstrator's joint
    angles ``Q`` (T, J) rad by ``joint_names``, phase ``labels`` (T,), the block's exact start and end
    poses (6,), the frame rate and where it came from (``"drawn"`` or ``"<path>#<episode>"``)."""

    action: str
    direction: str
    distance: float
    angle: float
    demonstrator: str
    height_m: float
    H: np.ndarray
    O: np.ndarray
    Q: np.ndarray
    joint_names: tuple[str, ...]
    labels: np.ndarray
    phase_names: tuple[str, ...]
    object_start: np.ndarray
    object_end: np.ndarray
    fps: float
    source: str


def _start_inside(rng: np.random.Generator, step: np.ndarray) -> tuple[float, float]:
    """A block start uniform over the active region from which ``step`` (m, x y) stays inside it."""
    low = np.maximum(ACTIVE_REGION_LOW, ACTIVE_REGION_LOW - step)
    high = np.minimum(ACTIVE_REGION_HIGH, ACTIVE_REGION_HIGH - step)
    x, y = rng.uniform(low, high)
    return float(x), float(y)


def draw_task(rng: np.random.Generator) -> DemoTask:
    """One episode to demonstrate: the action uniform over push, move, rotate and approach; a push or
    move's direction and distance and a rotate's turn as the paper preset has them; the block's start
    uniform over the active region (the end inside it too) with its yaw within :data:`YAW_SPREAD`."""
    action = ACTIONS[int(rng.integers(len(ACTIONS)))]
    yaw = float(rng.uniform(-YAW_SPREAD, YAW_SPREAD))
    if action in ("push", "move"):
        direction = sorted(DIRECTIONS)[int(rng.integers(len(DIRECTIONS)))]
        distance = float(DISTANCES[int(rng.integers(len(DISTANCES)))])
        xy = _start_inside(rng, distance * np.array(DIRECTIONS[direction]))
        return DemoTask(action, xy, yaw, direction, distance)
    if action == "rotate":
        direction = sorted(TURNS)[int(rng.integers(len(TURNS)))]
        return DemoTask("rotate", _start_inside(rng, np.zeros(2)), yaw, direction, angle=float(ROTATE_ANGLE))
    return DemoTask("approach", _start_inside(rng, np.zeros(2)), yaw)


def as_intended(task: DemoTask, start: np.ndarray, end: np.ndarray) -> bool:
    """Whether the block went from ``start`` to ``end`` (6,: centre m, rotation vector rad) as ``task``
    aimed: within :data:`INTENT_POSITION` of the aimed centre, its turn about the vertical within
    :data:`INTENT_ANGLE` of the aimed turn."""
    aim = task.target_pose(start)
    yaw = [Rotation.from_rotvec(pose[3:]).as_euler("zyx")[0] for pose in (start, aim, end)]
    miss = np.angle(np.exp(1j * ((yaw[2] - yaw[0]) - (yaw[1] - yaw[0]))))
    return bool(np.linalg.norm(end[:3] - aim[:3]) <= INTENT_POSITION and abs(miss) <= INTENT_ANGLE)


class DemonstrationWorld:
    """The human world behind ``Imitate-v0``: one demonstration scene per body height (each its own
    PyBullet client, made when first needed), the demonstrators that perform in them, and the camera."""

    def __init__(self, camera: Camera = DEMONSTRATOR_CAMERA) -> None:
        self.camera = camera
        self._scenes: dict[float, DemoScene] = {}
        self._demonstrators: dict[str, Demonstrator] = {}
        self._files: dict[tuple, Demonstrations] = {}

    def _scene(self, height_m: float) -> DemoScene:
        if height_m not in self._scenes:
            self._scenes[height_m] = DemoScene(body_height_m=height_m)
        return self._scenes[height_m]

    def perform(self, rng: np.random.Generator, demonstrator: str | None = None) -> ShownEpisode:
        """Draw a demonstrator (unless named), a task (:func:`draw_task`) and perform it, every draw from
        ``rng``. A performance that missed its aim (:func:`as_intended`: the simulated person's grasp
        slipped, say; by hand, 1 of the draws of seeds 0-119) is not shown: the draw is made again."""
        for _ in range(MAX_DEMONSTRATION_TRIES):
            name = demonstrator if demonstrator is not None else \
                sorted(DEMONSTRATORS)[int(rng.integers(len(DEMONSTRATORS)))]
            profile = DEMONSTRATORS[name]
            task = draw_task(rng)
            recording = self._demonstrator(profile).perform(task, np.random.default_rng(int(rng.integers(2**63))))
            if as_intended(task, recording.O[0], recording.O[-1]):
                break
            logger.info("%s missed its aim: drawn again", task)
        else:
            raise RuntimeError(f"no demonstration went as intended in {MAX_DEMONSTRATION_TRIES} draws")
        return ShownEpisode(
            action=task.action, direction=task.direction, distance=float(task.distance), angle=float(task.angle),
            demonstrator=profile.name, height_m=float(profile.height_m), H=recording.H, O=recording.O,
            Q=recording.Q, joint_names=RECORDED_JOINTS, labels=recording.labels, phase_names=PHASE_NAMES,
            object_start=recording.O[0].copy(), object_end=recording.O[-1].copy(), fps=float(FPS), source="drawn",
        )

    def _demonstrator(self, profile: DemonstratorProfile) -> Demonstrator:
        if profile.name not in self._demonstrators:
            self._demonstrators[profile.name] = Demonstrator(self._scene(profile.height_m), profile)
        return self._demonstrators[profile.name]

    def replay(self, path: str | os.PathLike, episode: int) -> ShownEpisode:
        """Episode ``episode`` of the recording at ``path`` (:mod:`hoap_actions.demonstration.datasets`).

        Raises :class:`~hoap_actions.errors.DataFileError` for a file that is not a readable recording and
        :class:`~hoap_actions.errors.InvalidInputError` for an episode index out of range or a recording
        without the demonstrator's joint angles (recorded before version 2), whose frames cannot be made."""
        demos = self._load(path)
        if isinstance(episode, bool) or not isinstance(episode, (int, np.integer)) or not 0 <= episode < len(demos):
            raise InvalidInputError(f"episode {episode!r} is not in the recording {path}; accepted: an int in "
                                    f"0..{len(demos) - 1}")
        if not demos.joint_names:
            raise InvalidInputError(f"the recording {path} has no joint angles (Q), so it holds no camera frames to "
                                    "show; record it again with this version: hoap-actions record")
        ep = demos[int(episode)]
        truth = ep.ground_truth
        who = demos.demonstrator
        return ShownEpisode(
            action=truth.action, direction=truth.direction, distance=float(truth.distance), angle=float(truth.angle),
            demonstrator=str(who.get("name", "reference")), height_m=float(who["height_m"]), H=ep.H, O=ep.O, Q=ep.Q,
            joint_names=tuple(demos.joint_names), labels=truth.labels, phase_names=tuple(demos.phase_names),
            object_start=truth.object_start.copy(), object_end=truth.object_end.copy(), fps=float(demos.fps),
            source=f"{path}#{int(episode)}",
        )

    def _load(self, path: str | os.PathLike) -> Demonstrations:
        """The recording at ``path``, read again only when the file changed (its size or time)."""
        resolved = Path(path).resolve()
        try:
            stat = resolved.stat()
            key = (str(resolved), stat.st_size, stat.st_mtime_ns)
        except OSError:
            key = (str(resolved),)
        if key not in self._files:
            demos = load_demonstrations(path)  # raises DataFileError naming what is wrong
            while len(self._files) >= _LOADED_FILES:
                self._files.pop(next(iter(self._files)))
            self._files[key] = demos
        return self._files[key]

    def render(self, shown: ShownEpisode, width: int, height: int) -> Demonstration:
        """Every frame of ``shown`` as the camera saw it, at ``width`` x ``height`` pixels."""
        camera = replace(self.camera, width=width, height=height)
        scene = self._scene(shown.height_m)
        background = scene.render_background(camera).rgb
        frames = np.empty((len(shown.Q), height, width, 3), dtype=np.uint8)
        for t, (q, pose) in enumerate(zip(shown.Q, shown.O)):
            scene.pose(shown.joint_names, q, pose)
            frames[t] = scene.render(camera).rgb
        logger.debug("rendered %d demonstration frames (%s)", len(frames), shown.source)
        return Demonstration(frames=frames, camera=camera, fps=shown.fps, background=background)

    def close(self) -> None:
        for scene in self._scenes.values():
            scene.close()
        self._scenes.clear()
        self._demonstrators.clear()
