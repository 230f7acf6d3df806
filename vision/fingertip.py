"""A learned detector of the index fingertip: where, in a window of a camera image about a guess, the fingertip is.

The tracker's edges and silhouettes place the hand's outline, but the fingertip is a small part of it: from two
320 x 240 views their best pose leaves it 1-2 cm off (``docs/experiments/tracking.md``). A detector trained on
rendered demonstrations, whose markers give the fingertip's true pixel, reads it from the window's appearance:
gradient-orientation histograms of its brightness and saturation (skin is saturated, the table and the shirt
less so) into a small multi-layer perceptron (numpy, Adam), which regresses the fingertip's offset from the
window's centre.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from hoap_actions.errors import DataFileError, InvalidInputError, NotFittedError
from hoap_actions.outputs import claimed_file

__all__ = ["WINDOW_HALF_PX", "FingertipDetector", "shipped_fingertip_detector", "window_features", "windows"]

WINDOW_HALF_PX = 24  # a 48 x 48 window: the hand's width and the estimate's usual error (2-4 cm, 6-13 px) inside it
CELL_PX = 8
BINS = 9
FORMAT_VERSION = 1


def windows(image: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """``(n, 48, 48, 3)`` float32 windows of ``image`` (H, W, 3) uint8 centred on the pixels nearest ``centres``
    (n, 2) (column, row), the image's border repeated beyond its edges."""
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise InvalidInputError(f"windows are cut from (H, W, 3) uint8 images; got {image.shape} {image.dtype}")
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(centres)):
        raise InvalidInputError("window centres must be finite pixels")
    half = WINDOW_HALF_PX
    padded = np.pad(image, ((half, half), (half, half), (0, 0)), mode="edge")
    cols = np.clip(np.rint(centres[:, 0]).astype(int), -half, image.shape[1] + half - 1) + half
    rows = np.clip(np.rint(centres[:, 1]).astype(int), -half, image.shape[0] + half - 1) + half
    offsets = np.arange(-half, half)
    r = np.clip(rows[:, None] + offsets[None], 0, padded.shape[0] - 1)
    c = np.clip(cols[:, None] + offsets[None], 0, padded.shape[1] - 1)
    return padded[r[:, :, None], c[:, None, :]].astype(np.float32)


def _orientation_histograms(channel: np.ndarray) -> np.ndarray:
    """``(n, F)`` block-normalised histograms of gradient orientation (unsigned, :data:`BINS` bins) weighted by
    gradient magnitude, over :data:`CELL_PX` cells, blocks of 2 x 2 cells: a HOG descriptor, vectorised."""
    n, h, w = channel.shape
    gx, gy = np.zeros_like(channel), np.zeros_like(channel)
    gx[:, :, 1:-1] = channel[:, :, 2:] - channel[:, :, :-2]
    gy[:, 1:-1] = channel[:, 2:] - channel[:, :-2]
    magnitude = np.hypot(gx, gy)
    bins = np.minimum((np.mod(np.arctan2(gy, gx), np.pi) * (BINS / np.pi)).astype(np.int64), BINS - 1)
    ch, cw = h // CELL_PX, w // CELL_PX
    cell = (np.arange(h)[:, None] // CELL_PX) * cw + np.arange(w)[None] // CELL_PX
    index = (np.arange(n)[:, None, None] * (ch * cw) + cell[None]) * BINS + bins
    histograms = np.bincount(index.ravel(), weights=magnitude.ravel(), minlength=n * ch * cw * BINS)
    cells = histograms.reshape(n, ch, cw, BINS)
    blocks = np.concatenate([cells[:, :-1, :-1], cells[:, 1:, :-1], cells[:, :-1, 1:], cells[:, 1:, 1:]], axis=3)
    blocks /= np.linalg.norm(blocks, axis=3, keepdims=True) + 1e-3
    return blocks.reshape(n, -1)


def window_features(crops: np.ndarray) -> np.ndarray:
    """``(n, F)`` features of windows ``(n, 48, 48, 3)``: orientation histograms of brightness and saturation."""
    crops = np.asarray(crops, dtype=np.float32)
    if crops.ndim != 4 or crops.shape[1:] != (2 * WINDOW_HALF_PX, 2 * WINDOW_HALF_PX, 3):
        raise InvalidInputError(f"windows must be (n, {2 * WINDOW_HALF_PX}, {2 * WINDOW_HALF_PX}, 3); "
                                f"got {crops.shape}")
    brightness = crops.mean(axis=3)
    saturation = crops.max(axis=3) - crops.min(axis=3)
    return np.concatenate([_orientation_histograms(brightness), _orientation_histograms(saturation)], axis=1)


class FingertipDetector:
    """The fingertip's offset (px) from a window's centre, regressed from :func:`window_features`.

    ``hidden``: the perceptron's hidden layer sizes (ReLU); ``alpha``: L2 penalty on the weights; ``epochs``,
    ``batch``, ``learning_rate``: Adam's; ``random_state``: the initial weights and the batches' order.
    """

    def __init__(self, hidden: tuple[int, ...] = (256, 128), alpha: float = 1e-3, epochs: int = 40,
                 batch: int = 256, learning_rate: float = 1e-3, random_state: int = 0) -> None:
        self.hidden, self.alpha, self.epochs = tuple(hidden), alpha, epochs
        self.batch, self.learning_rate, self.random_state = batch, learning_rate, random_state

    def _check_settings(self) -> None:
        if not (self.hidden and all(isinstance(h, int) and h > 0 for h in self.hidden) and self.alpha >= 0
                and isinstance(self.epochs, int) and self.epochs >= 1 and isinstance(self.batch, int)
                and self.batch >= 1 and self.learning_rate > 0):
            raise InvalidInputError(f"FingertipDetector takes hidden sizes > 0, alpha >= 0, epochs >= 1, batch >= 1 "
                                    f"and learning_rate > 0; got {self.hidden!r}, {self.alpha!r}, {self.epochs!r}, "
                                    f"{self.batch!r}, {self.learning_rate!r}")

    def fit(self, crops: np.ndarray, offsets: np.ndarray) -> FingertipDetector:
        """Learn from windows ``(n, 48, 48, 3)`` and their fingertips' offsets ``(n, 2)`` (px, column and row)."""
        self._check_settings()
        features = window_features(crops)
        offsets = np.asarray(offsets, dtype=np.float64)
        if offsets.shape != (len(features), 2) or not np.all(np.isfinite(offsets)) or len(features) < 2:
            raise InvalidInputError(f"fit takes n >= 2 windows and n finite offsets (n, 2); got {len(features)} "
                                    f"windows and offsets {offsets.shape}")
        self.feature_mean_ = features.mean(axis=0)
        self.feature_scale_ = features.std(axis=0) + 1e-6
        x = (features - self.feature_mean_) / self.feature_scale_
        self.offset_scale_ = float(np.sqrt(np.mean(offsets**2))) or 1.0
        y = offsets / self.offset_scale_
        rng = np.random.default_rng(self.random_state)
        sizes = (x.shape[1], *self.hidden, 2)
        self.weights_ = [rng.normal(0.0, np.sqrt(2.0 / a), (a, b)) for a, b in zip(sizes[:-1], sizes[1:])]
        self.biases_ = [np.zeros(b) for b in sizes[1:]]
        _adam(self, x, y, rng)
        return self

    def _check_is_fitted(self) -> None:
        if not hasattr(self, "weights_"):
            raise NotFittedError("this FingertipDetector is not fitted: call fit() or FingertipDetector.load()")

    def predict(self, crops: np.ndarray) -> np.ndarray:
        """The fingertips' offsets ``(n, 2)`` (px) from the centres of windows ``(n, 48, 48, 3)``."""
        self._check_is_fitted()
        x = (window_features(crops) - self.feature_mean_) / self.feature_scale_
        return _forward(self.weights_, self.biases_, x)[-1] * self.offset_scale_

    def locate(self, image: np.ndarray, guesses: np.ndarray) -> np.ndarray:
        """The fingertip's pixel ``(n, 2)`` in ``image`` (H, W, 3) uint8 near each of ``guesses`` (n, 2)."""
        guesses = np.asarray(guesses, dtype=float).reshape(-1, 2)
        return np.rint(guesses) + self.predict(windows(image, guesses))

    def save(self, path: str | os.PathLike, overwrite: bool = False) -> Path:
        """Write the fitted detector to ``path`` (.npz), claimed atomically; an existing one only with ``overwrite``."""
        self._check_is_fitted()
        arrays = {"format_version": np.array(FORMAT_VERSION), "hidden": np.array(self.hidden),
                  "feature_mean": self.feature_mean_, "feature_scale": self.feature_scale_,
                  "offset_scale": np.array(self.offset_scale_)}
        arrays.update({f"weights_{k}": w for k, w in enumerate(self.weights_)})
        arrays.update({f"biases_{k}": b for k, b in enumerate(self.biases_)})
        with claimed_file(path, overwrite, what="fingertip detector file") as partial:
            with open(partial, "wb") as handle:
                np.savez(handle, **arrays)
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike) -> FingertipDetector:
        """A detector written by :meth:`save`, checked."""
        try:
            with np.load(Path(path), allow_pickle=False) as data:
                arrays = {key: data[key] for key in data.files}
        except (OSError, ValueError) as error:
            raise DataFileError(f"{path}: not a fingertip detector file ({error})") from None
        try:
            if int(arrays["format_version"]) != FORMAT_VERSION:
                raise DataFileError(f"{path}: fingertip detector format {int(arrays['format_version'])}; this "
                                    f"version reads {FORMAT_VERSION}")
            hidden = tuple(int(h) for h in arrays["hidden"])
            detector = cls(hidden=hidden)
            layers = len(hidden) + 1
            detector.weights_ = [arrays[f"weights_{k}"].astype(float) for k in range(layers)]
            detector.biases_ = [arrays[f"biases_{k}"].astype(float) for k in range(layers)]
            detector.feature_mean_ = arrays["feature_mean"].astype(float)
            detector.feature_scale_ = arrays["feature_scale"].astype(float)
            detector.offset_scale_ = float(arrays["offset_scale"])
        except KeyError as missing:
            raise DataFileError(f"{path}: a fingertip detector file lacks {missing}") from None
        sizes = [w.shape for w in detector.weights_]
        chained = all(a[1] == b[0] for a, b in zip(sizes[:-1], sizes[1:]))
        if not (chained and sizes[0][0] == len(detector.feature_mean_) == len(detector.feature_scale_)
                and sizes[-1][1] == 2 and all(len(b) == w.shape[1] for w, b in zip(detector.weights_, detector.biases_))
                and all(np.all(np.isfinite(w)) for w in detector.weights_)):
            raise DataFileError(f"{path}: the fingertip detector's layers do not fit together or are not finite")
        return detector


def shipped_fingertip_detector() -> FingertipDetector:
    """The detector the package ships (``fingertip_detector.npz`` beside this module; how it was made:
    :mod:`hoap_actions.tracking.fingertip_training`)."""
    return FingertipDetector.load(Path(__file__).with_name("fingertip_detector.npz"))


def _forward(weights: list[np.ndarray], biases: list[np.ndarray], x: np.ndarray) -> list[np.ndarray]:
    """Every layer's output for inputs ``x``: ReLU hidden layers, a linear last one."""
    outputs = [x]
    for k, (w, b) in enumerate(zip(weights, biases)):
        z = outputs[-1] @ w + b
        outputs.append(z if k == len(weights) - 1 else np.maximum(z, 0.0))
    return outputs


def _adam(model: FingertipDetector, x: np.ndarray, y: np.ndarray, rng: np.random.Generator) -> None:
    """Mean squared error plus ``alpha`` times the weights' squares, minimised by Adam over shuffled batches."""
    params = model.weights_ + model.biases_
    first = [np.zeros_like(p) for p in params]
    second = [np.zeros_like(p) for p in params]
    beta1, beta2, step = 0.9, 0.999, 0
    layers = len(model.weights_)
    for _ in range(model.epochs):
        order = rng.permutation(len(x))
        for start in range(0, len(x), model.batch):
            rows = order[start:start + model.batch]
            outputs = _forward(model.weights_, model.biases_, x[rows])
            delta = 2.0 * (outputs[-1] - y[rows]) / len(rows)
            grads_w, grads_b = [None] * layers, [None] * layers
            for k in range(layers - 1, -1, -1):
                grads_w[k] = outputs[k].T @ delta + 2.0 * model.alpha * model.weights_[k] / len(x)
                grads_b[k] = delta.sum(axis=0)
                if k:
                    delta = (delta @ model.weights_[k].T) * (outputs[k] > 0)
            step += 1
            for p, g, m, v in zip(params, grads_w + grads_b, first, second):
                m *= beta1
                m += (1 - beta1) * g
                v *= beta2
                v += (1 - beta2) * g * g
                p -= model.learning_rate * (m / (1 - beta1**step)) / (np.sqrt(v / (1 - beta2**step)) + 1e-8)
