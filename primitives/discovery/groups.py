"""Views of a fitted discovery shared by its evaluation, files and plots: names, action groups, frame labels.

**Action groups.** The paper's classes are per primitive (one equivalence class of H segments per
primitive); a push over the longest distance is the chain P1 P2 P3 and a shorter one P1 P2 or P1
(Fig. 7). To count *actions* without ground truth, manipulation primitives that follow one another
in some demonstration are put in one group (connected components of the chains); approach and
remove are a group each. A group is what one box of Fig. 7 shows.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.discovery.estimator import MANIPULATION, PrimitiveDiscovery

__all__ = ["action_groups", "frame_labels", "group_members", "primitive_names"]


def frame_labels(model: PrimitiveDiscovery) -> list[np.ndarray]:
    """Per training demonstration, the primitive id of every frame ``(T_i,)`` ints, from ``segmentations_``."""
    check_is_fitted(model)
    return [
        np.concatenate([np.full(end - start, pid, dtype=int) for pid, start, end in segments])
        for segments in model.segmentations_
    ]


def action_groups(model: PrimitiveDiscovery) -> list[int]:
    """Per primitive id, its action group (module docstring), numbered by first primitive."""
    check_is_fitted(model)
    parent = list(range(len(model.primitives_)))

    def root(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for segments in model.segmentations_:
        chain = [pid for pid, *_ in segments if model.primitive_kinds_[pid] == MANIPULATION]
        for a, b in zip(chain, chain[1:]):
            parent[max(root(a), root(b))] = min(root(a), root(b))
    numbers: dict[int, int] = {}
    return [numbers.setdefault(root(pid), len(numbers)) for pid in range(len(model.primitives_))]


def group_members(groups: Sequence[int]) -> list[list[int]]:
    """Primitive ids of each group, by group id, from :func:`action_groups`' list."""
    members: list[list[int]] = [[] for _ in range(max(groups) + 1)]
    for pid, g in enumerate(groups):
        members[g].append(pid)
    return members


def primitive_names(model: PrimitiveDiscovery) -> list[str]:
    """Readable primitive names: ``approach``, ``remove`` and ``p<id>`` for manipulation primitives."""
    check_is_fitted(model)
    return [kind if kind != MANIPULATION else f"p{pid}" for pid, kind in enumerate(model.primitive_kinds_)]
