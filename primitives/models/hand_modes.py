"""How the demonstrator holds the hand through a demonstration, as a few modes, and the classes posed per mode.

A person pushes a block forward with the palm towards the body on the left of the shoulder and with the palm
forward on its right, and pushes sideways or carries with the fingers forward: discrete ways of holding the hand
that the effect (where the block or hand starts and ends) does not encode, so one class's mean averages postures
that differ by 10 cm at the elbow. The modes are the clusters (k-means) of the hand's pointing (the unit vectors
from the wrist to the index knuckle and to the thumb tip) at each training demonstration's first manipulation
frame; a class is refitted on each mode's segments where it has enough of them. The tracker's particles each
hold a mode for the whole demonstration (:class:`~hoap_actions.tracking.ActionTracker`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.cluster.vq import kmeans2

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import MANIPULATION
from hoap_actions.primitives.discovery.primitive_classes import PrimitiveClass
from hoap_actions.primitives.hmm.posture import hand_inputs
from hoap_actions.primitives.models.class_models import ClassModel

__all__ = ["HAND_MODES", "MIN_MODE_SEGMENTS", "HandModes", "fit_hand_modes"]

HAND_MODES = 4  # side pushes and carries (two thumb postures), front pushes with the fingers left or right
MIN_MODE_SEGMENTS = 6  # a class is refitted for a mode with at least this many of its segments in it


@dataclass(frozen=True, eq=False)
class HandModes:
    """The modes' ``centres`` ``(K, 6)`` (the hand's pointing: the unit vectors from the wrist to the index knuckle
    and to the thumb tip, :func:`~hoap_actions.primitives.hmm.posture.hand_inputs`' last six columns), their
    ``prior`` ``(K,)`` (the share of training demonstrations in each) and the ``classes`` refitted per mode,
    ``{(class id, mode): ClassModel}`` (a class missing for a mode is posed by its model over every mode)."""

    centres: np.ndarray
    prior: np.ndarray
    classes: Mapping[tuple[int, int], ClassModel]

    def __post_init__(self) -> None:
        k = len(self.prior)
        if np.shape(self.centres) != (k, 6) or k < 1:
            raise InvalidInputError(f"hand modes need centres (K, 6) and a prior (K,), K >= 1; got "
                                    f"{np.shape(self.centres)} and {np.shape(self.prior)}")
        if not (np.all(np.isfinite(self.prior)) and np.all(self.prior >= 0) and np.isclose(np.sum(self.prior), 1.0)):
            raise InvalidInputError(f"the hand modes' prior must be shares summing to 1; got {self.prior!r}")
        wrong = sorted(mode for _, mode in self.classes if not 0 <= mode < k)
        if wrong:
            raise InvalidInputError(f"hand-mode classes name modes {wrong} outside 0..{k - 1}")

    @property
    def n_modes(self) -> int:
        return len(self.prior)


def fit_hand_modes(classes: Sequence[PrimitiveClass], segmentations: Sequence[Sequence[tuple]],
                   hands: Sequence[np.ndarray], fit_class: Callable[[PrimitiveClass], ClassModel],
                   n_modes: int = HAND_MODES, min_segments: int = MIN_MODE_SEGMENTS) -> HandModes | None:
    """The hand modes of training demonstrations ``hands`` (each ``(T, 18)``) segmented by discovery
    (``classes`` and ``segmentations``, as :class:`PrimitiveDiscovery` fits them), each class refitted per mode
    by ``fit_class`` (given the class with that mode's segments alone); None when fewer than ``n_modes``
    demonstrations hold a manipulation. k-means from a fixed seed: the same demonstrations, the same modes."""
    kinds = {int(c.primitive_id): c.kind for c in classes}
    first = {d: next((start for pid, start, *_ in seg if kinds.get(int(pid)) == MANIPULATION), None)
             for d, seg in enumerate(segmentations)}
    demos = [d for d, frame in first.items() if frame is not None]
    if len(demos) < n_modes:
        return None
    pointing = hand_inputs(np.array([hands[d][first[d]] for d in demos]))[:, 3:]  # the wrist's position left out
    centres, labels = kmeans2(pointing, n_modes, minit="++", seed=np.random.default_rng(0))
    mode_of = dict(zip(demos, labels.tolist()))
    refitted = {}
    for c in classes:
        for mode in range(n_modes):
            segments = tuple(s for s in c.segments if mode_of.get(s.demo) == mode)
            if min_segments <= len(segments) < len(c.segments):
                refitted[(int(c.primitive_id), mode)] = fit_class(dataclasses.replace(c, segments=segments))
    prior = np.bincount(labels, minlength=n_modes) / len(labels)
    return HandModes(np.asarray(centres, float), prior, refitted)
