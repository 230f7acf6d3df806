"""The chains of manipulation classes the training demonstrations performed, with what each did to the object.

A demonstration's manipulation is cut by discovery into a chain of classes (a carry: lift, a short piece or two,
the carry proper), and which chain it was follows from where the object went: each direction and distance of a push
or a carry has its own chains, the object moved by their training displacements within millimetres. Read from a
fitted discovery (its segmentations and segments' effects), so any models that keep one have them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hoap_actions.primitives.discovery.estimator import MANIPULATION

__all__ = ["ManipulationChain", "manipulation_chains"]


@dataclass(frozen=True)
class ManipulationChain:
    """One chain of manipulation classes: ``classes`` in order, the object's mean ``displacement`` (3,) (m) from
    the first piece's start to the last one's end, each piece's mean ``durations`` (frames), and ``count``, the
    training demonstrations that performed it."""

    classes: tuple[int, ...]
    displacement: np.ndarray
    durations: np.ndarray
    count: int


def manipulation_chains(discovery) -> list[ManipulationChain]:
    """Every chain of manipulation classes in a fitted discovery's training demonstrations (one per demonstration's
    run of manipulations), most performed first."""
    kinds = {int(c.primitive_id): c.kind for c in discovery.classes_}
    effects = {(s.demo, s.start): (np.asarray(s.initial, float), np.asarray(s.final, float))
               for c in discovery.classes_ if c.kind == MANIPULATION for s in c.segments}
    seen: dict[tuple[int, ...], list[tuple[np.ndarray, np.ndarray]]] = {}
    for demo, pieces in enumerate(discovery.segmentations_):
        chain = [(int(pid), start, end) for pid, start, end in pieces if kinds[int(pid)] == MANIPULATION]
        if not chain:
            continue
        moved = effects[(demo, chain[-1][1])][1] - effects[(demo, chain[0][1])][0]
        seen.setdefault(tuple(pid for pid, _, _ in chain), []).append(
            (moved, np.array([end - start for _, start, end in chain], float)))
    chains = [ManipulationChain(classes, np.mean([m for m, _ in done], axis=0), np.mean([d for _, d in done], axis=0),
                                len(done)) for classes, done in seen.items()]
    return sorted(chains, key=lambda chain: -chain.count)
