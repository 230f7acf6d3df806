"""A demonstration's manipulation read again once it is over: the chain of classes the block's seen motion says.

Frame by frame the filter often takes a carry for another chain of the same direction (a lift shared by every
distance, then pieces that look alike), while where the block went, seen at rest before and after, tells the chain
within millimetres. The push-or-carry question the block's rest positions cannot answer (both move it the same) is
left to the frames' own reading: the chain is chosen among those of the action most of the manipulation's frames were
read as.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import MANIPULATION
from hoap_actions.primitives.models.manipulation_chains import ManipulationChain

__all__ = ["CHAIN_TOLERANCE_M", "read_manipulation_chain"]

CHAIN_TOLERANCE_M = 0.025  # m, half the 5 cm between the training distances of a push or carry


def read_manipulation_chain(classes: Sequence[int], blocks_seen: Sequence[np.ndarray | None],
                            chains: Sequence[ManipulationChain], action_of_class: Mapping[int, int],
                            kinds: Mapping[int, str], tolerance_m: float = CHAIN_TOLERANCE_M) -> np.ndarray:
    """``classes`` (T,), one per frame as recognised, with the manipulation's frames (the first to the last read as a
    manipulation) read again: the chain of the action most of them were read as whose training displacement lies
    within ``tolerance_m`` of the block's (``blocks_seen``: per frame, where it was last seen at rest, (3,) m or None;
    from the manipulation's first frame to the last frame), the one sharing most frames with the reading (then the
    most performed). From the manipulation's first frame the chain lasts its pieces' mean training durations (the
    frames read as manipulation beyond them go to what was read after it), each piece in turn. As recognised when no
    frame is a manipulation, the block was not seen before and after, or no chain fits."""
    out = np.array(classes, dtype=int)
    if out.ndim != 1 or len(blocks_seen) != len(out):
        raise InvalidInputError(f"give one class and one block sighting (or None) per frame; got classes of shape "
                                f"{out.shape} and {len(blocks_seen)} sightings")
    manipulating = np.flatnonzero([kinds.get(int(c)) == MANIPULATION for c in out])
    if not manipulating.size:
        return out
    start, stop = manipulating[0], manipulating[-1] + 1
    block_before, block_after = blocks_seen[start], blocks_seen[-1]
    if block_before is None or block_after is None:
        return out
    read = out[start:stop]
    votes = Counter(action_of_class[int(c)] for c in read if kinds.get(int(c)) == MANIPULATION)
    action = votes.most_common(1)[0][0]
    moved = (np.asarray(block_after, float) - np.asarray(block_before, float))[:2]  # across the table
    fitting = [chain for chain in chains if action_of_class.get(chain.classes[0]) == action
               and np.linalg.norm(chain.displacement[:2] - moved) < tolerance_m]
    if not fitting:
        return out
    chosen = max(fitting, key=lambda chain: (int(np.isin(read, chain.classes).sum()), chain.count))
    following = next((int(c) for c in out[stop:] if kinds.get(int(c)) != MANIPULATION), None)
    length = min(len(out) - start, int(round(chosen.durations.sum())))
    if start + length < stop and following is not None:  # read as manipulation for longer than the chain lasts
        out[start + length:stop] = following
    stop = start + length
    cuts = start + np.rint(np.cumsum(chosen.durations) / chosen.durations.sum() * length).astype(int)
    for cid, begin, end in zip(chosen.classes, np.r_[start, cuts[:-1]], cuts):
        out[begin:end] = cid
    return out
