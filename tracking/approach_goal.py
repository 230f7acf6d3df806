"""An approach's goal read from the whole demonstration: where the hand went is told by what it did next.

Each task's approach ends at its own place by the block, within millimetres every time, and centimetres from the
other tasks' places; one camera often cannot tell two places apart along its ray while the hand is still reaching.
Once the manipulation that followed has been recognised (the block's seen motion shows it), the goal is the place
where the training approaches that led into that manipulation ended, at the block as seen, the one nearest the
filter's own estimate where the task has several (a push made from either side of the block).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = ["read_approach_end"]


def read_approach_end(estimate: np.ndarray, following_class: int | None, block: np.ndarray | None,
                      places: Mapping[int, np.ndarray]) -> np.ndarray:
    """The approach's end (3,) (m): of the training ends ``places[following_class]`` (``(k, 3)``: x and y from the
    block, height), placed at the seen ``block`` (3,), the one nearest the filter's ``estimate`` (3,); the estimate
    itself when no manipulation followed, the class has no places or the block was not seen."""
    estimate = np.asarray(estimate, dtype=float)
    ends = None if following_class is None else places.get(int(following_class))
    if ends is None or not len(ends) or block is None:
        return estimate
    candidates = np.column_stack([np.asarray(block, float)[:2] + ends[:, :2], ends[:, 2]])
    return candidates[np.argmin(np.linalg.norm(candidates - estimate, axis=1))]
