"""Minimum-jerk motion (Flash and Hogan): the bell-shaped timing of human reaches, along straight lines
and cubic Bezier curves."""

from __future__ import annotations

import numpy as np


def minimum_jerk(tau: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress ``10 t^3 - 15 t^4 + 6 t^5`` of normalised time ``tau`` (clipped to [0, 1])."""
    t = np.clip(np.asarray(tau, float), 0.0, 1.0)
    return t**3 * (10.0 - 15.0 * t + 6.0 * t**2)


def minimum_jerk_curve(control: np.ndarray, n: int) -> np.ndarray:
    """``n`` points (n, 3) along the cubic Bezier curve with ``control`` points (4, 3), at times
    ``k / n`` (k = 1..n) of a minimum-jerk motion: arc length, not the Bezier parameter, follows the
    minimum-jerk profile, so the speed is bell-shaped whatever the control points."""
    control = np.asarray(control, float)
    s = np.linspace(0.0, 1.0, 513)[:, None]
    weights = np.hstack([(1 - s) ** 3, 3 * (1 - s) ** 2 * s, 3 * (1 - s) * s**2, s**3])
    dense = weights @ control
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    if arc[-1] < 1e-9:
        return np.repeat(control[-1:], n, axis=0)
    wanted = arc[-1] * minimum_jerk(np.arange(1, n + 1) / n)
    return np.column_stack([np.interp(wanted, arc, dense[:, i]) for i in range(3)])


def bezier_length(control: np.ndarray) -> float:
    """Arc length (m) of the cubic Bezier curve with ``control`` points (4, 3)."""
    return float(np.linalg.norm(np.diff(minimum_jerk_curve(control, 64), axis=0), axis=1).sum())
