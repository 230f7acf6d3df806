"""Segmentation metrics against ground-truth frame labels (kept out of learning, used to evaluate it).

All three metrics take per-frame labels of one demonstration (a 1-D array) or of several (a list
of 1-D arrays, same lengths pairwise) and return a number in [0, 1] (multiply by 100 for the
percentages of the action-segmentation literature):

* :func:`hungarian_frame_accuracy`: unsupervised labels are arbitrary ids, so predicted labels are
  matched one-to-one to true ones (Hungarian method on the contingency table, over all
  demonstrations at once so one id means one thing everywhere) before counting correct frames;
* :func:`many_to_one_frame_accuracy`: each predicted label is mapped to the true label it shares
  most frames with (several predicted labels may map to one true label: a method that cuts one
  true action into consecutive primitives, as the paper's Fig. 7 does, is not penalised for it,
  but a predicted label spanning two true actions still is). Never below the one-to-one figure;
  with as many predicted labels as frames it is 1, so read it beside the number of labels;
* :func:`edit_score`: ``1 - Levenshtein / max length`` on the sequences of segment labels, which
  penalises over-segmentation and wrong order but not boundary shifts (Lea et al., 2016);
* :func:`boundary_f1`: label-free; predicted label changes within ``tolerance_frames`` of a true
  one (matched one-to-one) count as hits.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.labels import runs

Labels = np.ndarray | Sequence[np.ndarray] | Sequence[Hashable]
_UNMATCHED = object()  # what an unmapped predicted label becomes: equal to no true label


def hungarian_mapping(pred_labels: Labels, true_labels: Labels) -> dict[Hashable, Hashable]:
    """One-to-one map predicted label -> true label maximising the frames they share, over all demos.

    Predicted labels left over (more predicted than true labels) are absent from the map.
    """
    table, pred_ids, true_ids = _contingency(pred_labels, true_labels)
    rows, cols = linear_sum_assignment(table, maximize=True)
    return {pred_ids[r].item(): true_ids[c].item() for r, c in zip(rows, cols)}


def _contingency(pred_labels: Labels, true_labels: Labels) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames shared by each (predicted, true) label pair over all demos, with the sorted label ids."""
    pred, true = _paired(pred_labels, true_labels)
    pred_ids, pred_index = np.unique(np.concatenate(pred), return_inverse=True)
    true_ids, true_index = np.unique(np.concatenate(true), return_inverse=True)
    table = np.zeros((len(pred_ids), len(true_ids)), dtype=np.int64)
    np.add.at(table, (pred_index.ravel(), true_index.ravel()), 1)
    return table, pred_ids, true_ids


def hungarian_frame_accuracy(pred_labels: Labels, true_labels: Labels) -> float:
    """Fraction of frames whose predicted label, after :func:`hungarian_mapping`, equals the true one."""
    mapping = hungarian_mapping(pred_labels, true_labels)
    pred, true = _paired(pred_labels, true_labels)
    pred_all, true_all = np.concatenate(pred), np.concatenate(true)
    hits = sum(int(np.sum((pred_all == p) & (true_all == t))) for p, t in mapping.items())
    return hits / len(true_all)


def many_to_one_mapping(pred_labels: Labels, true_labels: Labels) -> dict[Hashable, Hashable]:
    """Map every predicted label to the true label it shares most frames with, over all demos.

    Ties go to the true label that sorts first.
    """
    table, pred_ids, true_ids = _contingency(pred_labels, true_labels)
    return {p.item(): true_ids[int(np.argmax(row))].item() for p, row in zip(pred_ids, table)}


def many_to_one_frame_accuracy(pred_labels: Labels, true_labels: Labels) -> float:
    """Fraction of frames whose predicted label, after :func:`many_to_one_mapping`, equals the true one."""
    table, _, _ = _contingency(pred_labels, true_labels)
    return float(table.max(axis=1).sum() / table.sum())


def relabel(labels: Labels, mapping: dict[Hashable, Hashable], unmatched: Hashable = -1) -> list[np.ndarray]:
    """Per-frame labels passed through ``mapping`` (labels it lacks become ``unmatched``), one array per demo.

    Mapping frames before cutting segments lets :func:`edit_score` and :func:`boundary_f1` judge
    the mapped segmentation: consecutive primitives mapped to one action make one segment.
    """
    return [np.array([mapping.get(x, unmatched) for x in seq.tolist()]) for seq in _as_list(labels, "labels")]


def edit_score(pred_labels: Labels, true_labels: Labels, mapping: dict | None = None) -> float:
    """Mean over demos of ``1 - Levenshtein(segments_pred, segments_true) / max(len_pred, len_true)``.

    Segments are runs of equal labels. Give ``mapping`` (e.g. :func:`hungarian_mapping`) to compare
    unsupervised ids with true labels; unmapped predicted labels then match no true label.
    """
    pred, true = _paired(pred_labels, true_labels)
    scores = []
    for p, t in zip(pred, true):
        p_segments = [x if mapping is None else mapping.get(x, _UNMATCHED) for x, _, _ in runs(p)]
        t_segments = [x for x, _, _ in runs(t)]
        longest = max(len(p_segments), len(t_segments))
        scores.append(1.0 if longest == 0 else 1.0 - levenshtein(p_segments, t_segments) / longest)
    return float(np.mean(scores))


def boundary_f1(pred_labels: Labels, true_labels: Labels, tolerance_frames: int) -> float:
    """F1 of predicted segment boundaries against true ones, pooled over demos.

    A boundary is a frame whose label differs from the previous frame's. Each true boundary is hit
    by at most one predicted boundary at most ``tolerance_frames`` away (maximum one-to-one
    matching: a greedy sweep is optimal on a line). No boundaries in either gives 1.
    """
    if isinstance(tolerance_frames, (bool, np.bool_)) or not isinstance(tolerance_frames, (int, np.integer)):
        raise InvalidInputError(f"tolerance_frames must be an int >= 0, got {tolerance_frames!r}")
    if tolerance_frames < 0:
        raise InvalidInputError(f"tolerance_frames must be >= 0, got {tolerance_frames}")
    pred, true = _paired(pred_labels, true_labels)
    hits = n_pred = n_true = 0
    for p, t in zip(pred, true):
        p_bounds, t_bounds = _boundaries(p), _boundaries(t)
        n_pred, n_true = n_pred + len(p_bounds), n_true + len(t_bounds)
        i = j = 0
        while i < len(p_bounds) and j < len(t_bounds):
            if abs(p_bounds[i] - t_bounds[j]) <= tolerance_frames:
                hits, i, j = hits + 1, i + 1, j + 1
            elif p_bounds[i] < t_bounds[j]:
                i += 1
            else:
                j += 1
    if n_pred == 0 and n_true == 0:
        return 1.0
    if hits == 0:
        return 0.0
    precision, recall = hits / n_pred, hits / n_true
    return 2 * precision * recall / (precision + recall)


def levenshtein(a: Sequence[Hashable], b: Sequence[Hashable]) -> int:
    """Edit distance (insertions, deletions, substitutions cost 1), one numpy row per symbol of ``a``.

    Within a row, insertions chain left to right; ``min.accumulate(c - j) + j`` resolves them at once.
    """
    b_items = list(b)
    columns = np.arange(len(b_items) + 1)
    row = columns.copy()
    for i, symbol in enumerate(a, start=1):
        differs = np.array([symbol != x for x in b_items], dtype=np.int64)
        candidate = np.empty_like(row)
        candidate[0] = i
        candidate[1:] = np.minimum(row[1:] + 1, row[:-1] + differs)
        row = np.minimum.accumulate(candidate - columns) + columns
    return int(row[-1])


def _boundaries(labels: np.ndarray) -> list[int]:
    """Frames whose label differs from the previous frame's: where every run but the first starts."""
    return [start for _, start, _ in runs(labels)[1:]]


def _as_list(labels: Labels, name: str) -> list[np.ndarray]:
    """One demo's labels (a 1-D array or a flat list) or several demos' (a list of 1-D arrays)."""
    if isinstance(labels, np.ndarray):
        if labels.ndim != 1:
            raise InvalidInputError(f"{name} must be a 1-D label array or a list of them, got shape {labels.shape}")
        return [labels]
    items = list(labels)
    if not items:
        raise InvalidInputError(f"{name} is empty: give per-frame labels of at least one demonstration")
    if all(np.ndim(x) == 0 for x in items):
        return [np.asarray(items)]
    arrays = [np.asarray(x) for x in items]
    for i, array in enumerate(arrays):
        if array.ndim != 1:
            raise InvalidInputError(f"{name}[{i}] must be a 1-D array of per-frame labels, got shape {array.shape}")
    return arrays


def _paired(pred_labels: Labels, true_labels: Labels) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Validated ``(pred, true)`` lists with matching demo counts and lengths, at least one frame."""
    pred, true = _as_list(pred_labels, "pred_labels"), _as_list(true_labels, "true_labels")
    if len(pred) != len(true):
        raise InvalidInputError(f"got {len(pred)} predicted and {len(true)} true label sequences")
    for i, (p, t) in enumerate(zip(pred, true)):
        if len(p) != len(t):
            raise InvalidInputError(f"demo {i}: {len(p)} predicted labels for {len(t)} frames")
    if sum(len(t) for t in true) == 0:
        raise InvalidInputError("no frames to evaluate")
    return pred, true
