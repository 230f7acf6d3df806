"""Fixed nonlinear features g(phi) of an effect, for parametric HMMs whose state means bend with phi.

A thin-plate spline basis: ``g_i(phi) = U(|q(phi) - c_i|)`` with ``U(r) = r^2 log r`` (the radial
function of the thin-plate spline, smooth and free of a length scale to tune), where ``q`` maps the
training effects' range onto the unit box so that every effect component weighs alike, and the
centres ``c_i`` are the distinct training effects (at most ``max_centres`` of them, spread out by
farthest-point sampling). A mean ``mean_bar + W phi + V g(phi)`` is then an affine function plus a
thin-plate spline in phi, so the affine part a linear PHMM learns is kept and only the bend is added.
"""

from __future__ import annotations

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["ThinPlateFeatures", "effect_groups", "unit_range"]

# Effects closer than this (in the unit box of the training range) are one location: repetitions of a
# demonstration at the same target differ by sensor-level amounts, not by a new place to bend through.
DISTINCT_TOLERANCE = 1e-3


def unit_range(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``low`` and ``span`` (p,) of effects ``phi`` (S, p): ``(phi - low) / span`` fills the unit box
    (a component that never varies keeps span 1)."""
    low, high = phi.min(axis=0), phi.max(axis=0)
    return low, np.where(high - low > 0, high - low, 1.0)


def effect_groups(phi: np.ndarray, tolerance: float = DISTINCT_TOLERANCE) -> np.ndarray:
    """A group id per row of ``phi`` (S, p), numbered in order of first appearance: a row within
    ``tolerance`` (in the unit box of the rows' range) of a group's first row joins that group."""
    phi = np.asarray(phi, dtype=float)
    low, span = unit_range(phi)
    unit = (phi - low) / span
    groups, firsts = np.empty(len(unit), dtype=int), []
    for i, row in enumerate(unit):
        near = np.flatnonzero(np.linalg.norm(unit[firsts] - row, axis=1) <= tolerance) if firsts else []
        if len(near):
            groups[i] = near[0]
        else:
            groups[i] = len(firsts)
            firsts.append(i)
    return groups


class ThinPlateFeatures:
    """``g(phi)``: thin-plate radial functions of the normalised effect around fixed centres.

    ``low`` and ``span`` (p,) map effects to the unit box (``q = (phi - low) / span``); ``centres``
    (m, p) are in that box. ``m = 0`` gives no features (the linear mean model).
    """

    def __init__(self, centres: np.ndarray, low: np.ndarray, span: np.ndarray) -> None:
        self.centres = np.asarray(centres, dtype=float)
        self.low = np.asarray(low, dtype=float)
        self.span = np.asarray(span, dtype=float)

    @classmethod
    def none(cls, p: int) -> ThinPlateFeatures:
        """No features: the linear mean model's ``g``."""
        return cls(np.zeros((0, p)), np.zeros(p), np.ones(p))

    @classmethod
    def from_effects(cls, phi: np.ndarray, max_centres: int) -> ThinPlateFeatures:
        """Centres at the distinct training effects ``phi`` (S, p), at most ``max_centres`` of them.

        When there are more, farthest-point sampling from the effect nearest the mean keeps a subset
        that covers the range evenly (deterministic: no seed needed).
        """
        phi = np.asarray(phi, dtype=float)
        low, span = unit_range(phi)
        _, firsts = np.unique(effect_groups(phi), return_index=True)
        unit = (phi[firsts] - low) / span
        if unit.shape[0] > max_centres:
            chosen = [int(np.argmin(np.linalg.norm(unit - unit.mean(axis=0), axis=1)))]
            gap = np.linalg.norm(unit - unit[chosen[0]], axis=1)
            while len(chosen) < max_centres:
                chosen.append(int(np.argmax(gap)))
                gap = np.minimum(gap, np.linalg.norm(unit - unit[chosen[-1]], axis=1))
            unit = unit[np.sort(chosen)]
        return cls(unit, low, span)

    @property
    def n_features(self) -> int:
        return int(self.centres.shape[0])

    def check(self, p: int) -> None:
        """Raise InvalidInputError unless these are features of a p-dimensional effect (shapes, finite, span > 0)."""
        if self.centres.ndim != 2 or self.centres.shape[1] != p or self.low.shape != (p,) or self.span.shape != (p,):
            raise InvalidInputError(f"thin-plate features need centres (m, {p}), low ({p},) and span ({p},); got "
                                    f"{self.centres.shape}, {self.low.shape}, {self.span.shape}")
        values = np.concatenate([self.centres.ravel(), self.low, self.span])
        if not np.all(np.isfinite(values)) or np.any(self.span <= 0):
            raise InvalidInputError("thin-plate features need finite centres and range, and a span > 0 in every "
                                    "component")

    def _offsets(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``q - c_i`` (S, m, p) and ``|q - c_i|`` (S, m)."""
        q = (np.atleast_2d(phi) - self.low) / self.span
        delta = q[:, None, :] - self.centres[None]
        return delta, np.linalg.norm(delta, axis=2)

    def transform(self, phi: np.ndarray) -> np.ndarray:
        """``g(phi)``: (S, m) from effects (S, p)."""
        _, r = self._offsets(phi)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(r > 0, r * r * np.log(r), 0.0)

    def jacobian(self, phi: np.ndarray) -> np.ndarray:
        """``dg/dphi``: (S, m, p); ``dU/dq = (2 log r + 1)(q - c)``, which tends to 0 at a centre."""
        delta, r = self._offsets(phi)
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = np.where(r > 0, 2.0 * np.log(r) + 1.0, 0.0)
        return slope[:, :, None] * delta / self.span
