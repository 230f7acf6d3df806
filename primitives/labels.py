"""Per-frame label arrays as runs: the one place that cuts a labelling into its segments."""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np
from numpy.typing import ArrayLike

from hoap_actions.errors import InvalidInputError

__all__ = ["runs"]


def runs(labels: ArrayLike) -> list[tuple[Hashable, int, int]]:
    """Runs of equal values in a 1-D label array: ``(value, start, end)``, ``end`` exclusive, in order.

    Values come back as Python scalars (an int for an int array, so a class id is an ``int``); the
    runs tile the array, and an empty array has none.
    """
    labels = np.asarray(labels)
    if labels.ndim != 1:
        raise InvalidInputError(f"labels must be a 1-D array, got shape {labels.shape}")
    if len(labels) == 0:
        return []
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    ends = np.r_[starts[1:], len(labels)]
    return [(labels[a].item(), int(a), int(b)) for a, b in zip(starts, ends)]
