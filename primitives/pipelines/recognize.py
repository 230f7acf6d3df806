"""The pipeline behind ``hoap-actions recognize``: recognise every episode of a held-out recording.

Two ways, each scored against the classes the models' discovery assigns to the held-out recording
from its object trajectories (frames it cannot parse are left out):

- **from the movement alone** (:meth:`ActionModels.decode`): the arm markers are cut and classified
  together; scored frame by frame (``frame_accuracy``), per true segment (``segment_accuracy``: the
  class at most of its frames is the true one) and as a sequence (``edit_score``: 1 minus the
  Levenshtein distance between the predicted and true run sequences over the longer one, averaged
  over episodes, as in action-segmentation work);
- **with the cuts given** (``oracle_cut_accuracy``): the true segments recognised together through
  the grammar (:meth:`ActionModels.decode_segments`): the upper bound that perfect cutting allows.

Baseline, so a reader sees what the chains and the grammar add: every frame on its own takes the class
of the state whose Gaussian (over the training effects, on the features connected recognition uses)
explains it best (``baseline_frame_accuracy``, ``baseline_edit_score``).

Effect error (``phi_error_median_m``): mean distance of the estimated initial and final locations to
the true ones, over the decoded segments whose class is right and that overlap their true segment
by more than half (its frames and theirs), then the median.
"""

from __future__ import annotations

import logging
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from hoap_actions.demonstration.datasets import Demonstrations, Episode
from hoap_actions.errors import InvalidInputError, UnseenDemonstratorWarning
from hoap_actions.parallel import ordered_map
from hoap_actions.primitives.discovery.estimator import MANIPULATION, UNKNOWN
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.pipelines.mocap_cleaning import clean_demonstrations

logger = logging.getLogger(__name__)

__all__ = ["EpisodeScores", "edit_score", "recognize_recording"]


def edit_score(predicted: list, truth: list) -> float:
    """1 - Levenshtein(predicted, truth) / max(len): 1 for the same sequence, 0 for nothing in common."""
    n, k = len(predicted), len(truth)
    if max(n, k) == 0:
        return 1.0
    row = np.arange(k + 1, dtype=float)
    for i in range(1, n + 1):
        previous, row[0] = row.copy(), i
        for j in range(1, k + 1):
            row[j] = min(previous[j] + 1, row[j - 1] + 1, previous[j - 1] + (predicted[i - 1] != truth[j - 1]))
    return 1.0 - row[k] / max(n, k)


@dataclass(frozen=True)
class EpisodeScores:
    """One episode's counts: frames right / scored, true segments right / all, edit score, effect errors (m)."""

    frames_right: int
    frames: int
    segments_right: int
    segments: int
    edit: float
    phi_errors: tuple[float, ...]
    oracle_right: int
    oracle_phi_errors: tuple[float, ...]
    decode_s: float
    baseline_frames_right: int
    baseline_edit: float


_WORKER: dict = {}


def _start_worker(models: ActionModels, hand_marker: int, oracle: bool) -> None:
    """Give a worker process the models once, not with every episode."""
    _WORKER.update(models=models, hand_marker=hand_marker, oracle=oracle)


def _score_episode(job: tuple[Episode, np.ndarray]) -> EpisodeScores:
    episode, truth = job
    models: ActionModels = _WORKER["models"]
    started = time.perf_counter()
    X = models.features(episode.H)
    log_emissions = models.connected_log_emissions(X)  # the decoder's evidence, and the baseline's
    decoded = models.decode_features(X, log_emissions)
    decode_s = time.perf_counter() - started
    predicted = np.full(episode.T, -2)
    for segment in decoded:
        predicted[segment.start:segment.end] = segment.class_id
    known = truth != UNKNOWN
    true_runs = [r for r in runs(truth) if r[0] != UNKNOWN]
    segments_right = sum(int(np.bincount(predicted[a:b] + 2).argmax()) - 2 == c for c, a, b in true_runs)
    errors = []
    for segment in decoded:
        for c, a, b in true_runs:
            overlap = min(b, segment.end) - max(a, segment.start)
            if c == segment.class_id and overlap > 0.5 * max(b - a, segment.end - segment.start):
                errors.append(_phi_error(segment.phi, _true_phi(episode, c, a, b, models)))
    baseline = models.chained().class_ids[models.chained().state_class[log_emissions.argmax(axis=1)]]
    oracle_right, oracle_errors = 0, []
    if _WORKER["oracle"] and true_runs:
        recognised = models.decode_segments([episode.H[a:b] for _, a, b in true_runs])
        for (c, a, b), rec in zip(true_runs, recognised):
            if rec.class_id == c:
                oracle_right += 1
                oracle_errors.append(_phi_error(rec.phi, _true_phi(episode, c, a, b, models)))
    return EpisodeScores(
        frames_right=int(np.sum(predicted[known] == truth[known])),
        frames=int(known.sum()),
        segments_right=int(segments_right),
        segments=len(true_runs),
        edit=edit_score([v for v, *_ in runs(predicted)], [c for c, *_ in true_runs]),
        phi_errors=tuple(e for e in errors if np.isfinite(e)),
        oracle_right=oracle_right,
        oracle_phi_errors=tuple(e for e in oracle_errors if np.isfinite(e)),
        decode_s=decode_s,
        baseline_frames_right=int(np.sum(baseline[known] == truth[known])),
        baseline_edit=edit_score([v for v, *_ in runs(baseline)], [c for c, *_ in true_runs]),
    )


def _warn_if_unseen(models: ActionModels, demos: Demonstrations) -> None:
    """Warn when the models know who they learned from and this recording's demonstrator is not among them."""
    seen = models.demonstrators_
    demonstrator = demos.demonstrator
    if seen and demonstrator not in seen:
        warnings.warn(
            f"the recording's demonstrator {demonstrator['name']!r} ({demonstrator['height_m']} m, speed "
            f"{demonstrator['speed']}) is none of those the models learned from "
            f"({', '.join(d['name'] for d in seen)}): "
            "expect lower segment accuracy and edit score (docs/experiments/demonstrators.md)",
            UnseenDemonstratorWarning, stacklevel=3)


def _true_phi(episode: Episode, class_id: int, start: int, end: int, models: ActionModels) -> np.ndarray:
    """The effect of frames [start, end): the object's locations for a manipulation, the hand marker's otherwise."""
    if models.classes_[class_id].kind == MANIPULATION:
        return np.concatenate([episode.O[start, :3], episode.O[end - 1, :3]])
    marker = _WORKER["hand_marker"]
    return np.concatenate([episode.H[start, marker], episode.H[end - 1, marker]])


def _phi_error(estimate: np.ndarray, truth: np.ndarray) -> float:
    return float(0.5 * (np.linalg.norm(estimate[:3] - truth[:3]) + np.linalg.norm(estimate[3:] - truth[3:])))


def recognize_recording(
    models: ActionModels, demos: Demonstrations, jobs: int = 1, oracle: bool = True, progress: bool = False
) -> dict:
    """Recognise every episode of ``demos`` (never seen by ``models``, cleaned as their declared noise
    requires: :mod:`~hoap_actions.primitives.pipelines.mocap_cleaning`); the figures of the module docstring.

    ``jobs`` worker processes share the episodes (the figures do not depend on it).
    """
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise InvalidInputError(f"jobs must be an int >= 1; got {jobs!r}")
    if tuple(demos.marker_names) != tuple(models.marker_names_) or demos.fps != models.fps_:
        raise InvalidInputError(
            f"the recording has markers {list(demos.marker_names)} at {demos.fps} fps but the models were learned "
            f"from {list(models.marker_names_)} at {models.fps_} fps; recognise recordings of the same kind"
        )
    _warn_if_unseen(models, demos)
    started = time.perf_counter()
    demos = clean_demonstrations(demos)
    truth = models.discovery_.predict(np.concatenate([e.O for e in demos]), [e.T for e in demos])
    jobs_list = list(zip(demos, truth))
    initargs = (models, models.discovery_.hand_marker, oracle)
    bar = dict(total=len(jobs_list), desc="recognising episodes", unit="episode",
               disable=not (progress and sys.stderr.isatty()))
    if jobs == 1:
        _start_worker(*initargs)
        scores = [_score_episode(job) for job in tqdm(jobs_list, **bar)]
    else:
        scores = list(tqdm(ordered_map(_score_episode, jobs_list, _start_worker, initargs, jobs), **bar))
    wall = time.perf_counter() - started
    frames = sum(s.frames for s in scores)
    segments = sum(s.segments for s in scores)
    phi_errors = [e for s in scores for e in s.phi_errors]
    oracle_errors = [e for s in scores for e in s.oracle_phi_errors]
    movement = sum(e.T for e in demos) / demos.fps
    return {
        "frame_accuracy": sum(s.frames_right for s in scores) / max(frames, 1),
        "segment_accuracy": sum(s.segments_right for s in scores) / max(segments, 1),
        "edit_score": float(np.mean([s.edit for s in scores])),
        "baseline_frame_accuracy": sum(s.baseline_frames_right for s in scores) / max(frames, 1),
        "baseline_edit_score": float(np.mean([s.baseline_edit for s in scores])),
        "oracle_cut_accuracy": sum(s.oracle_right for s in scores) / max(segments, 1) if oracle else None,
        "phi_error_median_m": float(np.median(phi_errors)) if phi_errors else None,
        "oracle_cut_phi_error_median_m": float(np.median(oracle_errors)) if oracle_errors else None,
        "episodes": len(scores),
        "segments": segments,
        "frames_scored": frames,
        "wall_s": wall,
        "decode_s": float(sum(s.decode_s for s in scores)),
        "movement_s": movement,
        "jobs": jobs,
    }
