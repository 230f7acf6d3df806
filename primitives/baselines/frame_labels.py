"""Per-frame class labels: what the recognition baselines share (checked inputs, the class runs they learn
from, the grammar over cut pieces) and the scores every recogniser gets against discovery's labels.

The scores are those of :mod:`hoap_actions.primitives.pipelines.recognize`, for any per-frame labelling:
frames whose true class is unknown (-1) are left out; a true segment is right when the class at most of
its frames is its own; the edit score is 1 minus the Levenshtein distance between the predicted and true
run sequences over the longer one; with the cuts given, a segment is right when its recognised class is.
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping, Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.evaluation.segmentation import levenshtein
from hoap_actions.primitives.labels import runs

__all__ = ["UNKNOWN", "check_frames", "check_labels", "class_runs", "decode_cuts", "episode_scores",
           "estimator_params", "recording_scores", "sequence_bounds", "set_estimator_params", "true_cuts"]

UNKNOWN = -1  # a frame of no class (discovery's UNKNOWN); a recogniser's frames it cannot explain too


def estimator_params(estimator: object) -> dict:
    """The hyper-parameters of ``estimator`` as given to its ``__init__`` (stored under the same names)."""
    names = [p for p in inspect.signature(type(estimator).__init__).parameters if p != "self"]
    return {name: getattr(estimator, name) for name in names}


def set_estimator_params(estimator: object, params: dict, decoding: Sequence[str]) -> None:
    """Set ``params`` on ``estimator`` (checked together by its ``_check_params``; on an error none changes).
    A fitted estimator takes only the ``decoding`` ones, which change how it recognises, not what it learned."""
    names = estimator_params(estimator)
    unknown = sorted(set(params) - set(names))
    if unknown:
        raise InvalidInputError(f"{type(estimator).__name__} has no hyper-parameter(s) {unknown}; it has {list(names)}")
    refit = sorted(set(params) - set(decoding))
    if refit and all(hasattr(estimator, name) for name in estimator._learned):
        raise InvalidInputError(f"this {type(estimator).__name__} is fitted: it takes new values of {list(decoding)} "
                                f"only; fit a new one to change {refit}")
    previous = dict(names)
    estimator.__dict__.update(params)
    try:
        estimator._check_params()
    except InvalidInputError:
        estimator.__dict__.update(previous)
        raise


def check_frames(X: np.ndarray, lengths: Sequence[int] | None, dim: int | None = None
                 ) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """``X`` as finite (N, D) floats (D = ``dim`` when given) and each sequence's ``[start, end)`` frames."""
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or len(X) < 1 or (dim is not None and X.shape[1] != dim) or not np.all(np.isfinite(X)):
        want = f"(N, {dim})" if dim is not None else "(N, D)"
        raise InvalidInputError(f"X must be finite features {want} with N >= 1; got shape {X.shape}")
    if lengths is None:
        return X, [(0, len(X))]
    counts = np.asarray(lengths)
    if counts.ndim != 1 or counts.dtype.kind not in "iu" or np.any(counts < 1) or counts.sum() != len(X):
        raise InvalidInputError(f"lengths must be positive ints summing to len(X) = {len(X)}; got {lengths!r}")
    ends = np.cumsum(counts)
    return X, list(zip((ends - counts).tolist(), ends.tolist()))


def check_labels(labels: np.ndarray | None, n_frames: int) -> np.ndarray:
    """Training labels as (N,) int64: a class id (>= 0) per frame, -1 for a frame of no class."""
    if labels is None:
        raise InvalidInputError("fit needs each frame's class: fit(X, lengths, labels=...) with labels (N,) ints")
    labels = np.asarray(labels)
    if labels.shape != (n_frames,) or labels.dtype.kind not in "iu" or np.any(labels < UNKNOWN):
        raise InvalidInputError(f"labels must be ({n_frames},) ints, one class id per frame (-1: none); got "
                                f"{labels.dtype} {labels.shape}")
    if not np.any(labels >= 0):
        raise InvalidInputError("labels name no class: give each training frame its class id (>= 0)")
    return labels.astype(np.int64)


def class_runs(labels: np.ndarray, bounds: Sequence[tuple[int, int]]
               ) -> tuple[dict[int, list[tuple[int, int]]], list[list[int]]]:
    """Each class's runs ``[start, end)`` (frames of ``labels``), and each sequence's run classes in order
    (what the grammar learns from); runs of -1 are left out."""
    pieces: dict[int, list[tuple[int, int]]] = {}
    sequences = []
    for a, b in bounds:
        order = []
        for c, start, end in runs(labels[a:b]):
            if c != UNKNOWN:
                pieces.setdefault(int(c), []).append((a + start, a + end))
                order.append(int(c))
        if order:
            sequences.append(order)
    return pieces, sequences


def sequence_bounds(cuts: Sequence[tuple[int, int]], n_frames: int) -> list[tuple[int, int]]:
    """``cuts`` checked: non-empty pieces ``[start, end)`` of a sequence of ``n_frames``, in order, not overlapping."""
    cuts = [(int(a), int(b)) for a, b in cuts]
    ends = [0] + [b for _, b in cuts[:-1]]
    if not cuts or any(not (previous <= a < b <= n_frames) for (a, b), previous in zip(cuts, ends)):
        raise InvalidInputError(f"cuts must be (start, end) pieces of the {n_frames} frames, in order, each with "
                                f"start < end and none overlapping; got {cuts!r:.120}")
    return cuts


def decode_cuts(grammar: ActionGrammar, scores: list[Mapping[int, float]], penalty: float | None) -> np.ndarray:
    """The grammatical class sequence that best explains consecutive pieces with these class log-scores;
    each piece's best class on its own when the strict grammar parses no sequence of them."""
    try:
        labels, _ = grammar.decode(scores, penalty)
    except InvalidInputError:
        labels = [max(s, key=s.get) for s in scores]
    return np.asarray(labels, dtype=np.int64)


def true_cuts(truth: np.ndarray) -> list[tuple[int, int, int]]:
    """The true segments ``(class, start, end)`` of one episode's labels, runs of unknown frames left out."""
    return [(int(c), a, b) for c, a, b in runs(truth) if c != UNKNOWN]


def episode_scores(predicted: np.ndarray, truth: np.ndarray, cut_classes: np.ndarray | None = None) -> dict:
    """One episode's counts: frames right / scored, true segments right / all, edit score, and (given the
    class recognised for each of :func:`true_cuts`) segments right with the cuts given."""
    predicted, truth = np.asarray(predicted), np.asarray(truth)
    if predicted.shape != truth.shape or truth.ndim != 1:
        raise InvalidInputError(f"predicted and true labels must be 1-D of one length; got {predicted.shape} and "
                                f"{truth.shape}")
    segments = true_cuts(truth)
    known = truth != UNKNOWN
    right = 0
    for c, a, b in segments:
        values, counts = np.unique(predicted[a:b], return_counts=True)
        right += int(values[counts.argmax()] == c)
    predicted_runs = [int(v) for v, _, _ in runs(predicted)]
    longest = max(len(predicted_runs), len(segments))
    scores = {
        "frames_right": int(np.sum(predicted[known] == truth[known])),
        "frames": int(known.sum()),
        "segments_right": right,
        "segments": len(segments),
        "edit": 1.0 if longest == 0 else 1.0 - levenshtein(predicted_runs, [c for c, _, _ in segments]) / longest,
    }
    if cut_classes is not None:
        cut_classes = np.asarray(cut_classes)
        if cut_classes.shape != (len(segments),):
            raise InvalidInputError(f"give one class per true segment ({len(segments)}); got {cut_classes.shape}")
        scores["cuts_right"] = int(np.sum(cut_classes == [c for c, _, _ in segments]))
    return scores


def recording_scores(episodes: Sequence[dict]) -> dict:
    """A recording's figures from its episodes' :func:`episode_scores`: frame and segment accuracy pooled
    over its frames and segments, the edit score averaged over its episodes, and the accuracy with the
    cuts given when every episode has it."""
    frames = sum(e["frames"] for e in episodes)
    segments = sum(e["segments"] for e in episodes)
    out = {
        "frame_accuracy": sum(e["frames_right"] for e in episodes) / max(frames, 1),
        "segment_accuracy": sum(e["segments_right"] for e in episodes) / max(segments, 1),
        "edit_score": float(np.mean([e["edit"] for e in episodes])),
    }
    if episodes and all("cuts_right" in e for e in episodes):
        out["oracle_cut_accuracy"] = sum(e["cuts_right"] for e in episodes) / max(segments, 1)
    return out
