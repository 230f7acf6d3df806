"""What a demonstration did, read from its recorded markers and the block's path (the ``--from-markers``
oracle of vision): which action, and where the block started and ended.

Connected recognition (the action models' :meth:`decode`) cuts the markers into primitives; the frames
from its first to its last manipulation are the manipulation. The action is named from what the block
did over them: lifted, a move; turned, a rotate; slid, a push; left where it was (or no manipulation
recognised while the block stayed), an approach. The block's start and end are its poses at the
demonstration's first and last frames, where it rests.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.goals import block_turn
from hoap_actions.primitives.discovery.estimator import MANIPULATION
from hoap_actions.primitives.models.class_models import DecodedSegment

__all__ = ["LIFTED", "MOVED", "TURNED", "DemonstrationReading", "read_markers"]

LIFTED = 0.02  # m, a block raised this far over its start during the manipulation was carried (a move)
TURNED = np.radians(30.0)  # rad, a block turned this far between start and end was rotated
MOVED = 0.01  # m, a block displaced less than this and turned less than STILL_TURN was not manipulated
STILL_TURN = np.radians(10.0)  # rad


class DecodingModels(Protocol):
    """What the reading needs of :class:`~hoap_actions.primitives.models.action_models.ActionModels`."""

    classes_: dict

    def decode(self, H: np.ndarray) -> list[DecodedSegment]: ...


@dataclass(frozen=True)
class DemonstrationReading:
    """A demonstration read: the ``action`` (``"approach"``, ``"move"``, ``"push"`` or ``"rotate"``; ``None``
    when the markers could not be explained), the block's ``object_start`` and ``object_end`` (6,: centre m,
    rotation vector rad), the decoded ``class_ids`` in order and the ``manipulation``'s frames
    ``[start, end)`` (``None`` when none was recognised)."""

    action: str | None
    object_start: np.ndarray
    object_end: np.ndarray
    class_ids: tuple[int, ...]
    manipulation: tuple[int, int] | None


def _checked_path(O: np.ndarray, frames: int) -> np.ndarray:
    O = np.asarray(O, dtype=float)
    if O.shape != (frames, 6) or not np.all(np.isfinite(O)):
        raise InvalidInputError(f"the block's path must be ({frames}, 6) finite poses (centre m, rotation vector "
                                f"rad), one a marker frame; got shape {O.shape}")
    return O


def read_markers(models: DecodingModels, H: np.ndarray, O: np.ndarray) -> DemonstrationReading:
    """Read a demonstration from its markers ``H`` (T, M, 3) m and the block's path ``O`` (T, 6) (module
    docstring). ``models`` are fitted action models whose markers ``H`` has."""
    O = _checked_path(O, len(H))  # before decoding, the costly part
    segments = models.decode(H)
    start, end = O[0].copy(), O[-1].copy()
    class_ids = tuple(int(s.class_id) for s in segments)
    pieces = [s for s in segments if models.classes_[s.class_id].kind == MANIPULATION]
    turn = abs(block_turn(start, end))
    still = np.linalg.norm(end[:2] - start[:2]) < MOVED and turn < STILL_TURN
    if not pieces:
        action = "approach" if segments and still else None
        return DemonstrationReading(action, start, end, class_ids, None)
    manipulation = (int(pieces[0].start), int(pieces[-1].end))
    lift = float(np.max(O[manipulation[0]:manipulation[1], 2]) - start[2])
    if still and lift < LIFTED:
        action = "approach"
    elif lift >= LIFTED:
        action = "move"
    elif turn >= TURNED:
        action = "rotate"
    else:
        action = "push"
    return DemonstrationReading(action, start, end, class_ids, manipulation)
