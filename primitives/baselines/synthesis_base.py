"""What the synthesis baselines (ProMP, DMP, GMR) share: the input checks, the length of a synthesised
movement and the hand's end point as a function of the effect.

Each baseline follows the parametric HMM's synthesis interface so that the Fig. 8 protocol
(:func:`~hoap_actions.primitives.evaluation.grid_synthesis.synthesis_map`) and the hyper-parameter rule
(:func:`~hoap_actions.primitives.hmm.selection.select_mean_model` with ``estimator=``) take any of them:
``fit(X, lengths, phi) -> self`` on concatenated ``(N, D)`` movements with one effect per movement,
``synthesize(phi) -> (T, D)``. They are benchmark-only: they have no file format (no ``save``/``load``).

The effect phi of an approach is the object's (x, y), the place the hand reaches. ProMP and DMP are
told where the movement ends: the hand markers' final (x, y) (:data:`HAND_XY`) as an affine function
of phi fitted to the training movements' last frames (:class:`EndPointMap`); the slope is close to
the identity and the offset is where each marker sits relative to the object when the hand is on it.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Sequence
from types import ModuleType
from typing import Any, ClassVar

import numpy as np

from hoap_actions.demonstration.datasets import N_MARKERS
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.hmm.hmm_math import validate_sequences
from hoap_actions.primitives.hmm.phmm_batch import check_train_phi

__all__ = ["HAND_XY", "EndPointMap", "SynthesisBaseline", "import_optional"]

# Columns of the (T, 18) marker frames (shoulder, elbow, wrist, index tip, index knuckle, thumb tip; xyz
# each): the x and y of the four hand markers, which end on the object (spread about 2 mm around it).
HAND_XY = (6, 7, 9, 10, 12, 13, 15, 16)
MIN_FRAMES = 3  # the DMP's velocities and accelerations need a few frames per movement


def import_optional(module: str, method: str) -> ModuleType:
    """``module``, or an error saying that the ``method`` baseline needs the ``bench`` extra."""
    try:
        return importlib.import_module(module)
    except ImportError:
        package = module.split(".")[0]
        raise InvalidInputError(f'the {method} baseline needs {package}: pip install "hoap-actions[bench]"') from None


def check_positive_int(name: str, value: Any, low: int = 1) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise InvalidInputError(f"{name} must be an int >= {low}; got {value!r}")


def check_positive_real(name: str, value: Any, allow_zero: bool = False) -> None:
    ok = (not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))
          and np.isfinite(value) and (value >= 0 if allow_zero else value > 0))
    if not ok:
        raise InvalidInputError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0; got {value!r}")


class EndPointMap:
    """The training movements' final values of ``columns`` as an affine function of the effect:
    ``end(phi) = [1, phi] @ coef_``, least squares over the movements; ``variance_`` is the residual
    variance per column (how tightly the demonstrator ends on the fitted point)."""

    def __init__(self, columns: Sequence[int]) -> None:
        self.columns = np.asarray(columns, dtype=np.intp)

    def fit(self, ends: np.ndarray, phi: np.ndarray) -> EndPointMap:
        """``ends`` ``(S, D)``: the last frame of each movement; ``phi`` ``(S, p)``: their effects."""
        design = np.hstack([np.ones((len(phi), 1)), phi])
        targets = ends[:, self.columns]
        self.coef_ = np.linalg.lstsq(design, targets, rcond=None)[0]
        dof = max(len(phi) - design.shape[1], 1)
        self.variance_ = np.sum((design @ self.coef_ - targets) ** 2, axis=0) / dof
        return self

    def __call__(self, phi: np.ndarray) -> np.ndarray:
        return np.concatenate([[1.0], phi]) @ self.coef_


class SynthesisBaseline:
    """Shared checks and fitted attributes: ``n_features_in_`` (D), ``phi_dim_`` (p), ``train_phi_`` (S, p),
    ``n_frames_`` (frames of a synthesised movement: the training movements' mean length)."""

    _learned: ClassVar[tuple[str, ...]] = ("n_features_in_", "phi_dim_", "train_phi_", "n_frames_")

    def get_params(self) -> dict[str, Any]:
        """Hyper-parameters as given to ``__init__``: ``type(self)(**get_params())`` is an unfitted copy."""
        names = [n for n in inspect.signature(type(self).__init__).parameters if n != "self"]
        return {name: getattr(self, name) for name in names}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.get_params().items())})"

    def _check_params(self) -> None:
        """Raise InvalidInputError naming a hyper-parameter out of range (each baseline adds its own)."""

    def _check_via_columns(self, via_columns: Sequence[int]) -> None:
        try:
            columns = np.asarray(via_columns)
        except (TypeError, ValueError):
            columns = np.array([None])
        if columns.ndim != 1 or columns.size == 0 or not np.issubdtype(columns.dtype, np.integer) or np.any(
                columns < 0) or np.unique(columns).size != columns.size:
            raise InvalidInputError(f"via_columns must be distinct column indices >= 0 (default HAND_XY, the hand "
                                    f"markers' x and y); got {via_columns!r}")

    def _check_training(self, X, lengths, phi) -> tuple[list[np.ndarray], np.ndarray]:
        """The movements (each ``(T_i, D)``) and effects ``(S, p)``, checked; sets the shared attributes."""
        self._check_params()
        if phi is None:
            raise InvalidInputError(f"{type(self).__name__}.fit needs the effects phi (n_sequences, p) of the "
                                    "training movements: fit(X, lengths, phi)")
        X, lengths = validate_sequences(X, lengths)
        phi = check_train_phi(phi, lengths.size)
        if lengths.min() < MIN_FRAMES:
            raise InvalidInputError(f"every movement needs >= {MIN_FRAMES} frames; movement "
                                    f"#{int(np.argmin(lengths))} has {int(lengths.min())}")
        columns = getattr(self, "via_columns", None)
        if columns is not None and max(columns) >= X.shape[1]:
            raise InvalidInputError(f"via_columns {tuple(columns)} name columns beyond the {X.shape[1]} of X; for "
                                    f"marker frames ({3 * N_MARKERS} columns) the default HAND_XY fits")
        self.n_features_in_ = X.shape[1]
        self.phi_dim_ = phi.shape[1]
        self.train_phi_ = phi
        self.n_frames_ = int(round(lengths.mean()))
        return np.split(X, np.cumsum(lengths)[:-1]), phi

    def _check_phi(self, phi) -> np.ndarray:
        """A fitted model's query effect as a finite ``(p,)`` array."""
        check_is_fitted(self)
        try:
            arr = np.asarray(phi, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"phi must be a numeric array of shape ({self.phi_dim_},); got {phi!r}") from exc
        if arr.shape != (self.phi_dim_,) or not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"phi must be {self.phi_dim_} finite numbers (this model's effect dimension); "
                                    f"got {np.asarray(phi).shape} {arr}")
        return arr
