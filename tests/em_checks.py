"""A check shared by the EM tests of the parametric HMMs (linear and bending)."""

from __future__ import annotations

import numpy as np


def assert_objective_rises(history: np.ndarray) -> None:
    """EM's objective per iteration: enough iterations to tell, never falling (beyond round-off), and rising."""
    assert history.size >= 4
    assert np.all(np.diff(history) >= -1e-9 * np.abs(history[1:]))
    assert history[-1] > history[0]
