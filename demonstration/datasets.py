"""Demonstration datasets: the documented HDF5 file format, its writer and its loader.

Why HDF5 (h5py), not Minari: Minari is built around reinforcement-learning episodes (observations,
actions, rewards, terminations) and pulls in extra dependencies; a demonstration here is marker and
object trajectories with evaluation-only labels. HDF5 is self-describing (names, shapes, units as
attributes), checksummed per chunk (Fletcher-32), and readable without this package (h5py, MATLAB,
``h5dump``).

File layout (``format_version`` 3 for a recording with measurement noise, 2 for an exact one: the
two differ only by the ``noise`` attribute, so exact recordings stay readable by older releases;
version 1 files, written before recordings kept the demonstrator's joint angles, load with ``Q`` None)::

    /                              attrs: format = "hoap-actions-demonstrations", format_version = 2 or 3,
                                          fps (Hz), marker_names (6 str), phase_names (str table),
                                          units = "m, rad, s", frame (str), rotation_convention (str),
                                          seed (int), scene (JSON str), generator (JSON str), episodes (int),
                                          joint_names (J str; empty: no Q),
                                          noise (JSON str, version 3 only: the motion-capture error
                                          model the data carry, :class:`hoap_actions.demonstration.mocap.MocapNoise`;
                                          absent: exact poses)
    /episode_00000/                attrs: seed (2 ints: the recording seed and the episode's index)
        H        (T, 6, 3) float64   marker positions (m): shoulder, elbow, wrist, index fingertip,
                                     index knuckle, thumb tip (root attr marker_names), scene frame;
                                     a marker the cameras lost is NaN in all 3 coordinates (only when
                                     the noise model has occlusion gaps)
        O        (T, 6)    float64   object pose: centre position (m) and rotation vector (rad)
        Q        (T, J)    float64   the demonstrator's joint angles (rad, root attr joint_names), when
                                     recorded: with O, all a camera needs to render the scene again
        ground_truth/              attrs: action, direction (str), distance (m), angle (rad),
                                          repetition (int), grid (str, "" if none)
            labels         (T,) int16   phase code per frame, an index into /phase_names
            object_start   (6,)         object pose at the first frame
            object_end     (6,)         object pose at the last frame
            object_target  (6,)         the pose the action aimed at
            hand_rest      (3,)         palm centre (m) at rest before the approach
            grid_index     (2,) int     (row, column) in the grid, (-1, -1) if none
    /episode_00001/ ...

Rotation convention: ``O[:, 3:]`` is ``scipy.spatial.transform.Rotation.as_rotvec()`` of the object's
orientation in the scene frame (axis times angle, |angle| <= pi), i.e. of the quaternion (x, y, z, w)
PyBullet reports. Frames are sampled at ``fps``; ``T`` differs between episodes. The ``ground_truth``
group is for evaluation only: learning code reads ``H`` and ``O`` (``Demonstrations.movement_data`` /
``object_data``) and never needs it.

Which frames carry which phase label is the recorder's business, not the format's: the demonstrator
labels each frame with the part of its plan it executes (approach, the manipulation, remove; the grasp
is approach and letting go is remove, as in the paper; see :mod:`hoap_actions.demonstration.demonstrator`) and
records that labelling's number in ``generator["labels_version"]`` (absent: labelling 1, from before
the number was recorded, in which the grasp and the release belonged to the manipulation).

Writing goes to a temporary file in the target directory that is renamed into place when complete,
so an interrupted write never leaves a partial dataset under the final name.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from hoap_actions.errors import DataFileError, HoapActionsError, InvalidInputError
from hoap_actions.inputs import checked_input_file
from hoap_actions.outputs import claimed_file, write_bytes

logger = logging.getLogger(__name__)

FORMAT = "hoap-actions-demonstrations"
FORMAT_VERSION = 3
EXACT_FORMAT_VERSION = 2  # what an exact recording is written as (module docstring)
_READABLE_VERSIONS = (1, 2, 3)
# A recording may miss markers (occlusion gaps) but not most of them: beyond this fraction of an
# episode's marker frames, gap filling would invent the movement rather than bridge it.
MAX_MISSING_FRACTION = 0.2
N_MARKERS = 6
MAX_RECORDING_BYTES = 64 * 2**30  # a whole recording file: hours of motion capture fit well under it
MAX_ENTRY_BYTES = 2**30  # one episode array: an hour at 1 kHz of 18 float64 coordinates is 0.5 GB
MAX_FPS = 10_000.0  # frames per second: motion capture records at 100-1000
ROTATION_CONVENTION = (
    "O[:, 3:] = scipy Rotation.as_rotvec() of the object orientation in the scene frame (rad, |angle| <= pi)"
)
FRAME = "scene frame: z up, origin on the table top at the centre of the active region, x away from the demonstrator"
_ARRAY_OPTIONS = {"compression": "gzip", "compression_opts": 4, "shuffle": True, "fletcher32": True}
# Reading checks every entry exists and is plausible: a marker or object coordinate beyond this (m,
# scene frame) is far outside any table-top scene, so the file is corrupt or mis-scaled.
MAX_COORDINATE_M = 100.0
ROTATION_SLACK_RAD = 1e-6  # float round-off allowed on the convention's |angle| <= pi
# A recorded joint angle beyond this (rad) is no human joint's: the file is corrupt, and the value would
# go to PyBullet when the frame is rendered again.
MAX_JOINT_ANGLE_RAD = 2.0 * np.pi
_TRUTH_SHAPES = {"object_start": (6,), "object_end": (6,), "object_target": (6,), "hand_rest": (3,), "grid_index": (2,)}
_TRUTH_ATTRIBUTES = ("action", "direction", "distance", "angle", "repetition", "grid")
_EPISODE_ARRAYS = ("H", "O", "ground_truth/labels", *(f"ground_truth/{name}" for name in _TRUTH_SHAPES))
_ROOT_ATTRIBUTES = ("marker_names", "phase_names", "episodes", "fps", "seed", "scene", "generator")


def _array(array: np.ndarray, dtype: type | str = np.float64) -> np.ndarray:
    """A copy of ``array`` as ``dtype`` (left writable: scipy's Rotation refuses read-only buffers)."""
    return np.array(array, dtype=dtype)


@dataclass(frozen=True)
class GroundTruth:
    """Evaluation-only truth of one episode: per-frame phase codes and the action's parameters.

    ``labels`` (T,) indexes ``phase_names``; poses are (6,) position (m) + rotation vector (rad);
    ``distance`` (m) is set for push/move, ``angle`` (rad) for rotate, ``grid``/``grid_index`` for
    approach-grid episodes (``""`` / ``(-1, -1)`` otherwise).
    """

    labels: np.ndarray
    phase_names: tuple[str, ...]
    action: str
    direction: str
    distance: float
    angle: float
    object_start: np.ndarray
    object_end: np.ndarray
    object_target: np.ndarray
    hand_rest: np.ndarray
    repetition: int = 0
    grid: str = ""
    grid_index: np.ndarray = field(default_factory=lambda: np.array([-1, -1]))

    def __post_init__(self) -> None:
        object.__setattr__(self, "labels", _array(self.labels, np.int16))
        object.__setattr__(self, "phase_names", tuple(self.phase_names))
        for name in ("object_start", "object_end", "object_target", "hand_rest"):
            object.__setattr__(self, name, _array(getattr(self, name)))
        object.__setattr__(self, "grid_index", _array(self.grid_index, np.int64))

    def phases(self) -> np.ndarray:
        """Phase name per frame, (T,) str."""
        return np.array(self.phase_names)[self.labels]

    def segments(self) -> list[tuple[str, int, int]]:
        """Runs of equal labels as ``(phase, first frame, end frame exclusive)``, in time order."""
        cuts = np.flatnonzero(np.diff(self.labels)) + 1
        bounds = np.concatenate([[0], cuts, [len(self.labels)]])
        return [(self.phase_names[self.labels[a]], int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]


@dataclass(frozen=True)
class Episode:
    """One demonstration: ``H`` (T, 6, 3) marker positions (m), ``O`` (T, 6) object pose (m, rad),
    its evaluation-only ``ground_truth``, the ``seed`` pair it was recorded with, and ``Q`` (T, J) the
    demonstrator's joint angles (rad) when recorded (None otherwise): learning reads H and O; Q is
    what a camera needs to see the demonstration (:meth:`DemoScene.pose`)."""

    H: np.ndarray
    O: np.ndarray
    ground_truth: GroundTruth
    seed: tuple[int, int] = (0, 0)
    Q: np.ndarray | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "H", _array(self.H))
        object.__setattr__(self, "O", _array(self.O))
        object.__setattr__(self, "seed", tuple(int(s) for s in self.seed))
        if self.Q is not None:
            object.__setattr__(self, "Q", _array(self.Q))

    @property
    def T(self) -> int:
        """Number of frames."""
        return len(self.H)


@dataclass(frozen=True)
class Demonstrations(Sequence[Episode]):
    """A recorded dataset: the episodes plus what is needed to interpret and reproduce them."""

    episodes: tuple[Episode, ...]
    fps: float
    marker_names: tuple[str, ...]
    phase_names: tuple[str, ...]
    seed: int = 0
    scene: dict = field(default_factory=dict)
    generator: dict = field(default_factory=dict)
    joint_names: tuple[str, ...] = ()
    noise: dict = field(default_factory=dict)
    """The motion-capture error model the data carry (:meth:`MocapNoise.to_dict`); empty: exact poses."""

    @property
    def exact(self) -> bool:
        """The poses are the simulation's own: no noise, no gaps."""
        return self._noise_model().exact

    @property
    def demonstrator(self) -> dict:
        """Who demonstrated (:mod:`hoap_actions.demonstration.bodies`): the profile the recording names in
        its ``generator``, else the reference demonstrator (recordings from before profiles existed)."""
        from hoap_actions.demonstration.bodies import DEMONSTRATORS  # envs imports this module

        return dict(self.generator.get("demonstrator", DEMONSTRATORS["reference"].to_dict()))

    @property
    def has_gaps(self) -> bool:
        """Markers may be missing (NaN) in some frames."""
        return self._noise_model().has_gaps

    def _noise_model(self):
        from hoap_actions.demonstration.mocap import MocapNoise  # the model's home; envs imports this module

        return MocapNoise.from_dict(self.noise)

    def __len__(self) -> int:
        return len(self.episodes)

    def __getitem__(self, index):  # type: ignore[override]
        return self.episodes[index]

    def __iter__(self) -> Iterator[Episode]:
        return iter(self.episodes)

    def movement_data(self) -> tuple[np.ndarray, np.ndarray]:
        """Marker trajectories in the hmmlearn convention: ``X`` (sum T, 18) = H flattened per frame
        (marker-major: shoulder x y z, elbow x y z, ...), and ``lengths`` (n_episodes,)."""
        return np.concatenate([e.H.reshape(e.T, -1) for e in self.episodes]), self.lengths()

    def object_data(self) -> tuple[np.ndarray, np.ndarray]:
        """Object trajectories in the hmmlearn convention: ``X`` (sum T, 6) and ``lengths``."""
        return np.concatenate([e.O for e in self.episodes]), self.lengths()

    def lengths(self) -> np.ndarray:
        return np.array([e.T for e in self.episodes], dtype=np.int64)


# ---------------------------------------------------------------------------------------- writing
def _check_episode(index: int, episode: Episode, n_phases: int, n_joints: int, gaps: bool) -> None:
    where = f"episode {index}"
    if (episode.Q is None) != (n_joints == 0):
        raise InvalidInputError(f"{where}: Q must be given exactly when joint_names are ({n_joints} names, Q "
                                f"{'missing' if episode.Q is None else 'given'})")
    if episode.Q is not None and (episode.Q.shape != (len(episode.H), n_joints) or not np.all(np.isfinite(episode.Q))):
        raise InvalidInputError(f"{where}: Q must be finite with shape (T, J) = ({len(episode.H)}, {n_joints}); "
                                f"got {episode.Q.shape}")
    H, O, labels = episode.H, episode.O, episode.ground_truth.labels
    if H.ndim != 3 or H.shape[1:] != (N_MARKERS, 3) or len(H) < 1:
        raise InvalidInputError(f"{where}: H must have shape (T, {N_MARKERS}, 3) with T >= 1; got {H.shape}")
    if O.shape != (len(H), 6):
        raise InvalidInputError(f"{where}: O must have shape (T, 6) = ({len(H)}, 6); got {O.shape}")
    if labels.shape != (len(H),):
        raise InvalidInputError(f"{where}: labels must have shape (T,) = ({len(H)},); got {labels.shape}")
    if not np.all(np.isfinite(O)):
        raise InvalidInputError(f"{where}: O must be finite (no NaN or inf)")
    try:
        _check_markers(where, H, gaps)
    except DataFileError as exc:
        raise InvalidInputError(str(exc)) from None
    if labels.min() < 0 or labels.max() >= n_phases:
        raise InvalidInputError(f"{where}: labels must index phase_names (0..{n_phases - 1})")


def write_demonstrations(path: Path | str, demos: Demonstrations, overwrite: bool = False) -> Path:
    """Write ``demos`` to the HDF5 file ``path`` (layout in the module docstring); returns the path.

    Raises :class:`DataExistsError` if ``path`` exists (unless ``overwrite``) or another process is
    writing it, :class:`InvalidInputError` for a malformed episode. The file appears under ``path``
    only once completely written (:func:`hoap_actions.outputs.claimed_file`); a job that produces
    ``demos`` slowly claims ``path`` first and calls :func:`write_hdf5` on the partial.
    """
    with claimed_file(path, overwrite, what="dataset") as partial:
        write_hdf5(partial, demos)
    logger.info("wrote %d episodes to %s", len(demos.episodes), path)
    return Path(path)


def write_hdf5(file: Path | str, demos: Demonstrations) -> None:
    """Check ``demos`` and write them to ``file`` as it is, replacing its contents: for a target
    already claimed by the caller (use :func:`write_demonstrations` otherwise)."""
    if len(demos.marker_names) != N_MARKERS:
        raise InvalidInputError(f"expected {N_MARKERS} marker names; got {list(demos.marker_names)}")
    if not demos.episodes:
        raise InvalidInputError("there are no episodes to write")
    gaps = demos.has_gaps
    for index, episode in enumerate(demos.episodes):
        _check_episode(index, episode, len(demos.phase_names), len(demos.joint_names), gaps)
    # The file is made in memory and written with Python's own I/O: a disk that fills up is an OSError
    # here, where HDF5 writing to it would fail its close and abort the process.
    with h5py.File(Path(file).name, "w", driver="core", backing_store=False, track_order=True) as f:
        f.attrs.update(
            format=FORMAT,
            format_version=EXACT_FORMAT_VERSION if demos.exact else FORMAT_VERSION,
            fps=float(demos.fps),
            marker_names=list(demos.marker_names),
            phase_names=list(demos.phase_names),
            units="m, rad, s",
            frame=FRAME,
            rotation_convention=ROTATION_CONVENTION,
            seed=int(demos.seed),
            scene=json.dumps(demos.scene, sort_keys=True),
            generator=json.dumps(demos.generator, sort_keys=True),
            episodes=len(demos.episodes),
            joint_names=list(demos.joint_names),
        )
        if not demos.exact:
            f.attrs["noise"] = json.dumps(demos.noise, sort_keys=True)
        for index, episode in enumerate(demos.episodes):
            _write_episode(f.create_group(f"episode_{index:05d}"), episode)
        f.flush()
        image = f.id.get_file_image()
    write_bytes(file, image, "dataset")


def _write_episode(group: h5py.Group, episode: Episode) -> None:
    group.attrs["seed"] = np.array(episode.seed, dtype=np.int64)
    group.create_dataset("H", data=episode.H, chunks=episode.H.shape, track_times=False, **_ARRAY_OPTIONS)
    group.create_dataset("O", data=episode.O, chunks=episode.O.shape, track_times=False, **_ARRAY_OPTIONS)
    if episode.Q is not None:
        group.create_dataset("Q", data=episode.Q, chunks=episode.Q.shape, track_times=False, **_ARRAY_OPTIONS)
    truth = episode.ground_truth
    gt = group.create_group("ground_truth")
    gt.attrs.update(
        action=truth.action,
        direction=truth.direction,
        distance=float(truth.distance),
        angle=float(truth.angle),
        repetition=int(truth.repetition),
        grid=truth.grid,
    )
    gt.create_dataset("labels", data=truth.labels, chunks=truth.labels.shape, track_times=False, **_ARRAY_OPTIONS)
    for name in ("object_start", "object_end", "object_target", "hand_rest", "grid_index"):
        gt.create_dataset(name, data=getattr(truth, name), track_times=False, fletcher32=True)


# ---------------------------------------------------------------------------------------- loading
def load_demonstrations(path: Path | str) -> Demonstrations:
    """Read a dataset written by :func:`write_demonstrations`.

    Raises :class:`DataFileError` for a missing, truncated or corrupt file (checksums are verified),
    another format or version, a missing array or attribute, wrong shapes (ground truth included),
    labels outside the phase table, NaN/inf values, coordinates beyond :data:`MAX_COORDINATE_M` or
    rotation vectors longer than pi; the message names the file, the episode, the entry and (for
    values) the first bad frame.
    """
    path = checked_input_file(path, "demonstrations file", MAX_RECORDING_BYTES)
    try:
        with h5py.File(path, "r") as f:
            return _read(f, path)
    except HoapActionsError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise DataFileError(f"{path} is not a readable demonstrations file (truncated or corrupt?): {exc}") from exc


def _read(f: h5py.File, path: Path) -> Demonstrations:
    fmt = f.attrs.get("format")
    if fmt != FORMAT:
        raise DataFileError(f"{path}: format is {fmt!r}, expected {FORMAT!r}")
    version = f.attrs.get("format_version")
    version = version.item() if isinstance(version, np.generic) else version
    if isinstance(version, bool) or version not in _READABLE_VERSIONS:
        raise DataFileError(f"{path}: format_version {version!r} is not supported; this code reads "
                            f"{list(_READABLE_VERSIONS)}")
    header = {name: _attribute(f, name, str(path)) for name in _ROOT_ATTRIBUTES}
    marker_names = tuple(str(m) for m in header["marker_names"])
    phase_names = tuple(str(p) for p in header["phase_names"])
    if len(marker_names) != N_MARKERS:
        raise DataFileError(f"{path}: expected {N_MARKERS} marker names, found {list(marker_names)}")
    joint_names = tuple(str(j) for j in _attribute(f, "joint_names", str(path))) if version >= 2 else ()
    noise_model = _noise_attribute(f, path) if version >= 3 else None
    noise = {} if noise_model is None else noise_model.to_dict()
    gaps = noise_model is not None and noise_model.has_gaps
    names = sorted(name for name in f if name.startswith("episode_"))
    if len(names) != int(header["episodes"]):
        raise DataFileError(f"{path}: {len(names)} episode groups but the header says {int(header['episodes'])}")
    fps = header["fps"]
    if isinstance(fps, (bool, np.bool_)) or not isinstance(fps, (int, float, np.integer, np.floating)) \
            or not np.isfinite(fps) or not 0 < fps <= MAX_FPS:
        raise DataFileError(f"{path}: attribute fps is {fps!r}; accepted: frames per second in (0, {MAX_FPS:g}]")
    documents = {}
    for name in ("scene", "generator"):
        try:
            documents[name] = json.loads(header[name])
        except (TypeError, ValueError, RecursionError):
            documents[name] = None
        if not isinstance(documents[name], dict):
            raise DataFileError(f"{path}: attribute {name} is not a JSON object; accepted: the object "
                                f"write_demonstrations stores")
    episodes = []
    for name in names:
        if not isinstance(f[name], h5py.Group):
            raise DataFileError(f"{path}:{name} is an array; accepted: a group holding {', '.join(_EPISODE_ARRAYS)}")
        episodes.append(_read_episode(f[name], f"{path}:{name}", phase_names, len(joint_names), gaps))
    return Demonstrations(
        episodes=tuple(episodes),
        fps=float(fps),
        marker_names=marker_names,
        phase_names=phase_names,
        seed=int(header["seed"]),
        scene=documents["scene"],
        generator=documents["generator"],
        joint_names=joint_names,
        noise=noise,
    )


def _noise_attribute(f: h5py.File, path: Path):
    """The error model the ``noise`` attribute of a version-3 file describes (a ``MocapNoise``), checked."""
    from hoap_actions.demonstration.mocap import MocapNoise  # the model's home; envs imports this module

    try:
        return MocapNoise.from_dict(json.loads(_attribute(f, "noise", str(path))))
    except (ValueError, HoapActionsError) as exc:
        raise DataFileError(f"{path}: attribute noise is not a motion-capture error model ({exc}); accepted: the "
                            "JSON of hoap_actions.demonstration.mocap.MocapNoise.to_dict()") from None


def _read_episode(group: h5py.Group, where: str, phase_names: tuple[str, ...], n_joints: int,
                  gaps: bool) -> Episode:
    """One episode with every entry checked, so an edited or damaged file fails here naming the episode
    and the entry, not later in the learning code."""
    H, O, labels = (_entry(group, name, where) for name in ("H", "O", "ground_truth/labels"))
    if H.ndim != 3 or H.shape[1:] != (N_MARKERS, 3) or len(H) < 1:
        raise DataFileError(f"{where}: H has shape {H.shape}, expected (T, {N_MARKERS}, 3) with T >= 1")
    if O.shape != (len(H), 6):
        raise DataFileError(f"{where}: O has shape {O.shape}, expected ({len(H)}, 6)")
    if labels.shape != (len(H),) or labels.dtype.kind not in "iu":
        raise DataFileError(f"{where}: labels have shape {labels.shape} and dtype {labels.dtype}, expected "
                            f"({len(H)},) integers")
    _check_poses(where, H, O, gaps)
    if labels.min() < 0 or labels.max() >= len(phase_names):
        raise DataFileError(f"{where}: labels outside the phase table 0..{len(phase_names) - 1}")
    truth_arrays = {name: _entry(group, f"ground_truth/{name}", where) for name in _TRUTH_SHAPES}
    for name, value in truth_arrays.items():
        shape = _TRUTH_SHAPES[name]
        kinds = "iu" if name == "grid_index" else "iuf"
        if value.shape != shape or value.dtype.kind not in kinds or not np.all(np.isfinite(value)):
            raise DataFileError(f"{where}: entry ground_truth/{name} has shape {value.shape} and dtype {value.dtype}; "
                                f"accepted: {shape} finite {'integers' if kinds == 'iu' else 'numbers'}")
    gt = group["ground_truth"]
    attrs = {name: _attribute(gt, name, f"{where}/ground_truth") for name in _TRUTH_ATTRIBUTES}
    try:
        truth = GroundTruth(
            labels=labels,
            phase_names=phase_names,
            action=str(attrs["action"]),
            direction=str(attrs["direction"]),
            distance=float(attrs["distance"]),
            angle=float(attrs["angle"]),
            repetition=int(attrs["repetition"]),
            grid=str(attrs["grid"]),
            **truth_arrays,
        )
        seed = tuple(int(s) for s in _attribute(group, "seed", where))
    except (TypeError, ValueError) as exc:
        raise DataFileError(f"{where}: a ground_truth or seed attribute is malformed ({exc}); accepted: distance, "
                            "angle numbers, repetition an int, seed 2 ints") from exc
    Q = None
    if n_joints:
        Q = _entry(group, "Q", where)
        if Q.shape != (len(H), n_joints) or Q.dtype.kind != "f" or not np.all(np.isfinite(Q)):
            raise DataFileError(f"{where}: entry Q has shape {Q.shape} and dtype {Q.dtype}; accepted: ({len(H)}, "
                                f"{n_joints}) finite joint angles, one column per root attribute joint_names")
        _raise_beyond(where, "Q", np.abs(Q).max(axis=1), MAX_JOINT_ANGLE_RAD, "a joint angle of", "rad",
                      f"joint angles within +-{MAX_JOINT_ANGLE_RAD:.3g} rad")
    return Episode(H=H, O=O, ground_truth=truth, seed=seed, Q=Q)


def _entry(group: h5py.Group, name: str, where: str) -> np.ndarray:
    """The array ``name`` of an episode; a missing one (or a group in its place) raises DataFileError naming it."""
    entry = group.get(name)
    if not isinstance(entry, h5py.Dataset):
        problem = "is missing" if entry is None else "is a group, not an array"
        raise DataFileError(f"{where}: entry {name} {problem}; every episode holds {', '.join(_EPISODE_ARRAYS)}")
    declared = int(np.prod(entry.shape, dtype=object)) * entry.dtype.itemsize
    if declared > MAX_ENTRY_BYTES:  # refused before h5py allocates it
        raise DataFileError(f"{where}: entry {name} declares {declared / 2**30:.1f} GiB (shape {entry.shape}); an "
                            f"episode's arrays are at most {MAX_ENTRY_BYTES / 2**30:.0f} GiB")
    return entry[()]


def _attribute(node: h5py.Group, name: str, where: str):
    """The attribute ``name`` of a group or the file; a missing one raises DataFileError naming it."""
    if name not in node.attrs:
        raise DataFileError(f"{where}: attribute {name} is missing; see the file layout in {__name__}")
    return node.attrs[name]


def _check_markers(where: str, H: np.ndarray, gaps: bool) -> None:
    """Markers finite, or (in a recording with occlusion gaps) missing as a whole marker and in at most
    :data:`MAX_MISSING_FRACTION` of the episode's marker frames; within :data:`MAX_COORDINATE_M`."""
    present = np.isfinite(H)
    if gaps:
        partial = np.flatnonzero((present.any(axis=2) & ~present.all(axis=2)).any(axis=1)
                                 | np.isinf(H).any(axis=(1, 2)))
        if partial.size:
            raise DataFileError(f"{where}: H frame {partial[0]} has a marker with some coordinates missing or inf; "
                                "accepted: a missing marker is NaN in all 3 coordinates")
        missing = 1.0 - present[..., 0].mean()
        if missing > MAX_MISSING_FRACTION:
            raise DataFileError(f"{where}: {missing:.0%} of the marker frames are missing; accepted: at most "
                                f"{MAX_MISSING_FRACTION:.0%} (the gaps could not be bridged)")
    else:
        frames = np.flatnonzero(~present.all(axis=(1, 2)))
        if frames.size:
            raise DataFileError(f"{where}: H frame {frames[0]} contains NaN or inf ({frames.size} such frame(s)); "
                                "accepted: finite values (missing markers only in a recording whose noise model "
                                "has occlusion gaps)")
    with np.errstate(invalid="ignore"):
        size = np.nan_to_num(np.abs(H.reshape(len(H), -1)), nan=0.0).max(axis=1)
    _raise_beyond(where, "H", size, MAX_COORDINATE_M, "a marker coordinate of", "m",
                  f"coordinates within +-{MAX_COORDINATE_M:g} m of the scene origin")


def _check_poses(where: str, H: np.ndarray, O: np.ndarray, gaps: bool = False) -> None:
    """Markers as :func:`_check_markers` has them, finite object poses within :data:`MAX_COORDINATE_M`,
    rotation vectors of angle <= pi.

    A corrupt or mis-scaled value would otherwise surface deep in discovery (scipy's rotations, linear
    algebra) without saying where it is; the error names the first bad frame.
    """
    _check_markers(where, H, gaps)
    frames = np.flatnonzero(~np.isfinite(O).all(axis=1))
    if frames.size:
        raise DataFileError(f"{where}: O frame {frames[0]} contains NaN or inf ({frames.size} such "
                            "frame(s)); accepted: finite values")
    bound = f"coordinates within +-{MAX_COORDINATE_M:g} m of the scene origin"
    _raise_beyond(where, "O", np.abs(O[:, :3]).max(axis=1), MAX_COORDINATE_M, "an object coordinate of", "m", bound)
    with np.errstate(over="ignore"):
        angle = np.linalg.norm(O[:, 3:], axis=1)
    _raise_beyond(where, "O", angle, np.pi + ROTATION_SLACK_RAD, "a rotation vector of angle", "rad",
                  "rotation vectors with angle <= pi, as scipy's Rotation.as_rotvec() gives them")


def _raise_beyond(where: str, name: str, size: np.ndarray, limit: float, what: str, unit: str, accepted: str) -> None:
    """Raise DataFileError naming the first frame whose ``size`` (T,) exceeds ``limit``, and how many do."""
    frames = np.flatnonzero(size > limit)
    if frames.size:
        raise DataFileError(f"{where}: {name} frame {frames[0]} has {what} {size[frames[0]]:.3g} {unit} "
                            f"({frames.size} such frame(s)); accepted: {accepted}")
