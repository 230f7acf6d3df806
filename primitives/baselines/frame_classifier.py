"""A frame-wise classifier with temporal smoothing: scikit-learn's gradient boosting on a window of
per-frame features, the recogniser an action-segmentation reader compares connected recognition with.

Each frame is described by the features of the frames at ``offsets`` around it (clamped at the sequence's
ends); :func:`marker_frame_features` gives the per-frame features of arm markers (positions relative to
the shoulder, the shoulder itself, velocities). A ``HistGradientBoostingClassifier`` learns each frame's
class from every ``train_stride``-th training frame (neighbouring frames nearly repeat one another). Its
frame-by-frame classes are then smoothed (``smoothing``):

- ``"none"``: each frame's likeliest class;
- ``"majority"``: the class most frames in a centred window of ``smoothing_window`` frames take;
- ``"grammar"``: Viterbi over one state per class, the classifier's posteriors (floored at
  :data:`PROBABILITY_FLOOR`: boosting's underflow to 0 would rule a class out for good) over the class's
  share of the training frames as evidence (``emission_weight`` times their log), staying in a class with the
  geometric duration of its training runs and leaving it only to a class the grammar allows next
  (the project's :class:`~hoap_actions.primitives.models.connected_recognition.ChainedHMM` with chains
  of one state).

scikit-learn is an optional dependency (``pip install "hoap-actions[bench]"``), imported when a model is fitted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.baselines.frame_labels import (
    check_frames,
    check_labels,
    class_runs,
    estimator_params,
    sequence_bounds,
    set_estimator_params,
)
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.models.connected_recognition import ChainedHMM

__all__ = ["PROBABILITY_FLOOR", "SMOOTHINGS", "FrameClassifier", "marker_frame_features", "window_features"]

SMOOTHINGS = ("none", "majority", "grammar")
PROBABILITY_FLOOR = 1e-6  # the least class probability "grammar" smoothing reads


def marker_frame_features(H: np.ndarray, fps: float, reference: int = 0) -> np.ndarray:
    """Per-frame features of one movement's markers ``(T, M, 3)`` or ``(T, 3M)`` (m) recorded at ``fps``:
    the ``reference`` marker's position (the shoulder), every other marker's position relative to it, and
    every marker's velocity (m/s, central differences): ``(T, 6M)``."""
    H = np.asarray(H, dtype=float)
    if H.ndim not in (2, 3) or H.reshape(len(H), -1).shape[1] % 3 or len(H) < 1:
        raise InvalidInputError(f"markers must be (T, M, 3) or (T, 3M) positions (m); got shape {H.shape}")
    P = H.reshape(len(H), -1, 3)
    if not 0 <= reference < P.shape[1]:
        raise InvalidInputError(f"reference must index one of the {P.shape[1]} markers; got {reference!r}")
    relative = np.delete(P - P[:, reference:reference + 1], reference, axis=1).reshape(len(P), -1)
    velocity = np.gradient(P.reshape(len(P), -1), axis=0) * fps if len(P) > 1 else np.zeros((1, P[0].size))
    return np.hstack([P[:, reference], relative, velocity])


def window_features(X: np.ndarray, bounds: Sequence[tuple[int, int]], offsets: Sequence[int]) -> np.ndarray:
    """Each frame's features beside those of the frames ``offsets`` away in its sequence (clamped at the
    sequence's ends): ``(N, D * len(offsets))``."""
    offsets = np.asarray(offsets, dtype=np.int64)
    out = np.empty((len(X), X.shape[1] * offsets.size))
    for a, b in bounds:
        index = np.clip(np.arange(b - a)[:, None] + offsets[None, :], 0, b - a - 1)
        out[a:b] = X[a:b][index].reshape(b - a, -1)
    return out


class FrameClassifier:
    """Recognise each frame's class with gradient boosting on a window of features, then smooth in time.

    Parameters
    ----------
    offsets
        frames (relative to the classified one) whose features describe it.
    train_stride
        fit on every this-many-th training frame.
    max_iter, learning_rate, max_leaf_nodes, l2_regularization
        ``HistGradientBoostingClassifier``'s (no early stopping: ``max_iter`` rounds). Without an L2
        penalty (scikit-learn's default) the boosting diverged on the ``paper`` classes, some of which
        have a single short run: its training accuracy fell after a few rounds.
    smoothing, smoothing_window, emission_weight
        the temporal smoothing (module docstring).
    random_state
        seed of the boosting's random draws.
    n_threads
        OpenMP threads the boosting may use (fit and predict); on a shared machine more than one can be
        many times slower, as its threads wait on one another.

    Attributes
    ----------
    classifier_
        the fitted ``sklearn.ensemble.HistGradientBoostingClassifier``.
    class_ids_
        (C,) the classes, sorted (the classifier's ``classes_``).
    log_prior_
        (C,) log share of the training frames of each class.
    grammar_
        :class:`ActionGrammar` of the class runs' order in the training sequences.
    chained_
        :class:`ChainedHMM` of one state per class (what ``"grammar"`` smoothing decodes with).
    """

    _learned = ("classifier_", "class_ids_", "log_prior_", "grammar_", "chained_")

    def __init__(self, offsets: Sequence[int] = (-20, -10, 0, 10, 20), train_stride: int = 8, max_iter: int = 100,
                 learning_rate: float = 0.1, max_leaf_nodes: int = 31, l2_regularization: float = 1.0,
                 smoothing: str = "grammar", smoothing_window: int = 25, emission_weight: float = 1.0,
                 random_state: int = 0, n_threads: int = 1) -> None:
        self.offsets = offsets
        self.train_stride = train_stride
        self.max_iter = max_iter
        self.learning_rate = learning_rate
        self.max_leaf_nodes = max_leaf_nodes
        self.l2_regularization = l2_regularization
        self.smoothing = smoothing
        self.smoothing_window = smoothing_window
        self.emission_weight = emission_weight
        self.random_state = random_state
        self.n_threads = n_threads

    def get_params(self) -> dict:
        """The hyper-parameters as given to ``__init__``."""
        return estimator_params(self)

    DECODING_PARAMS = ("smoothing", "smoothing_window", "emission_weight", "n_threads")
    """Hyper-parameters only recognition reads: a fitted model takes new values of these (:meth:`set_params`)."""

    def set_params(self, **params: object) -> FrameClassifier:
        """Set hyper-parameters (a fitted model: :data:`DECODING_PARAMS` only) and return ``self``."""
        set_estimator_params(self, params, self.DECODING_PARAMS)
        return self

    def _check_params(self) -> None:
        offsets = self.offsets
        if (isinstance(offsets, (str, bytes)) or not isinstance(offsets, Sequence) or not offsets
                or any(isinstance(o, bool) or not isinstance(o, (int, np.integer)) for o in offsets)):
            raise InvalidInputError(f"offsets must be a non-empty sequence of int frame offsets; got {offsets!r}")
        for name, low in (("train_stride", 1), ("max_iter", 1), ("max_leaf_nodes", 2), ("smoothing_window", 1),
                          ("n_threads", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise InvalidInputError(f"{name} must be an int >= {low}; got {value!r}")
        for name, low, open_low in (("learning_rate", 0.0, True), ("l2_regularization", 0.0, False),
                                    ("emission_weight", 0.0, True)):
            value = getattr(self, name)
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value)
            if not (ok and (value > low if open_low else value >= low)):
                raise InvalidInputError(f"{name} must be a number {'>' if open_low else '>='} {low}; got {value!r}")
        if self.smoothing not in SMOOTHINGS:
            raise InvalidInputError(f"smoothing must be one of {SMOOTHINGS}; got {self.smoothing!r}")

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None, labels: np.ndarray | None = None
            ) -> FrameClassifier:
        """Fit the classifier on the per-frame features ``X`` (N, D), ``lengths`` frames per sequence
        (``None``: one), and ``labels`` (N,) (class ids; -1: a frame of no class, not learned from); the
        grammar and the classes' durations from the labels' runs."""
        HistGradientBoostingClassifier = _import_sklearn()
        self._check_params()
        X, bounds = check_frames(X, lengths)
        labels = check_labels(labels, len(X))
        rows = np.concatenate([np.arange(a, b, self.train_stride) for a, b in bounds])
        rows = rows[labels[rows] >= 0]
        features = window_features(X, bounds, self.offsets)
        classifier = HistGradientBoostingClassifier(
            max_iter=self.max_iter, learning_rate=self.learning_rate, max_leaf_nodes=self.max_leaf_nodes,
            l2_regularization=self.l2_regularization, early_stopping=False, random_state=self.random_state)
        with _threads(self.n_threads):
            self.classifier_ = classifier.fit(features[rows], labels[rows])
        self.class_ids_ = np.asarray(self.classifier_.classes_, dtype=np.int64)
        counts = np.array([np.sum(labels == c) for c in self.class_ids_], dtype=float)
        self.log_prior_ = np.log(counts / counts.sum())
        pieces, sequences = class_runs(labels, bounds)
        self.grammar_ = ActionGrammar(0.0).fit(sequences)
        exits = np.array([len(pieces[c]) / counts[k] for k, c in enumerate(self.class_ids_.tolist())])
        self.chained_ = self._chain(exits)
        return self

    def _chain(self, exits: np.ndarray) -> ChainedHMM:
        """One state per class, leaving it with probability ``exits`` per frame into a class the grammar allows."""
        n = len(self.class_ids_)
        symbols = {int(s): i + 1 for i, s in enumerate(self.grammar_.symbols_)}
        missing = [c for c in self.class_ids_.tolist() if c not in symbols]
        if missing:
            raise InvalidInputError(f"classes {missing} have no run of their own in the labels; give each class a run")
        index = np.array([symbols[c] for c in self.class_ids_.tolist()])
        with np.errstate(divide="ignore"):
            log_a = np.log(self.grammar_.transmat_)
            return ChainedHMM(
                class_ids=self.class_ids_, state_class=np.arange(n), first=np.arange(n), last=np.arange(n),
                log_stay=np.log1p(-np.minimum(exits, 1.0)), log_next=np.full(n, -np.inf), log_exit=np.log(exits),
                log_start=log_a[0, index], log_end=log_a[index, len(log_a) - 1],
                log_grammar=log_a[np.ix_(index, index)],
                means=np.zeros((n, 0)), variances=np.ones((n, 0)))

    def predict_proba(self, X: np.ndarray, lengths: Sequence[int] | None = None) -> np.ndarray:
        """Each frame's class probabilities (N, C) in the order of ``class_ids_``, before any smoothing."""
        check_is_fitted(self)
        X, bounds = check_frames(X, lengths, self.classifier_.n_features_in_ // len(self.offsets))
        with _threads(self.n_threads):
            return self.classifier_.predict_proba(window_features(X, bounds, self.offsets))

    def predict(self, X: np.ndarray, lengths: Sequence[int] | None = None) -> np.ndarray:
        """Each frame's class id (N,) after the smoothing, sequence by sequence."""
        return self.smooth(self.predict_proba(X, lengths), lengths)

    def smooth(self, proba: np.ndarray, lengths: Sequence[int] | None = None) -> np.ndarray:
        """Each frame's class id (N,) from the frames' class probabilities (:meth:`predict_proba`), smoothed
        sequence by sequence: several smoothings of one set of probabilities without classifying again."""
        check_is_fitted(self)
        proba, bounds = check_frames(proba, lengths, len(self.class_ids_))
        out = np.empty(len(proba), dtype=np.int64)
        for a, b in bounds:
            out[a:b] = self.class_ids_[self._smoothed(proba[a:b])]
        return out

    def _smoothed(self, proba: np.ndarray) -> np.ndarray:
        """One sequence's class indices (T,) from its frames' probabilities (T, C)."""
        best = proba.argmax(axis=1)
        if self.smoothing == "none":
            return best
        if self.smoothing == "majority":
            counts = np.zeros((len(best) + 1, proba.shape[1]))
            counts[np.arange(1, len(best) + 1), best] = 1.0
            counts = counts.cumsum(axis=0)
            t = np.arange(len(best))
            low = np.clip(t - self.smoothing_window // 2, 0, len(best))
            high = np.clip(t + (self.smoothing_window + 1) // 2, 0, len(best))
            return (counts[high] - counts[low]).argmax(axis=1)
        evidence = self.emission_weight * (np.log(np.maximum(proba, PROBABILITY_FLOOR)) - self.log_prior_)
        path, score = self.chained_.viterbi(evidence)
        return path if np.isfinite(score) else best

    def predict_segments(self, X: np.ndarray, cuts: Sequence[tuple[int, int]]) -> np.ndarray:
        """The class of each piece ``[start, end)`` of one sequence ``X`` (T, D) with its cuts given: the
        class most of its frames take in :meth:`predict` of the whole sequence."""
        labels = self.predict(X)
        out = []
        for a, b in sequence_bounds(cuts, len(labels)):
            values, counts = np.unique(labels[a:b], return_counts=True)
            out.append(values[counts.argmax()])
        return np.asarray(out, dtype=np.int64)


def _import_sklearn():
    """scikit-learn's ``HistGradientBoostingClassifier``, or an error saying how to install it."""
    try:
        from sklearn.ensemble import HistGradientBoostingClassifier
    except ImportError:
        raise InvalidInputError('the frame-wise classifier baseline needs scikit-learn: '
                                'pip install "hoap-actions[bench]"') from None
    return HistGradientBoostingClassifier


def _threads(n: int):
    """A context in which OpenMP (the boosting's threads) uses at most ``n`` threads (threadpoolctl comes
    with scikit-learn)."""
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=n, user_api="openmp")
