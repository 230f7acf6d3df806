"""The demonstrator's shoulder and elbow from the hand: a posture model learned from every training frame.

A parametric HMM interpolates each state's mean across the effect phi, so with few training locations the
markers whose path bends most with the target (shoulder, elbow) are known at those few points only. How
the body follows the hand, though, shows at every frame of every training movement. :class:`PostureModel`
regresses the shoulder and elbow markers on the wrist's position and the hand's pointing (unit vectors
wrist -> index knuckle and wrist -> thumb tip): polynomial features of the standardised inputs, ridge
penalty. :meth:`PostureModel.complete` replaces those markers of a synthesised movement with its
prediction from the movement's own hand. :func:`choose_alpha` picks the penalty on the training
movements alone, leaving out one group (e.g. one grid location) at a time.

File format (JSON, ``kind`` "PostureModel", ``format_version`` 1): ``params`` (``degree``, ``alpha``),
``input_mean``, ``input_scale`` (9 each), ``feature_mean`` (F), ``target_mean`` (6), ``coef`` (F x 6),
with F the number of monomials of degree 1..``degree`` in 9 inputs.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.demonstration.datasets import N_MARKERS
from hoap_actions.errors import DataFileError, InvalidInputError
from hoap_actions.primitives.base import Estimator, check_is_fitted, file_params
from hoap_actions.primitives.hmm import hmm_math
from hoap_actions.primitives.json_files import JsonModelFile, write_json_model

__all__ = ["PostureModel", "choose_alpha", "hand_inputs"]

# Marker order of the recordings (datasets.MARKER_NAMES): shoulder, elbow, wrist, index tip, knuckle, thumb.
COMPLETED = slice(0, 6)  # shoulder and elbow, xyz each: the markers the model predicts
WRIST, KNUCKLE, THUMB = 2, 4, 5
N_INPUTS = 9  # wrist position (m) and two unit pointing vectors
MIN_POINTING_M = 1e-4  # a knuckle or thumb closer than this to the wrist gives no pointing direction
ALPHAS = (0.01, 0.1, 1.0, 10.0)  # the penalties choose_alpha tries by default (standardised inputs)


def hand_inputs(X: np.ndarray) -> np.ndarray:
    """``(T, 9)`` regression inputs of marker frames ``X`` ``(T, 18)``: the wrist (m), then the unit
    vectors from the wrist to the index knuckle and to the thumb tip."""
    markers = X.reshape(len(X), N_MARKERS, 3)
    wrist = markers[:, WRIST]
    pointing = [markers[:, k] - wrist for k in (KNUCKLE, THUMB)]
    lengths = [np.linalg.norm(p, axis=1, keepdims=True) for p in pointing]
    short = np.flatnonzero(np.minimum(*lengths)[:, 0] < MIN_POINTING_M)
    if short.size:
        raise InvalidInputError(f"frame {short[0]}: the knuckle or thumb marker is within {MIN_POINTING_M * 1e3:g} mm "
                                "of the wrist, so the hand has no pointing direction; markers must be distinct")
    return np.hstack([wrist, pointing[0] / lengths[0], pointing[1] / lengths[1]])


@functools.cache
def _monomials(degree: int) -> np.ndarray:
    """``(F, degree)`` input indices of every monomial of total degree 1..``degree`` in :data:`N_INPUTS`
    variables, padded with index :data:`N_INPUTS` (a column of ones) below full degree."""
    table = [m + (N_INPUTS,) * (degree - len(m)) for d in range(1, degree + 1)
             for m in itertools.combinations_with_replacement(range(N_INPUTS), d)]
    table = np.array(table, dtype=np.intp)
    table.flags.writeable = False
    return table


class PostureModel(JsonModelFile, Estimator):
    """Shoulder and elbow markers as a ridge regression on polynomial features of the hand (module docstring).

    Parameters
    ----------
    degree:
        Highest total degree of the monomials of the 9 standardised inputs (3: 219 features).
    alpha:
        Ridge penalty on the coefficients, in the standardised inputs' units (> 0).

    Attributes (after ``fit``)
    --------------------------
    input_mean_, input_scale_:
        ``(9,)``: the standardisation of :func:`hand_inputs`.
    feature_mean_, target_mean_, coef_:
        ``(F,)``, ``(6,)``, ``(F, 6)``: prediction = (features - feature_mean_) @ coef_ + target_mean_.
    """

    _learned = ("input_mean_", "input_scale_", "feature_mean_", "target_mean_", "coef_")
    _file_kind = "PostureModel"
    _format_version = 1
    _readable_versions = (1,)

    def __init__(self, degree: int = 3, alpha: float = 0.1) -> None:
        self.degree = degree
        self.alpha = alpha

    def _check_params(self) -> None:
        if isinstance(self.degree, bool) or not isinstance(self.degree, (int, np.integer)) or not 1 <= self.degree <= 5:
            raise InvalidInputError(f"degree must be an int from 1 to 5; got {self.degree!r}")
        if not (isinstance(self.alpha, (int, float, np.floating, np.integer)) and np.isfinite(self.alpha)
                and self.alpha > 0):
            raise InvalidInputError(f"alpha must be a finite number > 0; got {self.alpha!r}")

    def _features(self, inputs: np.ndarray) -> np.ndarray:
        """``(T, F)`` monomials of the standardised :func:`hand_inputs` ``inputs``, in one gather."""
        z = (inputs - self.input_mean_) / self.input_scale_
        return np.prod(np.hstack([z, np.ones((len(z), 1))])[:, _monomials(self.degree)], axis=2)

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None) -> PostureModel:
        """Learn from marker frames ``X`` ``(N, 18)`` (6 markers x xyz, m) of movements of ``lengths`` frames
        (the frames are used one by one; ``lengths`` is checked against ``X``)."""
        self._check_params()
        X, _ = hmm_math.validate_sequences(X, lengths)
        if X.shape[1] != 3 * N_MARKERS:
            raise InvalidInputError(f"X must have {3 * N_MARKERS} columns (6 markers x xyz); got shape {X.shape}")
        n_features = len(_monomials(self.degree))
        if len(X) <= n_features:
            raise InvalidInputError(f"degree {self.degree} has {n_features} features: it needs more than {n_features} "
                                    f"frames to fit; got {len(X)}")
        inputs = hand_inputs(X)
        self.input_mean_ = inputs.mean(axis=0)
        self.input_scale_ = np.maximum(inputs.std(axis=0), 1e-9)
        features = self._features(inputs)
        self.feature_mean_ = features.mean(axis=0)
        self.target_mean_ = X[:, COMPLETED].mean(axis=0)
        F = features - self.feature_mean_
        self.coef_ = np.linalg.solve(F.T @ F + self.alpha * np.eye(F.shape[1]),
                                     F.T @ (X[:, COMPLETED] - self.target_mean_))
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        """``(T, 6)``: the shoulder and elbow (xyz, m) the model gives for the hand in frames ``X`` ``(T, 18)``."""
        check_is_fitted(self)
        X = np.asarray(X, dtype=float)
        if X.ndim != 2 or X.shape[1] != 3 * N_MARKERS or not np.all(np.isfinite(X)):
            raise InvalidInputError(f"X must be finite marker frames of shape (T, {3 * N_MARKERS}); got shape "
                                    f"{X.shape}")
        return (self._features(hand_inputs(X)) - self.feature_mean_) @ self.coef_ + self.target_mean_

    def complete(self, X: np.ndarray) -> np.ndarray:
        """A copy of marker frames ``X`` (``(T, 18)`` or ``(T, 6, 3)``) with the shoulder and elbow replaced
        by the model's prediction from the frames' own hand."""
        X = np.asarray(X, dtype=float)
        flat = X.reshape(len(X), -1).copy()
        flat[:, COMPLETED] = self.predict(flat)
        return flat.reshape(X.shape)

    # -- files

    def _write(self, path: Path, overwrite: bool) -> None:
        body = {"params": file_params(self),
                **{name.rstrip("_"): getattr(self, name).tolist() for name in self._learned}}
        write_json_model(path, self._file_kind, self._format_version, body, overwrite)

    @classmethod
    def _from_file(cls, path: Path, document: dict[str, Any], version: int) -> PostureModel:
        try:
            model = cls(**document["params"])
            model._check_params()
            n_features = len(_monomials(model.degree))
            shapes = {"input_mean_": (N_INPUTS,), "input_scale_": (N_INPUTS,), "feature_mean_": (n_features,),
                      "target_mean_": (6,), "coef_": (n_features, 6)}
            for name, shape in shapes.items():
                value = np.array(document[name.rstrip("_")], dtype=float)
                if value.shape != shape or not np.all(np.isfinite(value)):
                    raise DataFileError(f"{path}: {name.rstrip('_')} must be {shape} finite numbers; got shape "
                                        f"{value.shape}")
                setattr(model, name, value)
        except (KeyError, TypeError, ValueError, InvalidInputError) as exc:
            raise DataFileError(f"{path} is not a valid PostureModel file: {exc}") from exc
        if np.any(model.input_scale_ <= 0):
            raise DataFileError(f"{path}: input_scale must be > 0")
        return model


def choose_alpha(
    groups: Sequence[Sequence[np.ndarray]], alphas: Sequence[float] = ALPHAS, degree: int = 3
) -> tuple[float, dict[float, float]]:
    """The ridge penalty that best predicts a left-out group's shoulder and elbow from its own hand.

    ``groups``: movements (``(T, 18)`` marker frames) grouped, e.g. by grid location; each group is left
    out in turn and predicted by a model fitted on the others. Returns the chosen alpha and the RMS
    error (m) of every alpha tried (ties go to the larger penalty).
    """
    if len(groups) < 2:
        raise InvalidInputError(f"choosing alpha needs at least 2 groups of movements to leave out in turn; got "
                                f"{len(groups)}")
    stacked = [np.concatenate([np.asarray(m, dtype=float) for m in group]) for group in groups]
    errors = {}
    for alpha in alphas:
        squared, count = 0.0, 0
        for k, held_out in enumerate(stacked):
            rest = np.concatenate([g for j, g in enumerate(stacked) if j != k])
            model = PostureModel(degree=degree, alpha=alpha).fit(rest)
            squared += float(np.sum((model.predict(held_out) - held_out[:, COMPLETED]) ** 2))
            count += held_out.shape[0] * 2  # two markers per frame
        errors[float(alpha)] = float(np.sqrt(squared / count))
    best = min(errors.values())
    return max(a for a, e in errors.items() if e <= best), errors

