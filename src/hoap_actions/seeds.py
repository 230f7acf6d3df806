"""Seeds a user may pass: one check, used before any long job starts."""

from __future__ import annotations

import numpy as np

from hoap_actions.errors import InvalidInputError

MAX_SEED = 2**63 - 1
"""Largest seed: datasets store seeds as HDF5 int64 attributes, and Gymnasium's ``reset`` wants a non-negative int."""


def check_seed(seed: object, count: int = 1, what: str = "seed") -> int:
    """``seed`` as an int once ``seed .. seed + count - 1`` are all valid seeds (0 .. :data:`MAX_SEED`)."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InvalidInputError(f"{what} must be an integer in 0..{MAX_SEED}; got {seed!r}")
    seed = int(seed)
    if seed < 0 or seed + max(int(count), 1) - 1 > MAX_SEED:
        span = f"{what} {seed}" if count <= 1 else f"{what}s {seed}..{seed + count - 1}"
        raise InvalidInputError(f"{span} outside 0..{MAX_SEED}; seeds are non-negative 64-bit integers")
    return seed
