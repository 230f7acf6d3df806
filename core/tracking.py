"""Track a recorded demonstration from the demonstration world's camera (the paper's Figs. 11-12).

Each frame of the episode is rendered again from its recording (the demonstrator's joint angles ``Q``
and the block's pose ``O``: the same image the camera saw), turned into an edge image and given to
the :class:`~hoap_actions.primitives.tracking.action_tracker.ActionTracker`. The true markers ``H``
and the classes discovery reads from the block's trajectory are used only to score the track.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hoap_actions.envs.demo_scene import DEMONSTRATOR_CAMERA, DemoScene
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.action_models import ActionModels
from hoap_actions.primitives.datasets import Demonstrations
from hoap_actions.primitives.discovery import UNKNOWN
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.tracking.action_tracker import ActionTracker, TrackedFrame
from hoap_actions.primitives.tracking.body_model import BodyModel
from hoap_actions.primitives.tracking.edges import edge_image

__all__ = ["TrackResult", "track_episode"]

SCORED_MARKERS = ("shoulder", "elbow", "index_tip")  # the paper's shoulder, elbow and finger
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
    edges: list[np.ndarray] = field(default_factory=list)

    def summary(self) -> dict:
        """RMS errors (m) of the scored markers and of all, frame rate, approach-end error and frames to
        find it, per-frame agreement of the recognised class with discovery's, and both class sequences."""
        estimate = np.array([f.markers for f in self.frames])
        distance = np.linalg.norm(estimate - self.truth_markers, axis=2)  # (T, M)
        recognized = np.array([max(f.class_probabilities, key=f.class_probabilities.get) for f in self.frames])
        known = self.truth_classes != UNKNOWN
        errors, converge = [], []
        for start, end, target in self.approach_ends:
            gap = np.array([np.linalg.norm(f.end_mean - target) for f in self.frames[start:end]])
            errors.append(float(gap[-1]))
            outside = np.flatnonzero(gap >= CONVERGED_M)
            converge.append(0 if not outside.size else int(outside[-1]) + 1 if outside[-1] + 1 < gap.size else None)
        found = [c for c in converge if c is not None]
        return {
            "rms_m": {name: float(np.sqrt(np.mean(distance[:, self.marker_names.index(name)] ** 2)))
                      for name in SCORED_MARKERS},
            "rms_m_all": float(np.sqrt(np.mean(distance**2))),
            "hz": len(self.frames) / self.track_s,
            "particles": self.particles,
            "frames": len(self.frames),
            "phi_error_m": float(np.median(errors)) if errors else None,
            "frames_to_converge": float(np.median(found)) if found else None,
            "approaches_converged": f"{len(found)}/{len(converge)}",
            "frame_accuracy": float(np.mean(recognized[known] == self.truth_classes[known])) if known.any() else None,
            "recognized": recognized.tolist(),
            "truth": self.truth_classes.tolist(),
        }


def track_episode(models: ActionModels, demos: Demonstrations, episode: int, particles: int = 400,
                  seed: int = 0, keep_edges: bool = False,
                  progress: Callable[[int, int], None] | None = None) -> TrackResult:
    """Render episode ``episode`` of ``demos`` from the demonstration camera and track it."""
    if not demos.joint_names:
        raise InvalidInputError("this recording has no joint angles (Q), so its camera images cannot be rendered; "
                                "record it again with this version: hoap-actions record")
    if not 0 <= episode < len(demos):
        raise InvalidInputError(f"episode must be in [0, {len(demos) - 1}]; got {episode}")
    if tuple(demos.marker_names) != tuple(models.marker_names_):
        raise InvalidInputError(f"the recording's markers {list(demos.marker_names)} are not the models' "
                                f"{list(models.marker_names_)}")
    ep = demos[episode]
    scene = DemoScene()
    try:
        body = BodyModel(models.marker_names_, torso_base=np.asarray(scene.config.demonstrator_position))
        tracker = ActionTracker(models, body, DEMONSTRATOR_CAMERA, n_particles=particles, random_state=seed)
        frames, kept, spent = [], [], 0.0
        for t in range(ep.T):
            scene.pose(demos.joint_names, ep.Q[t], ep.O[t])
            image = scene.render().rgb
            started = time.perf_counter()
            edges = edge_image(image)
            frames.append(tracker.step(edges))
            spent += time.perf_counter() - started
            if keep_edges:
                kept.append(edges)
            if progress is not None:
                progress(t + 1, ep.T)
    finally:
        scene.close()
    truth = models.discovery_.predict(ep.O, [ep.T])[0]
    hand = models.discovery_.hand_marker
    kinds = {cid: c.kind for cid, c in models.classes_.items()}
    approaches = [(start, end, ep.H[end - 1, hand]) for cid, start, end in runs(truth)
                  if cid != UNKNOWN and kinds.get(cid) == "approach"]
    return TrackResult(frames, ep.H, np.asarray(truth), approaches, tuple(models.marker_names_), particles, spent, kept)
