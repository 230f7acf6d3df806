"""The paper's tracking experiment (Figs. 10-12): reaches to table locations the approach PHMM never saw,
tracked from one camera across the table.

The approach PHMM is trained, as in the paper's "The PHMM" section, on the reaches of an ``approach-grid``
recording's 3 x 3 grid (:func:`grid_tracking_models`; its effect phi = (u, v), the block's x, y at the end
of the reach: the pointed position, offsets from the active region's centre), linear as in the paper or
with a thin-plate mean and a :class:`~hoap_actions.primitives.hmm.posture.PostureModel` of the training
grid's frames. The test reaches are the approach phases of the 5 x 7 test grid's episodes
(:func:`grid_reaches`). Each is tracked with the one approach class (:func:`track_grid_reach`); the scores
(:meth:`ReachTrack.summary`) are the paper's: RMS over the reach of shoulder, elbow and finger pooled, each
marker's, and the frame from which the estimated pointed position (the red dot of Fig. 12) stays within
:data:`POINTED_WITHIN_M` of the truth (:func:`settling_frame`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.demonstration.tasks import MARKER_NAMES
from hoap_actions.envs.camera import Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import APPROACH
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.evaluation.grid_synthesis import GridData, fit_grid_model, fit_grid_posture
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.posture import PostureModel
from hoap_actions.primitives.models.class_models import EFFECT_DIM, ClassModel
from hoap_actions.primitives.models.connected_recognition import exit_probability
from hoap_actions.tracking.action_tracker import ActionTracker, TrackedFrame
from hoap_actions.tracking.episode import (
    SCORED_MARKERS,
    TABLE_TOP_Z,
    RenderedFrames,
    pooled_rms,
    render_frames,
    track_frames,
)
from hoap_actions.tracking.tracking_models import TrackingModels
from hoap_actions.vision.body_model import BodyModel

__all__ = ["GRID_MEAN_MODELS", "POINTED_WITHIN_M", "VARIANT_CUES", "GridReach", "ReachTrack",
           "approach_tracking_models", "grid_reaches", "grid_tracking_models", "pool_reaches", "reach_effect_figure",
           "reach_picture", "run_grid_experiment", "settling_frame", "track_grid_reach", "variant_name"]

TRAIN_GRID, TEST_GRID = "3x3", "5x7"
GRID_STATES = 40  # Fig. 8's approach PHMMs
GRID_PHMM = {"covariance_type": "full", "reg_covar": 1e-5, "n_iter": 200, "tol": 1e-3, "random_state": 0}
# thin-plate smoothing: the value Fig. 8's selection chose most often on earlier recordings' 3 x 3 grids
# (15 of 23; docs/experiments/tracking.md)
GRID_MEAN_MODELS = {"linear": {"mean_model": "linear"}, "thin-plate": {"mean_model": "tps", "smoothing": 0.1}}
POINTED_WITHIN_M = 0.02  # the pointed position counts as found within this distance of the truth
BLOCK_CENTRE_Z = 0.025  # m, the block's centre above the table: the height of the effect's (u, v)
FINGER = "index_tip"
# m, the spread of an effect drawn at the seen block: the effect is the block's place, so only the locator's
# jitter (90 % of its errors below 3-4 mm on the tracker's validation recording)
OBJECT_LOCATOR_M = 0.004


@dataclass(frozen=True)
class GridReach:
    """The approach phase of one ``approach-grid`` episode: frames ``[0, end)``, the pointed position
    ``target`` (2,) m (the block's x, y), the grid, the location's ``(row, col)`` and the repetition."""

    episode: int
    end: int
    target: np.ndarray
    grid: str
    location: tuple[int, int]
    repetition: int


def grid_reaches(demos: Demonstrations, grid: str = TEST_GRID) -> list[GridReach]:
    """The reaches of ``grid`` in an ``approach-grid`` recording (episode order), cut as Fig. 8 cuts them."""
    if "approach" not in demos.phase_names:
        raise InvalidInputError(f"this recording has no 'approach' phase (phases {demos.phase_names}); record one "
                                "with: hoap-actions record --preset approach-grid")
    code = demos.phase_names.index("approach")
    reaches = []
    for index, episode in enumerate(demos):
        truth = episode.ground_truth
        if truth.grid != grid:
            continue
        frames = np.flatnonzero(truth.labels == code)
        if not frames.size or frames[0] != 0:
            raise InvalidInputError(f"episode {index}: its approach must start at its first frame (labels "
                                    f"{'none' if not frames.size else f'from frame {frames[0]}'})")
        end = int(frames[-1]) + 1
        reaches.append(GridReach(index, end, episode.O[end - 1, :2].copy(), grid,
                                 (int(truth.grid_index[0]), int(truth.grid_index[1])), int(truth.repetition)))
    if not reaches:
        grids = sorted({e.ground_truth.grid for e in demos} - {""})
        raise InvalidInputError(f"this recording has no reaches of grid {grid!r} (its grids: {grids}); record one "
                                "with: hoap-actions record --preset approach-grid")
    return reaches


def grid_tracking_models(demos: Demonstrations, mean_model: str = "linear", posture: bool = False,
                         train_grid: str = TRAIN_GRID) -> TrackingModels:
    """One approach class for the tracker, its PHMM trained on the ``train_grid`` reaches of ``demos``
    (``mean_model``: a key of :data:`GRID_MEAN_MODELS`), with a posture model of those reaches' frames
    when ``posture``. The class's effect is 6-D as the tracker's are; only the end's x, y (u, v) vary. The
    effect is where the block is: seen, it is drawn at the block within the locator's jitter."""
    if mean_model not in GRID_MEAN_MODELS:
        raise InvalidInputError(f"mean_model must be one of {sorted(GRID_MEAN_MODELS)}; got {mean_model!r}")
    if tuple(demos.marker_names) != MARKER_NAMES:
        raise InvalidInputError(f"the recording's markers {list(demos.marker_names)} are not {list(MARKER_NAMES)}")
    reaches = grid_reaches(demos, train_grid)
    cells: dict[tuple[int, int], list[tuple[np.ndarray, np.ndarray]]] = {}
    for reach in reaches:
        X = demos[reach.episode].H[:reach.end].reshape(reach.end, -1)
        cells.setdefault(reach.location, []).append((X, reach.target))
    data = GridData({train_grid: cells}, {}, {}, {}, tuple(demos.marker_names))
    phmm, _ = fit_grid_model(data, train_grid, n_states=GRID_STATES, **GRID_PHMM, **GRID_MEAN_MODELS[mean_model])
    body = fit_grid_posture(data, train_grid)[0] if posture else None
    return approach_tracking_models(phmm, [m for reps in cells.values() for m in reps], body)


def approach_tracking_models(phmm: ParametricHMM, movements: list[tuple[np.ndarray, np.ndarray]],
                             posture: PostureModel | None = None) -> TrackingModels:
    """One approach class for the tracker from a PHMM fitted on ``movements`` ``(X (T, 18), phi (2,))`` whose
    effect phi is the block's (u, v): the class's 6-D effect varies in the end's x, y alone (the PHMM sees
    them as they are), it starts where the training reaches' finger starts on average, it leaves its last
    state at the rate the training reaches do, and an end drawn at the seen block lies within the block
    locator's jitter of it."""
    if phmm.phi_dim_ != 2 or phmm.n_features_in_ != 3 * len(MARKER_NAMES):
        raise InvalidInputError(f"the approach PHMM must take phi = (u, v) and {3 * len(MARKER_NAMES)} marker "
                                f"coordinates; got phi of {phmm.phi_dim_} and {phmm.n_features_in_} features")
    starts = np.array([x[0].reshape(-1, 3)[MARKER_NAMES.index(FINGER)] for x, _ in movements])
    centre = np.r_[starts.mean(axis=0), 0.0, 0.0, BLOCK_CENTRE_Z]  # phi's (u, v) enter the PHMM as they are
    basis = np.zeros((EFFECT_DIM, 2))
    basis[3, 0] = basis[4, 1] = 1.0
    leave = exit_probability(phmm, [x for x, _ in movements], np.array([p for _, p in movements]))
    approach = ClassModel(0, APPROACH, phmm, centre, basis, leave)
    return TrackingModels({0: approach}, ActionGrammar(0.0).fit([[0]]), MARKER_NAMES, MARKER_NAMES.index(FINGER),
                          posture, object_end=(np.array([0.0, 0.0, BLOCK_CENTRE_Z]), OBJECT_LOCATOR_M))


def settling_frame(errors: np.ndarray, within_m: float = POINTED_WITHIN_M) -> int | None:
    """The first frame from which ``errors`` (T,) stay below ``within_m`` to the last; None when the last
    frame is not within (the estimate never settled)."""
    errors = np.asarray(errors, dtype=float)
    if errors.ndim != 1 or not errors.size:
        raise InvalidInputError(f"errors must be a non-empty (T,) series; got shape {errors.shape}")
    outside = np.flatnonzero(~(errors < within_m))  # NaN counts as outside
    if outside.size and outside[-1] == errors.size - 1:
        return None
    return int(outside[-1]) + 1 if outside.size else 0


@dataclass
class ReachTrack:
    """The track of one reach and its scores (:meth:`summary`)."""

    reach: GridReach
    frames: list[TrackedFrame]
    truth_markers: np.ndarray           # (T, M, 3)
    marker_names: tuple[str, ...]
    particles: int
    track_s: float                      # wall time of edge images, masks, block and filter (rendering excluded)
    torso_base: np.ndarray
    images: list[np.ndarray] = field(default_factory=list)
    edges: list[np.ndarray] = field(default_factory=list)

    def pointed(self) -> np.ndarray:
        """``(T, 2)`` the estimated pointed position (u, v) per frame (m): the particles' mean effect."""
        return np.array([f.end_mean[:2] for f in self.frames])

    def pointed_std(self) -> np.ndarray:
        """``(T, 2)`` the particles' spread of (u, v) per frame (m)."""
        return np.array([f.end_std[:2] for f in self.frames])

    def summary(self) -> dict:
        """RMS (m) per scored marker, pooled over shoulder, elbow and finger (the paper's figure) and over all
        markers; the frame from which the pointed position stays within :data:`POINTED_WITHIN_M` (None: not at
        the end), the pointed position's error at the last frame (m), the reach's frames, frames per second."""
        estimate = np.array([f.markers for f in self.frames])
        distance = np.linalg.norm(estimate - self.truth_markers, axis=2)
        pointed = np.linalg.norm(self.pointed() - self.reach.target, axis=1)
        return {"episode": self.reach.episode, "location": list(self.reach.location),
                "rms_m": {name: float(np.sqrt(np.mean(distance[:, self.marker_names.index(name)] ** 2)))
                          for name in SCORED_MARKERS},
                "rms_m_pooled": pooled_rms(distance, self.marker_names),
                "rms_m_all": float(np.sqrt(np.mean(distance**2))),
                "pointed_frame": settling_frame(pointed), "pointed_error_end_m": float(pointed[-1]),
                "frames": len(self.frames), "hz": len(self.frames) / self.track_s, "particles": self.particles}


def track_grid_reach(models: TrackingModels, demos: Demonstrations, reach: GridReach, rendered: RenderedFrames,
                     particles: int = 400, seed: int = 0, pose_proposal: str = "hand", silhouette: bool = True,
                     object_cue: bool = True, keep_images: bool = False) -> ReachTrack:
    """Track ``reach`` of ``demos`` on its ``rendered`` frames (:func:`~hoap_actions.tracking.episode.render_frames`
    of frames ``range(reach.end)``) with ``models`` (e.g. :func:`grid_tracking_models`); cues and pose proposal
    as for :func:`~hoap_actions.tracking.episode.track_episode` (here poses generated from the hand by default:
    they won on the experiment's validation recording, docs/experiments/tracking.md)."""
    if len(rendered.images) != reach.end:
        raise InvalidInputError(f"rendered holds {len(rendered.images)} frames; the reach has {reach.end}")
    truth = demos[reach.episode].H[:reach.end]
    if not np.all(np.isfinite(truth)):
        raise InvalidInputError(f"episode {reach.episode} has missing markers in its reach: nothing to score against")
    body = BodyModel(models.marker_names, torso_base=rendered.torso_base, hidden_below_z=TABLE_TOP_Z)
    tracker = ActionTracker(models, body, rendered.views, n_particles=particles, pose_proposal=pose_proposal,
                            random_state=seed)
    frames, spent, edges = track_frames(tracker, rendered, silhouette, object_cue, keep_edges=keep_images)
    return ReachTrack(reach, frames, truth, tuple(models.marker_names), particles, spent, rendered.torso_base,
                      [images[0] for images in rendered.images] if keep_images else [], edges)


def reach_effect_figure(track: ReachTrack, path: str | Path, fps: float) -> None:
    """Fig. 11: the estimated pointed position u, v (cm from the active region's centre) over the reach, +-1
    standard deviation of the particles around it, the truth, and the frame it settled within 2 cm."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = np.arange(len(track.frames))
    mean, std = track.pointed() * 100, track.pointed_std() * 100
    settled = track.summary()["pointed_frame"]
    fig, ax = plt.subplots(figsize=(7, 3.4), constrained_layout=True)
    for k, (name, colour) in enumerate((("u (x)", "tab:red"), ("v (y)", "tab:green"))):
        ax.plot(frames, mean[:, k], color=colour, label=f"estimated {name}")
        ax.plot(frames, mean[:, k] - std[:, k], color=colour, linestyle="dotted", linewidth=1)
        ax.plot(frames, mean[:, k] + std[:, k], color=colour, linestyle="dotted", linewidth=1,
                label=f"{name} +-1 sd of the particles")
        ax.axhline(track.reach.target[k] * 100, color=colour, linewidth=0.8, label=f"true {name}")
    if settled is not None:
        ax.axvline(settled, color="black", linestyle="--", linewidth=0.8, label=f"within 2 cm from frame {settled}")
    ax.set_xlabel(f"frame ({fps:.0f} per s)")
    ax.set_ylabel("cm from the active region's centre")
    ax.set_title(f"Fig. 11: the pointed position over a reach to {tuple(track.reach.location)} (episode "
                 f"{track.reach.episode})", fontsize=9)
    ax.legend(fontsize=7, loc="best", ncol=2)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def reach_picture(track: ReachTrack, camera: Camera, t: int) -> np.ndarray:
    """Fig. 12 at frame ``t``: the edge image beside the camera image with the estimated body (red), the
    recorded markers' body (green, thin), the estimated pointed position (red dot) and the true one (green
    ring), and a legend; (H, 2 W, 3) uint8."""
    import cv2

    if not track.images:
        raise InvalidInputError("the track kept no images: track with keep_images=True to draw it")
    frame = track.frames[t]
    body = BodyModel(track.marker_names, torso_base=track.torso_base)
    picture = body.draw(track.images[t], track.truth_markers[t], camera, (0, 160, 0))
    picture = body.draw(picture, frame.markers, camera, (230, 0, 0), thickness=2)
    points = np.array([[*frame.end_mean[:2], BLOCK_CENTRE_Z], [*track.reach.target, BLOCK_CENTRE_Z]])
    (u, v), (tu, tv) = camera.pixels(points)
    if np.all(np.isfinite([tu, tv])):
        cv2.circle(picture, (int(round(tu)), int(round(tv))), 6, (0, 160, 0), 1, lineType=cv2.LINE_AA)
    if np.all(np.isfinite([u, v])):
        cv2.circle(picture, (int(round(u)), int(round(v))), 4, (230, 0, 0), -1, lineType=cv2.LINE_AA)
    error = np.linalg.norm(frame.end_mean[:2] - track.reach.target) * 100
    cv2.putText(picture, f"frame {t}: pointed position {error:.1f} cm off", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42,
                (0, 0, 0), 1, cv2.LINE_AA)
    for row, (text, colour) in enumerate((("red: estimated body, red dot: estimated (u, v)", (230, 0, 0)),
                                          ("green: recorded markers' body, ring: true (u, v)", (0, 140, 0)))):
        cv2.putText(picture, text, (6, picture.shape[0] - 22 + 14 * row), cv2.FONT_HERSHEY_SIMPLEX, 0.36, colour, 1,
                    cv2.LINE_AA)
    edges = cv2.cvtColor((track.edges[t] * 255).astype(np.uint8), cv2.COLOR_GRAY2RGB)
    cv2.putText(edges, f"edge image G, frame {t}", (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1,
                cv2.LINE_AA)
    return np.hstack([edges, picture])


VARIANT_CUES = {"default": (True, True), "edges": (False, False)}  # (silhouette, block located in the image)


def run_grid_experiment(demos: Demonstrations, models: Mapping[str, TrackingModels],
                        variants: Sequence[tuple[str, str, str]], reaches: Sequence[GridReach], particles: int = 400,
                        seed: int = 0, keep: tuple[int, str] | None = None,
                        progress: Callable[[GridReach, str, dict], None] | None = None
                        ) -> tuple[dict[str, list[dict]], list[dict], ReachTrack | None]:
    """Track every reach once per variant ``(models key, pose proposal, cues)`` (cues: ``"default"``, edges,
    silhouette and the block located in the image; ``"edges"``, the edge image alone, the paper's eq. 8), each
    reach rendered once and seen by every variant with the same filter seed. Returns each variant's reach
    summaries (:meth:`ReachTrack.summary`), each reach's baselines (the arm held at its first pose; the
    pointed position put at the training effects' mean) and, with ``keep`` ``(episode, variant)``, that
    track with its images (for Figs. 11 and 12)."""
    for name, proposal, cues in variants:
        if name not in models or cues not in VARIANT_CUES:
            raise InvalidInputError(f"a variant is (models, pose proposal, cues) with models in {sorted(models)} and "
                                    f"cues in {sorted(VARIANT_CUES)}; got {(name, proposal, cues)}")
    results: dict[str, list[dict]] = {variant_name(v): [] for v in variants}
    baselines, kept = [], None
    for reach in reaches:
        rendered = render_frames(demos, reach.episode, range(reach.end))
        truth = demos[reach.episode].H[:reach.end]
        held = np.linalg.norm(truth[:1] - truth, axis=2)
        guess = np.mean([m.classes[0].phmm.train_phi_.mean(axis=0) for m in models.values()], axis=0)
        baselines.append({"episode": reach.episode, "held_still_rms_m_pooled": pooled_rms(held, MARKER_NAMES),
                          "held_still_rms_m_all": float(np.sqrt(np.mean(held**2))),
                          "pointed_at_training_mean_m": float(np.linalg.norm(guess - reach.target))})
        for variant in variants:
            name, proposal, cues = variant
            silhouette, block = VARIANT_CUES[cues]
            keep_this = keep is not None and keep == (reach.episode, variant_name(variant))
            track = track_grid_reach(models[name], demos, reach, rendered, particles, seed, proposal, silhouette,
                                     block, keep_images=keep_this)
            summary = track.summary()
            results[variant_name(variant)].append(summary)
            kept = track if keep_this else kept
            if progress is not None:
                progress(reach, variant_name(variant), summary)
    return results, baselines, kept


def variant_name(variant: tuple[str, str, str]) -> str:
    """``"models / proposal / cues"``: how a variant is named in results."""
    return " / ".join(variant)


def pool_reaches(summaries: Sequence[dict], by_frame: int = 60) -> dict:
    """One recording's figures from its reach summaries: RMS (m) pooled over every frame of every reach, per
    scored marker, over the three (the paper's figure) and over all markers; the share of reaches whose pointed
    position settled within 2 cm by ``by_frame`` (and their count), the median settling frame of those that
    settled, how many never did; the median frame rate."""
    frames = np.array([s["frames"] for s in summaries], float)

    def pooled(values: list[float]) -> float:
        return float(np.sqrt(np.sum(frames * np.square(values)) / frames.sum()))

    settled = [s["pointed_frame"] for s in summaries if s["pointed_frame"] is not None]
    early = sum(frame <= by_frame for frame in settled)
    return {"rms_m": {m: pooled([s["rms_m"][m] for s in summaries]) for m in SCORED_MARKERS},
            "rms_m_pooled": pooled([s["rms_m_pooled"] for s in summaries]),
            "rms_m_all": pooled([s["rms_m_all"] for s in summaries]),
            "pointed_by_frame": by_frame, "pointed_by_frame_count": int(early), "reaches": len(summaries),
            "pointed_by_frame_share": early / len(summaries),
            "pointed_frame_median": float(np.median(settled)) if settled else None,
            "never_settled": len(summaries) - len(settled),
            "pointed_error_end_m_median": float(np.median([s["pointed_error_end_m"] for s in summaries])),
            "hz": float(np.median([s["hz"] for s in summaries]))}
