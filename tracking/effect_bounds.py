"""Where a particle's effect may lie: the box its class's training ends span, the hand's end held where the
model that poses the particle sees it, and where an approach ends from the block it reaches.

A hand mode's refit (:mod:`~hoap_actions.primitives.models.hand_modes`) learns its effect directions from that mode's
segments alone; an approach's segments in one mode end at nearly one height, so the refit's effect basis leaves the
end's height out and its pose does not move with it. A particle's end then drifts there unseen, and the approach's
goal read from it drifts too. :class:`EndHold` keeps the hand's end at the posing model's centre in the directions the
model ignores (:data:`IGNORED_END_WEIGHT`), leaving those it poses untouched: the pose moves by less than a tenth of
the end's move, and not at all along a direction the model leaves out.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION
from hoap_actions.primitives.models.class_models import ClassModel

__all__ = ["END_MARGIN_M", "IGNORED_END_WEIGHT", "EndHold", "end_boxes", "hand_offset_from_object"]

END_MARGIN_M = 0.05  # m, how far beyond its class's training ends an end may wander (the table's reach)
# an end direction counts as ignored by a model when a move along it changes the model's reduced effect by less than
# this share of the move (the end part of the model's orthonormal effect basis: 1 when the model varies the end there,
# 0 for a height a mode's approaches all reach; the removes' rest, not held, has 0.003-0.034)
IGNORED_END_WEIGHT = 0.1


def end_boxes(classes: Mapping[int, ClassModel], margin_m: float = END_MARGIN_M) -> dict[int, tuple]:
    """Per class, the (low, high) corners (3,) of its training ends widened by ``margin_m``."""
    boxes = {}
    for cid, model in classes.items():
        ends = (model.centre + np.einsum("np,kp->nk", model.phmm.train_phi_, model.basis))[:, 3:]
        boxes[cid] = (ends.min(axis=0) - margin_m, ends.max(axis=0) + margin_m)
    return boxes


def hand_offset_from_object(classes: Mapping[int, ClassModel]) -> np.ndarray:
    """Where an approach's end (the hand) lies from the object it reaches (3,), learned from the training
    effects: the approaches' mean end minus the manipulations' mean start (weighted by their counts) in
    x and y; the approaches' mean end height in z."""
    approach = [c.centre[3:] for c in classes.values() if c.kind == APPROACH]
    starts = [(len(c.phmm.train_phi_), c.centre[:3]) for c in classes.values() if c.kind == MANIPULATION]
    if not approach or not starts:
        return np.zeros(3)
    counts = np.array([n for n, _ in starts], float)
    object_start = np.sum(counts[:, None] * np.array([x for _, x in starts]), axis=0) / counts.sum()
    hand = np.mean(approach, axis=0)
    return np.array([*(hand[:2] - object_start[:2]), hand[2]])


def _ignored_directions(model: ClassModel) -> np.ndarray | None:
    """The projector (3, 3) onto the end directions ``model``'s pose ignores; None when it ignores none."""
    u, weights, _ = np.linalg.svd(model.basis[3:], full_matrices=True)
    posed = np.zeros(3, dtype=bool)
    posed[:weights.size] = weights >= IGNORED_END_WEIGHT
    if posed.all():
        return None
    ignored = u[:, ~posed]
    return ignored @ ignored.T


class EndHold:
    """The end of approach particles (the hand's goal) held at their posing model's centre along the directions that
    model ignores (see the module docstring); approaches whose models ignore none are left as they are. A remove's
    end (the hand at rest) and a manipulation's (the object's, which the next manipulation starts from) are not."""

    def __init__(self, classes: Mapping[int, ClassModel], by_mode: Mapping[tuple[int, int], ClassModel],
                 n_modes: int) -> None:
        self._held: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        for cid, pooled in classes.items():
            if pooled.kind != APPROACH:
                continue
            for mode in range(n_modes):
                model = by_mode.get((cid, mode), pooled)
                projector = _ignored_directions(model)
                if projector is not None:
                    self._held[(cid, mode)] = (model.centre[3:], projector)

    @property
    def held(self) -> list[tuple[int, int]]:
        """The (class id, mode) pairs whose ends are held."""
        return sorted(self._held)

    def hold(self, class_id: np.ndarray, mode: np.ndarray, end: np.ndarray) -> None:
        """Move ``end`` (n, 3), in place, onto each particle's posing model's centre along the ignored directions."""
        for (cid, m), (centre, projector) in self._held.items():
            chosen = np.flatnonzero((class_id == cid) & (mode == m))
            if chosen.size:
                end[chosen] -= (end[chosen] - centre) @ projector
