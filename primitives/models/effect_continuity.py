"""Effect continuity between neighbouring manipulation pieces, as evidence for decoding a demonstration.

Where one piece of a manipulation ends, the next begins: the object's location at the cut is both the
final location of piece ``i`` and the initial location of piece ``i + 1``.  Each class's PHMM
estimates a segment's effect on its own, so a wrong pair of classes for two neighbouring segments
usually shows as a gap between the final location one estimates and the initial location the other
estimates.  :func:`effect_gap_scores` turns those gaps into pair scores for
:meth:`ActionGrammar.decode <hoap_actions.primitives.discovery.grammar.ActionGrammar.decode>`.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["effect_gap_scores"]


def effect_gap_scores(final: Mapping[Hashable, np.ndarray], initial: Mapping[Hashable, np.ndarray],
                      weight: float) -> dict[tuple[Hashable, Hashable], float]:
    """``-weight * |final[a] - initial[b]|^2`` (nats) for every class ``a`` with a final-location estimate
    for segment ``i`` and every class ``b`` with an initial-location estimate for segment ``i + 1``.

    ``weight`` is in nats per squared unit of location (e.g. 1e6 per m^2: a 1 cm gap costs 100 nats).
    Classes whose estimate is missing or not finite are left out (the decoder adds 0 for them).
    """
    if not (isinstance(weight, (int, float)) and np.isfinite(weight) and weight >= 0):
        raise InvalidInputError(f"weight must be a finite number >= 0 (nats per squared unit); got {weight!r}")
    a_keys, a_points = _finite_points(final, "final")
    b_keys, b_points = _finite_points(initial, "initial")
    if not a_keys or not b_keys:
        return {}
    if a_points.shape[1] != b_points.shape[1]:
        raise InvalidInputError(f"final locations have {a_points.shape[1]} coordinates but initial ones "
                                f"{b_points.shape[1]}; they must be the same kind of location")
    gap = a_points[:, None, :] - b_points[None, :, :]
    scores = -float(weight) * np.einsum("abi,abi->ab", gap, gap)
    return {(a, b): float(scores[i, j]) for i, a in enumerate(a_keys) for j, b in enumerate(b_keys)}


def _finite_points(points: Mapping[Hashable, np.ndarray], name: str) -> tuple[list[Hashable], np.ndarray]:
    """Keys and stacked (n, d) locations of the finite entries of ``points``."""
    if not isinstance(points, Mapping):
        raise InvalidInputError(f"{name} must map classes to locations; got {type(points).__name__}")
    keys, rows = [], []
    for key, value in points.items():
        row = np.asarray(value, dtype=float)
        if row.ndim != 1:
            raise InvalidInputError(f"{name}[{key!r}] must be a 1-D location; got shape {row.shape}")
        if np.all(np.isfinite(row)):
            keys.append(key)
            rows.append(row)
    if len({row.shape for row in rows}) > 1:
        raise InvalidInputError(f"{name} locations differ in length: {sorted({row.size for row in rows})}")
    return keys, np.array(rows)
