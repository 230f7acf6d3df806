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
from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from tqdm import tqdm

from hoap_actions.demonstration.datasets import Demonstrations, Episode
from hoap_actions.errors import InvalidInputError, UnseenDemonstratorWarning
from hoap_actions.parallel import ordered_map
from hoap_actions.primitives.discovery.estimator import MANIPULATION, UNKNOWN
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.action_models import ActionModels, DecodedSegment
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
    """One episode's counts: frames right / scored, true segments right / all, edit score, effect errors (m);
    ``decode_s`` is its share of the time its group of episodes took to decode (:data:`EPISODES_PER_JOB`)."""

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


EPISODES_PER_JOB = 4
"""Episodes a worker scores at a time: their labels are decoded, and their true segments recognised, in
batches (the effect EMs that converge last, and discovery's Viterbi, then share their frames); few enough
that the workers stay evenly loaded. The figures do not depend on ``jobs``, which only decides who scores
each group."""

_WORKER: dict = {}

def _start_worker(models: ActionModels, hand_marker: int, oracle: bool) -> None:
    """Give a worker process the models once, not with every episode."""
    _WORKER.update(models=models, hand_marker=hand_marker, oracle=oracle)


def _score_episodes(job: list[tuple[Episode, np.ndarray]]) -> list[EpisodeScores]:
    """Score a few episodes: all their labels decoded together, then (``oracle``) all their true segments
    recognised together."""
    models: ActionModels = _WORKER["models"]
    true_runs = [[r for r in runs(truth) if r[0] != UNKNOWN] for _, truth in job]
    started = time.perf_counter()
    features = [models.features(episode.H) for episode, _ in job]
    movements = [(X, models.connected_log_emissions(X)) for X in features]  # the decoder's evidence, and the baseline's
    decoded = models.decode_movements(movements)
    decode_s = (time.perf_counter() - started) / len(job)  # each episode's share
    scores = [_label_scores(episode, truth, cuts, segments, log_emissions, decode_s)
              for (episode, truth), cuts, segments, (_, log_emissions) in zip(job, true_runs, decoded, movements)]
    if not _WORKER["oracle"]:
        return scores
    return [replace(s, oracle_right=right, oracle_phi_errors=errors)
            for s, (right, errors) in zip(scores, _oracle_scores([episode for episode, _ in job], true_runs))]


def _label_scores(episode: Episode, truth: np.ndarray, true_runs: list[tuple[int, int, int]],
                  decoded: list[DecodedSegment], log_emissions: np.ndarray, decode_s: float) -> EpisodeScores:
    """An episode's scores from its movement alone, decoded into ``decoded`` (its oracle counts left 0)."""
    models: ActionModels = _WORKER["models"]
    predicted = np.full(episode.T, -2)
    for segment in decoded:
        predicted[segment.start:segment.end] = segment.class_id
    known = truth != UNKNOWN
    segments_right = sum(int(np.bincount(predicted[a:b] + 2).argmax()) - 2 == c for c, a, b in true_runs)
    errors = []
    for segment in decoded:
        for c, a, b in true_runs:
            overlap = min(b, segment.end) - max(a, segment.start)
            if c == segment.class_id and overlap > 0.5 * max(b - a, segment.end - segment.start):
                errors.append(_phi_error(segment.phi, _true_phi(episode, c, a, b, models)))
    baseline = models.chained().class_ids[models.chained().state_class[log_emissions.argmax(axis=1)]]
    return EpisodeScores(
        frames_right=int(np.sum(predicted[known] == truth[known])),
        frames=int(known.sum()),
        segments_right=int(segments_right),
        segments=len(true_runs),
        edit=edit_score([v for v, *_ in runs(predicted)], [c for c, *_ in true_runs]),
        phi_errors=tuple(e for e in errors if np.isfinite(e)),
        oracle_right=0,
        oracle_phi_errors=(),
        decode_s=decode_s,
        baseline_frames_right=int(np.sum(baseline[known] == truth[known])),
        baseline_edit=edit_score([v for v, *_ in runs(baseline)], [c for c, *_ in true_runs]),
    )


def _oracle_scores(episodes: list[Episode], true_runs: list[list[tuple[int, int, int]]]
                   ) -> list[tuple[int, tuple[float, ...]]]:
    """Per episode, its true segments recognised with their cuts given: how many right, and their effect errors."""
    models: ActionModels = _WORKER["models"]
    cut = [i for i, cuts in enumerate(true_runs) if cuts]
    recognised = models.decode_demonstrations([[episodes[i].H[a:b] for _, a, b in true_runs[i]] for i in cut])
    scores = [(0, ())] * len(episodes)
    for i, recognitions in zip(cut, recognised):
        right = [(c, a, b, rec) for (c, a, b), rec in zip(true_runs[i], recognitions) if rec.class_id == c]
        errors = (_phi_error(rec.phi, _true_phi(episodes[i], c, a, b, models)) for c, a, b, rec in right)
        scores[i] = (len(right), tuple(e for e in errors if np.isfinite(e)))
    return scores


def _scored(chunks: list[list[tuple[Episode, np.ndarray]]], initargs: tuple, jobs: int
            ) -> Iterator[list[EpisodeScores]]:
    """Each chunk's scores, in order: in this process (one job) or on ``jobs`` worker processes."""
    if jobs == 1:
        _start_worker(*initargs)
        yield from map(_score_episodes, chunks)
        return
    yield from ordered_map(_score_episodes, chunks, _start_worker, initargs, jobs)


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
    episodes = list(zip(demos, truth))
    chunks = [episodes[i:i + EPISODES_PER_JOB] for i in range(0, len(episodes), EPISODES_PER_JOB)]
    initargs = (models, models.discovery_.hand_marker, oracle)
    bar = tqdm(total=len(episodes), desc="recognising episodes", unit="episode",
               disable=not (progress and sys.stderr.isatty()))
    scores: list[EpisodeScores] = []
    with bar:
        for chunk in _scored(chunks, initargs, jobs):
            scores += chunk
            bar.update(len(chunk))
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
