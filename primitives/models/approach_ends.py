"""Where a demonstrator's hand ends an approach, relative to the object it reaches for.

An approach's goal is the object, but the hand does not end on its centre: it ends behind the block for a
push away from the body, beside it for a push to the side, over it for a carry, each a few millimetres
from the same place every time the task is the same, and centimetres from the other tasks' places. The
tracker draws approach goals around the block it sees from these training ends (their empirical
distribution), so that the arm's contour chooses among the tasks' places instead of searching a blob of
centimetres round their mean.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION

__all__ = ["approach_ends_by_following_class", "fit_approach_ends"]


def fit_approach_ends(discovery, hands: Sequence[np.ndarray], objects: Sequence[np.ndarray]) -> np.ndarray | None:
    """The end of every training approach segment of a fitted ``discovery``, ``(n, 3)``: the hand marker's
    x and y less the object's at the segment's last frame, and the hand's height (m); None when discovery
    found no approach. ``hands`` ``(T, 3 M)`` and ``objects`` ``(T, 6)`` per demonstration, in discovery's
    order."""
    if len(hands) != len(objects):
        raise InvalidInputError(f"give one object path per demonstration: {len(hands)} hands, {len(objects)} objects")
    hand = int(discovery.hand_marker)
    ends = []
    for c in discovery.classes_:
        if c.kind != APPROACH:
            continue
        for s in c.segments:
            point = np.asarray(hands[s.demo], float)[s.end - 1].reshape(-1, 3)[hand]
            held = np.asarray(objects[s.demo], float)[s.end - 1, :3]
            ends.append([point[0] - held[0], point[1] - held[1], point[2]])
    if not ends:
        return None
    ends = np.array(ends)
    if not np.all(np.isfinite(ends)):
        raise InvalidInputError("the hand and object at the approaches' ends must be finite; bridge marker gaps first")
    return ends


def approach_ends_by_following_class(discovery, ends: np.ndarray) -> dict[int, np.ndarray]:
    """The training approach ends ``ends`` (``(n, 3)``, as :func:`fit_approach_ends` gives them for ``discovery``)
    grouped by the manipulation classes its demonstration performed after each approach, up to the next approach:
    ``{class id: (k, 3)}`` (an approach's end under each of them). Each task's approach ends at its own place, so
    a manipulation seen after an approach tells which place its hand reached."""
    ends = np.asarray(ends, dtype=float)
    approaches = [s for c in discovery.classes_ if c.kind == APPROACH for s in c.segments]
    if ends.ndim != 2 or ends.shape != (len(approaches), 3):
        raise InvalidInputError(f"ends must be ({len(approaches)}, 3), one per approach of the discovery; "
                                f"got {ends.shape}")
    kinds = {int(c.primitive_id): c.kind for c in discovery.classes_}
    groups: dict[int, list[int]] = {}
    for k, s in enumerate(approaches):
        performed = set()
        for pid, start, _ in discovery.segmentations_[s.demo]:
            if start < s.end:
                continue
            if kinds[int(pid)] == APPROACH:
                break
            if kinds[int(pid)] == MANIPULATION:
                performed.add(int(pid))
        for pid in performed:
            groups.setdefault(pid, []).append(k)
    return {pid: ends[rows] for pid, rows in sorted(groups.items())}
