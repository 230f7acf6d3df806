"""Record demonstration datasets: named presets of :class:`DemoTask` lists and :func:`record`.

Presets (``PRESETS``):

- ``paper``: the paper's action set: push and move left/right/forward/backward by 5, 10 and 15 cm,
  and rotate (counter-)clockwise by 60 degrees, 4 repetitions each (104 episodes); block start
  locations drawn uniformly over the 80 x 30 cm active region such that the block also ends inside it,
  start yaw within +-5 degrees.
- ``approach-grid``: the paper's synthesis experiment: approach -> remove (no manipulation) to the
  block on a 2x2 grid (the region's corners), a 3x3 grid and the evenly spread 5x7 test grid, 4
  repetitions at each location (192 episodes).
- ``small``: one push, one move, one rotate and one approach, for tests (4 episodes, a few seconds).

Same preset and seed -> the same dataset, array for array: every random draw comes from generators
seeded by ``(seed, episode index)``, and each episode starts from the same restored PyBullet state.

Each frame's hidden phase label (``ground_truth/labels``) is the part of the demonstrator's plan it
executes, in the paper's decomposition: the grasp and the hand closing the last gap to a block it
pushes are approach, letting go is remove, only what changes the block is the manipulation (see
:mod:`hoap_actions.demonstration.demonstrator`). The ``generator`` attribute records ``labels_version``
(:data:`~hoap_actions.demonstration.tasks.LABELS_VERSION`); datasets recorded before it existed lack
the key and use labelling 1, in which the grasp and release belonged to the manipulation.
"""

from __future__ import annotations

import atexit
import logging
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hoap_actions.demonstration.arm_ik import RECORDED_JOINTS
from hoap_actions.demonstration.bodies import DEMONSTRATORS, DemonstratorProfile, demonstrator_profile
from hoap_actions.demonstration.datasets import Demonstrations, Episode, GroundTruth, write_hdf5
from hoap_actions.demonstration.demonstrator import Demonstrator
from hoap_actions.demonstration.mocap import MocapNoise, add_mocap_noise, parse_noise
from hoap_actions.demonstration.scene import ACTIVE_REGION_HIGH, ACTIVE_REGION_LOW, DemoScene, active_region_grid
from hoap_actions.demonstration.tasks import (
    DIRECTIONS,
    FPS,
    LABELS_VERSION,
    MARKER_NAMES,
    PHASE_NAMES,
    TURNS,
    DemoRecording,
    DemoTask,
)
from hoap_actions.errors import InvalidInputError
from hoap_actions.outputs import claimed_file
from hoap_actions.parallel import ordered_map
from hoap_actions.seeds import check_seed

logger = logging.getLogger(__name__)

DISTANCES = (0.05, 0.10, 0.15)  # m, push and move distances of the paper preset
ROTATE_ANGLE = np.radians(60.0)
REPETITIONS = 4
GRIDS = {"2x2": (2, 2), "3x3": (3, 3), "5x7": (5, 7)}
_YAW_SPREAD = np.radians(5.0)
_NO_NOISE = MocapNoise()  # the default noise: none, the exact poses (frozen, so one shared instance is safe)


def _start_for(rng: np.random.Generator, step: np.ndarray) -> tuple[float, float]:
    """A block start, uniform over the active region, from which ``step`` (m, x y) stays inside it."""
    low = np.maximum(ACTIVE_REGION_LOW, ACTIVE_REGION_LOW - step)
    high = np.minimum(ACTIVE_REGION_HIGH, ACTIVE_REGION_HIGH - step)
    x, y = rng.uniform(low, high)
    return float(x), float(y)


def paper_tasks(rng: np.random.Generator) -> list[DemoTask]:
    """The full action set (see the module docstring)."""
    tasks = []
    for action in ("push", "move"):
        for direction, unit in DIRECTIONS.items():
            for distance in DISTANCES:
                for rep in range(REPETITIONS):
                    xy = _start_for(rng, distance * np.array(unit))
                    yaw = float(rng.uniform(-_YAW_SPREAD, _YAW_SPREAD))
                    tasks.append(DemoTask(action, xy, yaw, direction, distance, repetition=rep))
    for direction in TURNS:
        for rep in range(REPETITIONS):
            xy = _start_for(rng, np.zeros(2))
            yaw = float(rng.uniform(-_YAW_SPREAD, _YAW_SPREAD))
            tasks.append(DemoTask("rotate", xy, yaw, direction, angle=ROTATE_ANGLE, repetition=rep))
    return tasks


def approach_grid_tasks(rng: np.random.Generator) -> list[DemoTask]:
    """Approach -> remove to every location of the 2x2, 3x3 and 5x7 grids, 4 times each."""
    del rng  # the locations are fixed; variability comes from the motion itself
    tasks = []
    for name, (rows, cols) in GRIDS.items():
        points = active_region_grid(rows, cols)
        for index, xy in enumerate(points):
            for rep in range(REPETITIONS):
                tasks.append(
                    DemoTask("approach", (float(xy[0]), float(xy[1])), repetition=rep, grid=name,
                             grid_index=(index // cols, index % cols))
                )
    return tasks


def small_tasks(rng: np.random.Generator) -> list[DemoTask]:
    """One episode of each kind, for tests and quick looks."""
    return [
        DemoTask("push", _start_for(rng, np.array([0.0, 0.10])), direction="left", distance=0.10),
        DemoTask("move", _start_for(rng, np.array([0.10, 0.0])), direction="forward", distance=0.10),
        DemoTask("rotate", _start_for(rng, np.zeros(2)), direction="ccw", angle=ROTATE_ANGLE),
        DemoTask("approach", (0.0, 0.0), grid="5x7", grid_index=(2, 3)),
    ]


PRESETS: dict[str, Callable[[np.random.Generator], list[DemoTask]]] = {
    "paper": paper_tasks,
    "approach-grid": approach_grid_tasks,
    "small": small_tasks,
}


def preset_tasks(preset: str, seed: int = 0) -> list[DemoTask]:
    """The episodes a preset records with ``seed`` (block starts are drawn from ``seed``)."""
    if preset not in PRESETS:
        raise InvalidInputError(f"unknown preset {preset!r}; choose one of {sorted(PRESETS)}")
    return PRESETS[preset](np.random.default_rng([seed, 0]))


def _episode(task: DemoTask, recording: DemoRecording, seed: int, index: int, noise: MocapNoise) -> Episode:
    truth = GroundTruth(
        labels=recording.labels,
        phase_names=PHASE_NAMES,
        action=task.action,
        direction=task.direction,
        distance=float(task.distance),
        angle=float(task.angle),
        object_start=recording.O[0],
        object_end=recording.O[-1],
        object_target=recording.object_target,
        hand_rest=recording.hand_rest,
        repetition=task.repetition,
        grid=task.grid,
        grid_index=np.array(task.grid_index),
    )
    H, O = add_mocap_noise(recording.H, recording.O, noise, FPS, seed, index)
    return Episode(H=H, O=O, ground_truth=truth, seed=(seed, index + 1), Q=recording.Q)


def record(preset: str, out: Path, seed: int = 0, overwrite: bool = False, progress: bool = True,
           workers: int = 1, ray_address: str | None = None, noise: MocapNoise | str = "none",
           demonstrator: DemonstratorProfile | str = "reference") -> Path:
    """Record every episode of ``preset`` and write them to the HDF5 file ``out`` (see
    :mod:`hoap_actions.demonstration.datasets`); returns ``out``.

    ``out`` is claimed before the first episode (:func:`hoap_actions.outputs.claimed_file`): a bad
    path, an existing file (unless ``overwrite``) or another run writing it fails at once, not after
    the recording. The progress bar shows only when stderr is a terminal. ``workers`` processes share
    the episodes; every episode draws from its own ``(seed, index)`` generator in a freshly restored
    scene, so the file is the same byte for byte whatever their number, or with ``ray_address``
    whatever Ray actors recorded them (see :func:`hoap_actions.parallel.ordered_map`).

    ``noise`` (a :class:`~hoap_actions.demonstration.mocap.MocapNoise`, or a name or magnitudes for
    :func:`~hoap_actions.demonstration.mocap.parse_noise`) is what a motion-capture system would add; the
    default ``"none"`` records the simulation's exact poses. Ground truth and ``Q`` stay exact.
    ``demonstrator`` (a profile, a name of :data:`~hoap_actions.demonstration.bodies.DEMONSTRATORS`, or
    ``"random"``: drawn from ``seed``) is who performs the episodes; the default ``"reference"`` is the
    demonstrator the shipped models learned from.
    """
    check_seed(seed)
    noise = noise if isinstance(noise, MocapNoise) else parse_noise(noise)
    profile = demonstrator_profile(demonstrator, seed)
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise InvalidInputError(f"workers must be an int >= 1; got {workers!r}")
    tasks = preset_tasks(preset, seed)
    with claimed_file(out, overwrite, what="dataset") as partial:
        demos = _record_tasks(preset, tasks, seed, progress, int(workers), ray_address, noise, profile)
        write_hdf5(partial, demos)
    logger.info("recorded %d episodes (%d frames) of preset %r", len(demos), sum(e.T for e in demos), preset)
    return Path(out)


_WORKER: dict = {}


def _start_worker(profile: DemonstratorProfile) -> None:
    """A worker process's own scene and demonstrator, closed when the process ends."""
    scene = DemoScene(body_height_m=profile.height_m)
    atexit.register(scene.close)
    _WORKER.update(demonstrator=Demonstrator(scene, profile))


def _perform(job: tuple[DemoTask, int, int]) -> DemoRecording:
    task, seed, index = job
    return _WORKER["demonstrator"].perform(task, np.random.default_rng([seed, index + 1]))


def _recordings(tasks: list[DemoTask], seed: int, workers: int, scene: DemoScene,
                ray_address: str | None, profile: DemonstratorProfile) -> Iterator[DemoRecording]:
    """Each task performed, in order: in ``scene``, or spread over ``workers`` spawned processes or Ray actors."""
    jobs = [(task, seed, index) for index, task in enumerate(tasks)]
    if workers == 1 and ray_address is None:
        demonstrator = Demonstrator(scene, profile)
        for task, _, index in jobs:
            yield demonstrator.perform(task, np.random.default_rng([seed, index + 1]))
        return
    yield from ordered_map(_perform, jobs, _start_worker, (profile,), workers, ray_address)


def _record_tasks(preset: str, tasks: list[DemoTask], seed: int, progress: bool, workers: int = 1,
                  ray_address: str | None = None, noise: MocapNoise = _NO_NOISE,
                  profile: DemonstratorProfile = DEMONSTRATORS["reference"]) -> Demonstrations:
    episodes, table_contacts, missed_grasps = [], [], []
    scene = DemoScene(body_height_m=profile.height_m)  # the recorded scene's numbers, and the scene for one worker
    try:
        scene_parameters = scene.parameters()
        bar = tqdm(_recordings(tasks, seed, workers, scene, ray_address, profile), total=len(tasks),
                   desc=f"recording {preset}",
                   unit="episode", disable=not (progress and sys.stderr.isatty()))
        for index, (task, recording) in enumerate(zip(tasks, bar)):
            episodes.append(_episode(task, recording, seed, index, noise))
            if recording.table_contact_frames:
                table_contacts.append(index)
            if task.action in ("move", "rotate") and not recording.grasped:
                missed_grasps.append(index)
    finally:
        scene.close()
    return Demonstrations(
        episodes=tuple(episodes),
        fps=float(FPS),
        marker_names=MARKER_NAMES,
        phase_names=PHASE_NAMES,
        seed=seed,
        scene=scene_parameters,
        generator={
            "preset": preset,
            "seed": seed,
            "episodes": len(episodes),
            "labels_version": LABELS_VERSION,
            "tasks": [_task_dict(t) for t in tasks],
            # quality record: episodes in which the hand touched the table, or a grasp was not made
            "table_contact_episodes": table_contacts,
            "missed_grasp_episodes": missed_grasps,
            # who demonstrated; absent: the reference demonstrator (recordings from before profiles existed)
            **({} if profile == DEMONSTRATORS["reference"] else {"demonstrator": profile.to_dict()}),
        },
        joint_names=RECORDED_JOINTS,
        noise={} if noise.exact else noise.to_dict(),
    )


def _task_dict(task: DemoTask) -> dict:
    """A task as JSON-ready values (stored in the dataset's ``generator`` attribute)."""
    return {
        "action": task.action, "object_xy": list(task.object_xy), "object_yaw": task.object_yaw,
        "direction": task.direction, "distance": task.distance, "angle": float(task.angle),
        "repetition": task.repetition, "grid": task.grid, "grid_index": list(task.grid_index),
    }
