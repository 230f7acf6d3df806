"""Connected recognition against the recognition baselines on the same recordings: the labels the baselines
learn from (discovery's classes of the training recordings, the classes the action models were learned
with), the features each reads, every method's labels and scores per episode, and a timeline figure.

Callers load and clean the recordings (:func:`hoap_actions.primitives.pipelines.learn.load_training_demonstrations`,
:func:`hoap_actions.primitives.pipelines.mocap_cleaning.clean_demonstrations`) and take the true classes of a
held-out recording from the models' discovery (``models.discovery_.predict``), as
:func:`hoap_actions.primitives.pipelines.recognize.recognize_recording` does.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.baselines.frame_classifier import marker_frame_features
from hoap_actions.primitives.baselines.frame_labels import UNKNOWN, episode_scores, true_cuts
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.class_models import marker_features

__all__ = ["HMM_FEATURES", "classifier_features", "discovery_labels", "hmm_features", "plot_timeline",
           "project_labels", "run_baseline", "timeline_runs"]

HMM_FEATURES = ("displacements", "positions+displacements")
"""What the per-class HMMs read of :func:`~hoap_actions.primitives.models.class_models.marker_features`: the
markers' displacements over 0.1 s (what connected recognition reads) or their positions too."""

EPISODES_PER_BATCH = 4  # episodes whose connected recognition runs together, as recognize_recording's jobs


def discovery_labels(discovery: PrimitiveDiscovery, lengths: Sequence[int]) -> np.ndarray:
    """Each training frame's class (N,) as ``discovery`` cut the demonstrations it was fitted on, which must
    be these, ``lengths`` frames each, in the same order (its segmentations tile every frame)."""
    segmentations = discovery.segmentations_
    if len(segmentations) != len(lengths) or any(
            sum(end - start for _, start, end in seg) != n for seg, n in zip(segmentations, lengths)):
        raise InvalidInputError(f"the discovery was fitted on {len(segmentations)} demonstrations, not on these "
                                f"{len(lengths)} (or not with these frame counts): give the recordings its models "
                                "were learned from, in the same order")
    labels = np.full(int(np.sum(lengths)), UNKNOWN, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    for offset, seg in zip(offsets, segmentations):
        for pid, start, end in seg:
            labels[offset + start:offset + end] = pid
    return labels


def hmm_features(H: np.ndarray, fps: float, features: str) -> np.ndarray:
    """The per-class HMMs' input of one movement's markers (T, M, 3): :data:`HMM_FEATURES`."""
    if features not in HMM_FEATURES:
        raise InvalidInputError(f"features must be one of {HMM_FEATURES}; got {features!r}")
    X = marker_features(H, fps)
    return X[:, X.shape[1] // 2:] if features == "displacements" else X


def classifier_features(H: np.ndarray, fps: float) -> np.ndarray:
    """The frame classifier's per-frame input of one movement's markers: :func:`marker_frame_features`
    relative to the first marker (the shoulder)."""
    return marker_frame_features(H, fps, reference=0)


def run_baseline(estimator, features: Callable[[np.ndarray], np.ndarray], movements: Sequence[np.ndarray],
                 truths: Sequence[np.ndarray], cuts: bool = True) -> dict:
    """A fitted baseline on each movement (its markers) against its true classes: per-episode labels,
    scores (:func:`episode_scores`; with ``cuts``, also each true segment classed with the cuts given,
    ``predict_segments``) and the seconds recognition and classing with the cuts took."""
    labels, scores, recognise_s, cuts_s = [], [], 0.0, 0.0
    for H, truth in zip(movements, truths):
        X = features(H)
        started = time.perf_counter()
        predicted = estimator.predict(X)
        recognised = time.perf_counter()
        segments = true_cuts(truth)
        cut_classes = estimator.predict_segments(X, [(a, b) for _, a, b in segments]) if cuts and segments else (
            np.empty(0, dtype=np.int64) if cuts else None)
        cuts_s += time.perf_counter() - recognised
        recognise_s += recognised - started
        labels.append(predicted)
        scores.append(episode_scores(predicted, truth, cut_classes))
    return {"labels": labels, "scores": scores, "recognise_s": recognise_s, "cuts_s": cuts_s if cuts else None}


def project_labels(models, movements: Sequence[np.ndarray], truths: Sequence[np.ndarray]) -> dict:
    """Connected recognition (:meth:`ActionModels.decode_movements`, the markers alone) of each movement:
    per-episode labels (-1 where no segment was decoded), scores and the seconds it took."""
    labels, scores = [], []
    started = time.perf_counter()
    for k in range(0, len(movements), EPISODES_PER_BATCH):
        batch = [models.features(H) for H in movements[k:k + EPISODES_PER_BATCH]]
        for H, decoded in zip(movements[k:k + EPISODES_PER_BATCH],
                              models.decode_movements([(X, models.connected_log_emissions(X)) for X in batch])):
            predicted = np.full(len(H), UNKNOWN, dtype=np.int64)
            for segment in decoded:
                predicted[segment.start:segment.end] = segment.class_id
            labels.append(predicted)
    recognise_s = time.perf_counter() - started
    scores = [episode_scores(p, t) for p, t in zip(labels, truths)]
    return {"labels": labels, "scores": scores, "recognise_s": recognise_s}


def timeline_runs(labels: Sequence[np.ndarray]) -> list[list[int]]:
    """Consecutive episodes' labels as one list of runs ``[class, start, end]`` (frames counted on from one
    episode to the next): how a timeline is kept in a results file."""
    out, offset = [], 0
    for episode in labels:
        out += [[int(c), offset + a, offset + b] for c, a, b in runs(np.asarray(episode))]
        offset += len(episode)
    return out


def plot_timeline(timeline: dict, path: str | Path) -> None:
    """Draw the true classes and each method's over consecutive episodes (``timeline``: ``rows``, a dict
    name -> runs as :func:`timeline_runs` gives them, the truth first; ``kinds``, class id -> kind;
    ``episode_starts``, frames; ``fps``; ``title``) with a legend for the colours, and mark each method's
    frames whose class is not the true one."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    rows = timeline["rows"]
    truth_name = next(iter(rows))
    truth = np.zeros(max(end for *_, end in rows[truth_name]), dtype=np.int64)
    for c, a, b in rows[truth_name]:
        truth[a:b] = c
    kinds = {int(k): v for k, v in timeline["kinds"].items()}
    shown = sorted({c for runs_ in rows.values() for c, *_ in runs_})
    # approach and remove (most frames) in greys, no class black, the manipulation pieces in 38 hues
    palette = [plt.get_cmap(name)(i) for name in ("tab20", "tab20b") for i in (*range(0, 20, 2), *range(1, 20, 2))
               if name != "tab20" or i not in (14, 15)]  # tab20's own greys left out
    pieces = iter(palette * (1 + len(shown) // len(palette)))
    fixed = {"approach": (0.78, 0.78, 0.78, 1.0), "remove": (0.5, 0.5, 0.5, 1.0)}
    colours = {c: (0.0, 0.0, 0.0, 1.0) if c == UNKNOWN else fixed.get(kinds.get(c), None) or next(pieces)
               for c in shown}
    fps = float(timeline["fps"])
    fig, ax = plt.subplots(figsize=(12, 1.0 + 0.75 * len(rows)))
    for row, runs_ in enumerate(rows.values()):
        y = len(rows) - 1 - row
        for c, a, b in runs_:
            ax.broken_barh([(a / fps, (b - a) / fps)], (y - 0.3, 0.6), facecolors=colours[c], edgecolor="none")
            if row:
                wrong = a + np.flatnonzero((truth[a:b] != c) & (truth[a:b] != UNKNOWN))
                for w0, w1 in _spans(wrong):
                    ax.broken_barh([(w0 / fps, (w1 - w0) / fps)], (y - 0.42, 0.1), facecolors="red")
    for start in timeline["episode_starts"][1:]:
        ax.axvline(start / fps, color="black", linewidth=0.8, linestyle=":")
    ax.set_yticks(range(len(rows)), list(rows)[::-1])
    ax.set_xlabel("time (s); dotted lines: episode boundaries; red ticks: scored frames whose class is not the "
                  "true one")
    ax.set_title(timeline["title"], fontsize=10)
    handles = [Patch(color=colours[c], label="no class" if c == UNKNOWN else f"{c} ({kinds.get(c, '?')})")
               for c in shown]
    ax.legend(handles=handles, title="class (kind)", loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7,
              ncol=1 + len(handles) // 16)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _spans(frames: np.ndarray) -> list[tuple[int, int]]:
    """Sorted frame indices as ``[start, end)`` spans of consecutive frames."""
    if not frames.size:
        return []
    breaks = np.flatnonzero(np.diff(frames) > 1)
    starts = np.r_[frames[0], frames[breaks + 1]]
    ends = np.r_[frames[breaks], frames[-1]] + 1
    return list(zip(starts.tolist(), ends.tolist()))
