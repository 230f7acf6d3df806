"""Track a recorded demonstration from the demonstration world's camera (the paper's Figs. 11-12).

Each frame of the episode is rendered again from its recording (the demonstrator's joint angles ``Q``
and the block's pose ``O``: the same image the camera saw), turned into an edge image and given to
the :class:`~hoap_actions.tracking.action_tracker.ActionTracker`. The true markers ``H``
and the classes discovery reads from the block's trajectory are used only to score the track.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA, DEMONSTRATOR_SIDE_CAMERA, DemoScene
from hoap_actions.envs.camera import Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION, UNKNOWN, effect_track
from hoap_actions.primitives.hmm.posture import PostureModel
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.models.approach_ends import approach_ends_by_following_class
from hoap_actions.primitives.models.manipulation_chains import ManipulationChain, manipulation_chains
from hoap_actions.primitives.pipelines.mocap_cleaning import clean_demonstrations
from hoap_actions.tracking.action_tracker import (
    FAR_LEAP_SHARE,
    MARKER_SIGMA_M,
    MARKERS_POSE_SHARPENING,
    ActionTracker,
    TrackedFrame,
)
from hoap_actions.tracking.approach_goal import read_approach_end
from hoap_actions.tracking.chain_reading import read_manipulation_chain
from hoap_actions.tracking.object_evidence import OBJECT_PLACE_M
from hoap_actions.tracking.poses import mean_poses
from hoap_actions.tracking.refinement import PoseRefiner, RefinedEstimates
from hoap_actions.tracking.smoothing import SmoothedFrame
from hoap_actions.tracking.tracking_models import TrackingModels
from hoap_actions.vision.body_model import BodyModel
from hoap_actions.vision.depth_sensor import DepthSensor
from hoap_actions.vision.edges import edge_image
from hoap_actions.vision.objects import ObjectLocator
from hoap_actions.vision.silhouette import BackgroundSubtractor

__all__ = ["SCORED_MARKERS", "RenderedFrames", "TrackResult", "effect_figure", "pooled_rms", "pose_floor",
           "render_frames", "side_cameras", "track_episode", "track_frames", "track_markers_episode",
           "tracking_video_frames"]

SCORED_MARKERS = ("shoulder", "elbow", "index_tip")  # the paper's shoulder, elbow and finger
TABLE_TOP_Z = 0.0  # m, the demonstration table's top in the scene frame: what is below it the camera cannot see
FLOOR_PHASES = 1000  # continuous states tried per frame by pose_floor (a 40-state chain: 25 per state; a fast reach
# moves up to about 9 cm between state means, so 5 per state left the floor up to 8.5 mm above the path's)
CONVERGED_M = 0.02  # an approach's estimated end counts as found once it stays within this of the truth


@dataclass
class TrackResult:
    """The track of one episode and its scores (see :meth:`summary`)."""

    frames: list[TrackedFrame]
    truth_markers: np.ndarray           # (T, M, 3)
    truth_classes: np.ndarray           # (T,) discovery's classes from the object (UNKNOWN = -1)
    approach_ends: list[tuple[int, int, np.ndarray]]  # (start, end, true end (3,)) of each approach piece
    marker_names: tuple[str, ...]
    particles: int
    track_s: float                      # wall time of edge images + filter (rendering excluded)
    torso_base: np.ndarray              # (3,) the body model's fixed trunk base (the lumbar joint)
    silhouette: bool                    # scored with the foreground cue as well as the edges
    edges: list[np.ndarray] = field(default_factory=list)
    images: list[np.ndarray] = field(default_factory=list)
    views: int = 1                      # cameras scored together (eq. 9); 0: tracked from markers
    kinds: dict[int, str] = field(default_factory=dict)  # class id -> approach / manipulation / remove
    lag: int = 0                        # frames of fixed-lag smoothing behind ``smoothed``
    smoothed: list[SmoothedFrame] = field(default_factory=list)  # one per frame when lag > 0
    objects_seen: list[np.ndarray | None] = field(default_factory=list)  # per frame, the tracker's object_seen
    approach_places: dict[int, np.ndarray] = field(default_factory=dict)  # training approach ends by what followed
    chains: list[ManipulationChain] = field(default_factory=list)  # the training manipulations' chains of classes
    action_of_class: dict[int, int] = field(default_factory=dict)  # class id -> action id
    refined: list[TrackedFrame] | list[SmoothedFrame] = field(default_factory=list)  # the quoted estimates, refined
    refine_s: float = 0.0               # wall time of the refinement (s)

    def summary(self) -> dict:
        """RMS errors (m) of the scored markers, of the three pooled (the paper's figure) and of all, frame
        rate, approach-end error and frames to find it, per-frame agreement of the recognised class with
        discovery's (and of its kind: approach, manipulation or remove), and both class sequences; with a
        lag, the same scores of the smoothed estimates under ``"smoothed"``; with a refinement, those of the
        refined estimates (smoothed with a lag) and the frame rate with it under ``"refined"``; with the block's
        sightings and the models' approach places and chains, each approach's end read from the manipulation
        recognised after it (:mod:`~hoap_actions.tracking.approach_goal`), scored as the filter's, and the classes
        with the manipulation read again as the chain the block's displacement fits
        (:mod:`~hoap_actions.tracking.chain_reading`)."""
        scores = self._scores(self.frames)
        recognized = self._recognized()  # the classes both readings of the finished track start from
        errors, found = [], []
        for start, end, target in self.approach_ends:
            gap = np.linalg.norm(np.array([self._approach_end(f) for f in self.frames[start:end]]) - target, axis=1)
            errors.append(float(gap[-1]))
            if gap[-1] < CONVERGED_M:  # found: the frames until it stays within CONVERGED_M to the end
                outside = np.flatnonzero(gap >= CONVERGED_M)
                found.append(int(outside[-1]) + 1 if outside.size else 0)
        smoothed = {"smoothed": {"lag": self.lag, **self._scores(self.smoothed)}} if self.lag else {}
        if self.refined:
            refined = {key: value for key, value in self._scores(self.refined).items() if key != "recognized"}
            smoothed["refined"] = {**refined, "hz": len(self.frames) / (self.track_s + self.refine_s)}
        return {
            **{key: scores[key] for key in ("rms_m", "rms_m_all", "rms_m_pooled")},
            "hz": len(self.frames) / self.track_s,
            "particles": self.particles,
            "cues": ["markers"] if self.views == 0 else ["edges", "silhouette"] if self.silhouette else ["edges"],
            "views": self.views,
            "frames": len(self.frames),
            "phi_error_m": float(np.median(errors)) if errors else None,
            "frames_to_converge": float(np.median(found)) if found else None,
            "approaches_converged": len(found),
            "approaches": len(self.approach_ends),
            **self._task_read_scores(recognized),
            **self._chain_read_scores(recognized),
            **{key: scores[key] for key in ("frame_accuracy", "kind_accuracy", "recognized")},
            "truth": self.truth_classes.tolist(),
            **smoothed,
        }

    def _recognized(self) -> list[int]:
        """The most probable class of each frame, as read ``lag`` frames later when smoothed."""
        return [max(f.class_probabilities, key=f.class_probabilities.get)
                for f in (self.smoothed if self.lag else self.frames)]

    def _chain_read_scores(self, recognized: list[int]) -> dict:
        """The classes with the manipulation read again from the block's seen motion (smoothed classes with a lag;
        :mod:`~hoap_actions.tracking.chain_reading`) and their agreement with discovery's; nothing without the
        block's sightings or the models' chains."""
        if not (self.objects_seen and self.chains and self.action_of_class):
            return {}
        read = read_manipulation_chain(recognized, self.objects_seen, self.chains, self.action_of_class, self.kinds)
        known = self.truth_classes != UNKNOWN
        agreement = float(np.mean(read[known] == self.truth_classes[known])) if known.any() else None
        return {"read_classes": read.tolist(), "read_frame_accuracy": agreement}

    def _task_read_scores(self, classes: list[int]) -> dict:
        """Each approach's end read from the manipulation recognised after it (smoothed classes with a lag): the
        approaches within :data:`CONVERGED_M` of the true end at the approach's last frame and the median error
        (m); nothing without the block's sightings or the models' approach places."""
        if not (self.objects_seen and self.approach_places):
            return {}
        errors = []
        for _, end, target in self.approach_ends:
            following = next((c for c in classes[end - 1:] if self.kinds.get(c) == MANIPULATION), None)
            goal = read_approach_end(self._approach_end(self.frames[end - 1]), following, self.objects_seen[end - 1],
                                     self.approach_places)
            errors.append(float(np.linalg.norm(goal - target)))
        return {"approaches_read_from_task": int(np.sum(np.array(errors) < CONVERGED_M)),
                "read_from_task_error_m": float(np.median(errors)) if errors else None}

    def _approach_end(self, frame: TrackedFrame) -> np.ndarray:
        """The approach's goal as a frame estimates it: its approach classes' ends, weighted by their
        probabilities (the particles that began a manipulation estimate where the object goes, not where
        the hand reached); all particles' end when none is in an approach."""
        shares = {c: frame.class_probabilities.get(c, 0.0) for c, end in frame.class_ends.items()
                  if self.kinds.get(c) == APPROACH}
        total = sum(shares.values())
        if total <= 0:
            return frame.end_mean
        return sum(share * frame.class_ends[c] for c, share in shares.items()) / total

    def _scores(self, estimates: list[TrackedFrame] | list[SmoothedFrame]) -> dict:
        """RMS errors (m) and class agreement of one estimate per frame (each with ``markers`` and
        ``class_probabilities``)."""
        distance = np.linalg.norm(np.array([f.markers for f in estimates]) - self.truth_markers, axis=2)  # (T, M)
        recognized = np.array([max(f.class_probabilities, key=f.class_probabilities.get) for f in estimates])
        known = self.truth_classes != UNKNOWN
        return {
            "rms_m": {name: float(np.sqrt(np.mean(distance[:, self.marker_names.index(name)] ** 2)))
                      for name in SCORED_MARKERS},
            "rms_m_all": float(np.sqrt(np.mean(distance**2))),
            "rms_m_pooled": pooled_rms(distance, self.marker_names),
            "frame_accuracy": float(np.mean(recognized[known] == self.truth_classes[known])) if known.any() else None,
            "kind_accuracy": float(np.mean([self.kinds.get(int(a), "unknown") == self.kinds.get(int(b)) for a, b in
                                            zip(recognized[known], self.truth_classes[known])]))
            if known.any() and self.kinds else None,
            "recognized": recognized.tolist(),
        }


def pooled_rms(distance: np.ndarray, marker_names: tuple[str, ...]) -> float:
    """The paper's figure: one RMS (m) over the frames of :data:`SCORED_MARKERS` (shoulder, elbow, finger)
    pooled, from per-frame distances ``(T, M)`` of the markers ``marker_names``."""
    scored = [marker_names.index(name) for name in SCORED_MARKERS]
    return float(np.sqrt(np.mean(np.asarray(distance)[:, scored] ** 2)))


def side_cameras(side: bool) -> tuple[Camera, ...]:
    """The views added to the demonstration camera: the side camera when ``side``, else none."""
    return (DEMONSTRATOR_SIDE_CAMERA,) if side else ()


def track_episode(models: ActionModels, demos: Demonstrations, episode: int, particles: int = 400,
                  seed: int = 0, keep_images: bool = False, camera: Camera = DEMONSTRATOR_CAMERA,
                  more_cameras: tuple[Camera, ...] = (), clutter: bool = False, image_noise: float = 0.0,
                  silhouette: bool = True, object_cue: bool = True,
                  progress: Callable[[int, int], None] | None = None, pose_proposal: str = "offsets",
                  posture: PostureModel | None = None, depth_sensor: DepthSensor | None = None,
                  lag: int = 0, pose_sharpening: float = 1.0, depth_weighs: str = "pose",
                  refine: Mapping[str, object] | None = None) -> TrackResult:
    """Render episode ``episode`` of ``demos`` from ``camera`` (the demonstration camera by default) and
    track it (``keep_images``: keep every camera and edge image, for :func:`tracking_video_frames`).
    ``more_cameras`` add views, scored together by eq. (9); the kept images are ``camera``'s. ``clutter``
    puts unrelated objects on the table (:meth:`DemoScene.add_clutter`); ``image_noise`` adds Gaussian
    noise of that standard deviation (share of the full intensity) to every image, drawn from ``seed``.
    ``silhouette`` adds the foreground cue: each image against a picture of the empty table from the same
    camera (taken once, before the episode, with its own noise); False scores edges alone (eq. 8).
    ``pose_proposal`` and ``posture``: how particles pose the arm (:class:`ActionTracker`). ``depth_sensor``
    adds each view's depth image as that sensor reads it (an RGB-D camera; its errors drawn from ``seed``,
    apart from the image noise's) to the evidence. ``lag``: frames of fixed-lag smoothing, scored beside the
    filter's own estimates (:mod:`~hoap_actions.tracking.smoothing`). ``pose_sharpening`` and ``depth_weighs``
    (what the depth images weigh: the pose estimate or the filter): as :class:`ActionTracker`'s. ``refine``: the
    estimates (the smoothed ones with a lag) also refined against their frame's images by a
    :class:`~hoap_actions.tracking.refinement.PoseRefiner` with these settings (``{}``: its defaults), in the
    result's ``refined`` beside the unrefined ones (the same filter run)."""
    ep = _bridged_episode(models, demos, episode)
    views = (camera, *more_cameras)
    frames, kept, pictures, seen = [], [], [], []
    with _Renderer(demos, episode, views, clutter, image_noise, seed, depth_sensor) as renderer:
        body = BodyModel(models.marker_names_, torso_base=renderer.torso_base, hidden_below_z=TABLE_TOP_Z)
        tracker = ActionTracker(TrackingModels.from_action_models(models, posture), body, views, n_particles=particles,
                                pose_proposal=pose_proposal, random_state=seed, lag=lag or None,
                                pose_sharpening=pose_sharpening, depth_weighs=depth_weighs)
        observe = _Observer(tracker, renderer.backgrounds() if silhouette else None,
                            _block_locator(camera, renderer.object_half_size_m) if object_cue else None)
        refine_with = RefinedEstimates(PoseRefiner.from_settings(body, views, refine), seed, episode)
        smoothed: list[SmoothedFrame] = []
        for t in range(ep.T):
            images = renderer.frame(ep, t)
            frames.append(observe(images, renderer.depths()))
            refine_with.keep(images, observe.edges, observe.masks, renderer.depths())
            smoothed += tracker.smoothed_frames() if lag else []
            refine_with.read(smoothed if lag else frames)
            seen.append(tracker.object_seen)
            if keep_images:
                kept.append(observe.edges[0])
                pictures.append(images[0])
            if progress is not None:
                progress(t + 1, ep.T)
        if lag:
            smoothed += tracker.smoothed_frames(final=True)
            refine_with.read(smoothed)
    truth, approaches = _classes_and_approach_ends(models, ep)
    return TrackResult(frames, ep.H, truth, approaches, tuple(models.marker_names_), particles, observe.spent,
                       body.torso_base, silhouette, kept, pictures, len(views), _kinds(models), lag,
                       smoothed, seen, _approach_places(models),
                       manipulation_chains(models.discovery_), _action_of_class(models), refine_with.refined,
                       refine_with.spent)


@dataclass
class RenderedFrames:
    """Camera images of frames of an episode, rendered once so that several trackers see the same ones:
    ``images[t][k]`` (H, W, 3) uint8 of view ``views[k]``, ``backgrounds[k]`` the empty table from it,
    the body model's ``torso_base`` (3,) and the block's half size (m)."""

    images: list[list[np.ndarray]]
    backgrounds: list[np.ndarray]
    views: tuple[Camera, ...]
    torso_base: np.ndarray
    object_half_size_m: float


def render_frames(demos: Demonstrations, episode: int, frames: range, camera: Camera = DEMONSTRATOR_CAMERA,
                  more_cameras: tuple[Camera, ...] = (), clutter: bool = False, image_noise: float = 0.0,
                  seed: int = 0) -> RenderedFrames:
    """The camera images of ``frames`` of episode ``episode`` (as recorded: joint angles and block pose), with
    the empty table first; clutter and noise as for :func:`track_episode` (the same images when it scores
    the silhouette)."""
    if not 0 <= episode < len(demos):
        raise InvalidInputError(f"episode must be in [0, {len(demos) - 1}]; got {episode}")
    ep = demos[episode]
    if not (len(frames) and 0 <= min(frames) and max(frames) < ep.T):
        raise InvalidInputError(f"frames must be a non-empty range within the episode's {ep.T} frames; got {frames}")
    views = (camera, *more_cameras)
    with _Renderer(demos, episode, views, clutter, image_noise, seed) as renderer:
        backgrounds = renderer.backgrounds()
        images = [renderer.frame(ep, t) for t in frames]
    return RenderedFrames(images, backgrounds, views, renderer.torso_base, renderer.object_half_size_m)


def track_frames(tracker: ActionTracker, rendered: RenderedFrames, silhouette: bool = True, object_cue: bool = True,
                 keep_edges: bool = False) -> tuple[list[TrackedFrame], float, list[np.ndarray]]:
    """Track already rendered frames: each frame's belief, the wall time of edge images, masks, block and
    filter (s), and (``keep_edges``) the first view's edge images."""
    observe = _Observer(tracker, rendered.backgrounds if silhouette else None,
                        _block_locator(rendered.views[0], rendered.object_half_size_m) if object_cue else None)
    frames, edges = [], []
    for images in rendered.images:
        frames.append(observe(images))
        if keep_edges:
            edges.append(observe.edges[0])
    return frames, observe.spent, edges


class _Renderer:
    """The demonstration scene posed as an episode records it, each view's image with its noise (a context
    manager: the scene's physics client is closed on exit)."""

    def __init__(self, demos: Demonstrations, episode: int, views: tuple[Camera, ...], clutter: bool,
                 image_noise: float, seed: int, depth_sensor: DepthSensor | None = None) -> None:
        if not (np.isfinite(image_noise) and 0.0 <= image_noise <= 1.0):
            raise InvalidInputError(f"image_noise must be a standard deviation in [0, 1] (share of full intensity); "
                                    f"got {image_noise!r}")
        if not demos.joint_names:
            raise InvalidInputError("this recording has no joint angles (Q), so its camera images cannot be "
                                    "rendered; record it again with this version: hoap-actions record")
        self.joint_names, self.views, self.image_noise = demos.joint_names, views, image_noise
        self.noise = np.random.default_rng([seed, episode])
        self.depth_sensor, self.depth_noise = depth_sensor, np.random.default_rng([seed, episode, 1])
        self._depths: list[np.ndarray] | None = None
        self.scene = DemoScene(body_height_m=demos.demonstrator["height_m"])
        try:
            if clutter:
                self.scene.add_clutter()
            self.torso_base = self.scene.torso_base()
        except BaseException:
            self.scene.close()
            raise
        self.object_half_size_m = self.scene.config.object_size / 2.0

    def __enter__(self) -> _Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.scene.close()

    def _noisy(self, images: list[np.ndarray]) -> list[np.ndarray]:
        if self.image_noise == 0:
            return images
        return [np.clip(image + self.noise.normal(0.0, 255.0 * self.image_noise, image.shape), 0, 255).astype(np.uint8)
                for image in images]

    def backgrounds(self) -> list[np.ndarray]:
        """Each view's picture of the empty table (drawn from the noise before any frame)."""
        return self._noisy([self.scene.render_background(view).rgb for view in self.views])

    def frame(self, ep, t: int) -> list[np.ndarray]:
        self.scene.pose(self.joint_names, ep.Q[t], ep.O[t])
        rendered = [self.scene.render(view) for view in self.views]
        if self.depth_sensor is not None:
            self._depths = [self.depth_sensor.measure(image.depth, self.depth_noise) for image in rendered]
        return self._noisy([image.rgb for image in rendered])

    def depths(self) -> list[np.ndarray] | None:
        """The last frame's depth images as the sensor read them (None without a depth sensor)."""
        return self._depths


def _block_locator(camera: Camera, half_size_m: float) -> ObjectLocator:
    """The block's locator on the plane of its centre, told its size so that it tells a whole block from one under
    the hand (:meth:`ObjectLocator.sighting`)."""
    return ObjectLocator(camera, half_size_m, cube_half_size_m=half_size_m)


class _Observer:
    """One frame's camera images into one tracker step (edge images, foreground masks against the empty table,
    the block's sighting, whole or partly hidden), timed; ``edges`` keeps the last frame's edge images."""

    def __init__(self, tracker: ActionTracker, backgrounds: list[np.ndarray] | None,
                 locate: ObjectLocator | None) -> None:
        self.tracker, self.locate = tracker, locate
        self.subtractors = None if backgrounds is None else [BackgroundSubtractor(empty) for empty in backgrounds]
        self.spent = 0.0
        self.edges: list[np.ndarray] = []
        self.masks: list[np.ndarray] | None = None

    def __call__(self, images: list[np.ndarray], depths: list[np.ndarray] | None = None) -> TrackedFrame:
        started = time.perf_counter()
        self.edges = [edge_image(image) for image in images]
        self.masks = masks = None if self.subtractors is None else [subtract(image) for subtract, image
                                                                    in zip(self.subtractors, images)]
        seen, whole = (None, False) if self.locate is None else self.locate.sighting(images[0])
        frame = self.tracker.step(self.edges, masks, seen, depths, object_whole=whole)
        self.spent += time.perf_counter() - started
        return frame


def track_markers_episode(models: ActionModels, demos: Demonstrations, episode: int, particles: int = 400,
                          seed: int = 0, sigma_m: float = MARKER_SIGMA_M, object_cue: bool = True,
                          pose_proposal: str = "turned", posture: PostureModel | None = None,
                          lag: int = 0, object_place_m: float | None = OBJECT_PLACE_M,
                          far_leap_share: float = FAR_LEAP_SHARE,
                          pose_sharpening: float = MARKERS_POSE_SHARPENING) -> TrackResult:
    """Track episode ``episode`` of ``demos`` from its recorded markers instead of images
    (:meth:`ActionTracker.step_markers`): recognition from motion capture, and the filter's error with
    vision taken out (scored as :func:`track_episode`'s, against the gap-bridged markers). ``object_cue``
    gives the tracker the recorded object's centre, as the camera's block locator does, and ``object_place_m``
    scores its place against each particle's class (None: its motion only, as from the camera); ``far_leap_share``
    (:class:`ActionTracker`) lets a few particles a frame leap anywhere ahead in their chain;
    ``pose_proposal``, ``posture`` and ``lag`` as for :func:`track_episode` (here the hand's turn is posed by
    default: the markers show it)."""
    ep = _bridged_episode(models, demos, episode)
    scene = DemoScene(body_height_m=demos.demonstrator["height_m"])
    try:
        torso_base = scene.torso_base()
    finally:
        scene.close()
    body = BodyModel(models.marker_names_, torso_base=torso_base, hidden_below_z=TABLE_TOP_Z)
    tracker = ActionTracker(TrackingModels.from_action_models(models, posture), body, DEMONSTRATOR_CAMERA,
                            n_particles=particles, pose_proposal=pose_proposal, random_state=seed,
                            lag=lag or None, object_place_m=object_place_m if object_cue else None,
                            far_leap_share=far_leap_share, pose_sharpening=pose_sharpening)
    started = time.perf_counter()
    observed = demos[episode].H  # as recorded: a marker missing in a frame is left out of its likelihood
    frames, seen = [], []
    for t in range(ep.T):
        frames.append(tracker.step_markers(observed[t], sigma_m, ep.O[t, :3] if object_cue else None))
        seen.append(tracker.object_seen)
    spent = time.perf_counter() - started
    truth, approaches = _classes_and_approach_ends(models, ep)
    return TrackResult(frames, ep.H, truth, approaches, tuple(models.marker_names_), particles, spent,
                       body.torso_base, silhouette=False, views=0, kinds=_kinds(models), lag=lag,
                       smoothed=tracker.smoothed_frames(final=True) if lag else [], objects_seen=seen,
                       approach_places=_approach_places(models), chains=manipulation_chains(models.discovery_),
                       action_of_class=_action_of_class(models))


def pose_floor(models: ActionModels, demos: Demonstrations, episode: int, fit_effect: bool = False,
               phases: int = FLOOR_PHASES) -> np.ndarray:
    """How close the models' mean poses can come to episode ``episode``: per frame, the distance ``(T, M)``
    (m) of each marker from the pose of discovery's class of the frame at the segment's true effect (the
    hand's start and end for approach and remove, the object's for a manipulation; ``fit_effect``: the
    effect that fits the segment best, by Nelder-Mead over the class's effect coordinates from the true
    one) and the best of ``phases`` continuous states per frame, with no offset. NaN rows: frames of no
    known class. A tracker whose poses are these means plus offsets cannot do better than this without
    the offsets; the floor tells the models' share of its error from the search's and the image's."""
    if isinstance(phases, bool) or not isinstance(phases, (int, np.integer)) or phases < 2:
        raise InvalidInputError(f"phases must be an int >= 2; got {phases!r}")
    ep = _bridged_episode(models, demos, episode)
    truth, _ = _classes_and_approach_ends(models, ep)
    hand, n_markers = models.discovery_.hand_marker, len(models.marker_names_)
    out = np.full((ep.T, n_markers), np.nan)
    for cid, start, end in runs(truth):
        if cid == UNKNOWN:
            continue
        model = models.classes_[cid]
        states = np.linspace(0.0, model.phmm.n_states - 1, phases)
        observed = ep.H[start:end]

        def distances(phi: np.ndarray, model=model, states=states, observed=observed) -> np.ndarray:
            # this iteration's model, states and frames bound now (it is only called within the iteration)
            poses = mean_poses(model, states, np.tile(phi, (phases, 1)), n_markers).reshape(phases, n_markers, 3)
            d = np.linalg.norm(poses[None] - observed[:, None], axis=3)  # (frames, phases, M)
            return d[np.arange(len(observed)), np.argmin(np.mean(d**2, axis=2), axis=1)]

        track, _ = effect_track(model.kind, ep.O, ep.H[:, hand])
        phi = np.r_[track[start], track[end - 1]]
        best = distances(phi)
        if fit_effect and model.basis.shape[1]:
            reduced = (phi - model.centre) @ model.basis
            outside = phi - model.centre - reduced @ model.basis.T  # the part of phi the class never varied
            fitted = minimize(lambda r, model=model, outside=outside:
                              float(np.mean(distances(model.centre + r @ model.basis.T + outside) ** 2)),
                              reduced, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-7, "maxiter": 300})
            candidate = distances(model.centre + fitted.x @ model.basis.T + outside)
            best = candidate if np.mean(candidate**2) < np.mean(best**2) else best
        out[start:end] = best
    return out


def _bridged_episode(models: ActionModels, demos: Demonstrations, episode: int):
    """Episode ``episode`` of ``demos`` with its marker gaps bridged (the truth a track is scored against),
    after checking that it exists and has the models' markers."""
    if not 0 <= episode < len(demos):
        raise InvalidInputError(f"episode must be in [0, {len(demos) - 1}]; got {episode}")
    if tuple(demos.marker_names) != tuple(models.marker_names_):
        raise InvalidInputError(f"the recording's markers {list(demos.marker_names)} are not the models' "
                                f"{list(models.marker_names_)}")
    return clean_demonstrations(dataclasses.replace(demos, episodes=(demos[episode],)))[0]


def _approach_places(models: ActionModels) -> dict[int, np.ndarray]:
    """The training approaches' ends by the manipulations that followed them (none for models without approach
    ends)."""
    if models.approach_ends_ is None:
        return {}
    return approach_ends_by_following_class(models.discovery_, models.approach_ends_)


def _action_of_class(models: ActionModels) -> dict[int, int]:
    return {int(cid): int(action) for cid, action in models.action_of_class_.items()}


def _kinds(models: ActionModels) -> dict[int, str]:
    return {int(cid): c.kind for cid, c in models.classes_.items()}


def _classes_and_approach_ends(models: ActionModels, ep) -> tuple[np.ndarray, list[tuple[int, int, np.ndarray]]]:
    """Discovery's class of each frame (from the block) and each approach's (start, end, true hand end)."""
    truth = models.discovery_.predict(ep.O, [ep.T])[0]
    hand = models.discovery_.hand_marker
    kinds = _kinds(models)
    approaches = [(start, end, ep.H[end - 1, hand]) for cid, start, end in runs(truth)
                  if cid != UNKNOWN and kinds.get(cid) == "approach"]
    return np.asarray(truth), approaches


def tracking_video_frames(result: TrackResult, body: BodyModel, every: int = 4) -> list[np.ndarray]:
    """Fig. 12 as video frames: the edge image beside the camera image with the estimated body (red), the
    true markers' body (green, thin) and the estimated end of the current primitive (red dot); the
    overlay names the class, its PHMM state and the entropy of the particles' classes, and a legend
    the colours."""
    import cv2

    if not result.images:
        raise InvalidInputError("the track kept no images: track with keep_images=True to film it")
    out = []
    for t in range(0, len(result.frames), every):
        frame = result.frames[t]
        picture = body.draw(result.images[t], result.truth_markers[t], DEMONSTRATOR_CAMERA, (0, 160, 0))
        picture = body.draw(picture, frame.markers, DEMONSTRATOR_CAMERA, (230, 0, 0), thickness=2)
        u, v = DEMONSTRATOR_CAMERA.pixels(frame.end_mean)[0]
        if np.isfinite(u) and np.isfinite(v):
            cv2.circle(picture, (int(round(u)), int(round(v))), 4, (230, 0, 0), -1, lineType=cv2.LINE_AA)
        cv2.putText(picture, f"class {frame.class_id}, state {frame.state}, entropy {frame.entropy:.2f} nats",
                    (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (0, 0, 0), 1, cv2.LINE_AA)
        for row, (text, colour) in enumerate((("estimated body, end of the primitive", (230, 0, 0)),
                                              ("recorded markers' body", (0, 160, 0)))):
            cv2.putText(picture, text, (6, picture.shape[0] - 22 + 14 * row), cv2.FONT_HERSHEY_SIMPLEX, 0.38,
                        colour, 1, cv2.LINE_AA)
        edges = cv2.cvtColor((result.edges[t] * 255).astype(np.uint8), cv2.COLOR_GRAY2RGB)
        cv2.putText(edges, f"edge image, frame {t}", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42,
                    (255, 255, 255), 1, cv2.LINE_AA)
        out.append(np.hstack([edges, picture]))
    return out


def effect_figure(result: TrackResult, path, fps: float) -> None:
    """Fig. 11: the estimated end of the current primitive (x, y) over time, one standard deviation
    around it, and the true end of each approach."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(len(result.frames)) / fps
    mean = np.array([f.end_mean for f in result.frames]) * 100
    std = np.array([f.end_std for f in result.frames]) * 100
    fig, ax = plt.subplots(figsize=(7, 3.2), constrained_layout=True)
    for k, (name, colour) in enumerate((("x", "tab:red"), ("y", "tab:green"))):
        ax.plot(t, mean[:, k], color=colour, label=f"estimated end {name}")
        ax.fill_between(t, mean[:, k] - std[:, k], mean[:, k] + std[:, k], color=colour, alpha=0.2,
                        label=f"+-1 sd of the particles' end {name}")
        for start, end, target in result.approach_ends:
            ax.hlines(target[k] * 100, start / fps, end / fps, colors=colour, linestyles="dotted")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("cm (scene frame)")
    ax.set_title("Fig. 11: the tracked effect; dotted: each approach's true end; shaded: +-1 sd")
    ax.legend(fontsize=8, loc="best")
    fig.savefig(path, dpi=110)
    plt.close(fig)
