"""Cleaning motion-capture data before discovery and learning read it, as its noise requires.

A recording declares its measurement noise (``Demonstrations.noise``, :mod:`hoap_actions.demonstration.mocap`),
but real motion-capture files do not: the noise is also measured, as the object's jitter above the
filter's cut-off (median over episodes, position and rotation at the rim, :data:`ROTATION_RADIUS_M`). A
recording that declares none and shows none passes unchanged; one that declares noise or shows more
than :data:`NOISE_FLOOR_M` is cleaned the way motion-capture data usually are:

- **occlusion gaps**: each missing run of a marker is bridged linearly between the frames before and
  after it (held at the nearest seen value at an episode's start or end);
- **jitter**: a zero-lag low-pass filter, a 2nd-order Butterworth run forwards and backwards with a
  6 Hz cut-off (:data:`LOWPASS_HZ`), the usual choice for human movement, on markers and object poses.

Why the filter: the discovery reads the object's pose to tell rest from motion and cut the motion
every few centimetres, and white noise of a millimetre or a degree makes it lose action groups
(``docs/experiments/discovery.md``).

Rotation vectors are filtered component by component: the table-top turns here stay far from the
angle pi where rotation vectors jump.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings

import numpy as np
from scipy.signal import butter, filtfilt

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.errors import InvalidInputError

logger = logging.getLogger(__name__)

__all__ = ["LOWPASS_HZ", "NoiseAboveDeclaredWarning", "clean_demonstrations", "fill_gaps", "lowpass",
           "measured_jitter"]

LOWPASS_HZ = 6.0  # Hz, cut-off of the zero-lag filter (module docstring)
FILTER_ORDER = 2
# The object's measured jitter (what the filter removes) may exceed its declared position noise by this
# factor, plus the movement's own fast part (NOISE_FLOOR_M), before a warning says the declaration is wrong.
NOISE_FACTOR = 3.0
NOISE_FLOOR_M = 0.0005  # exact simulated recordings jitter 0.06 mm (median), 0.27 mm at most; 1 mm of noise 0.9 mm
ROTATION_RADIUS_M = 0.05  # a rotation's jitter counts as the path of a point this far out (discovery's default)


class NoiseAboveDeclaredWarning(UserWarning):
    """A recording is noisier than the noise model it declares: the cleaning may not be enough."""


def fill_gaps(H: np.ndarray) -> np.ndarray:
    """``H`` ``(T, M, 3)`` with every NaN run of a marker bridged linearly (held at the episode's ends).

    A marker never seen in the episode cannot be bridged and raises InvalidInputError.
    """
    H = np.array(H, dtype=float)
    seen = np.isfinite(H).all(axis=2)
    frames = np.arange(len(H))
    for m in np.flatnonzero(~seen.all(axis=0)):
        known = seen[:, m]
        if not known.any():
            raise InvalidInputError(f"marker {m} is missing in every frame of a movement: its gaps cannot be bridged")
        for axis in range(3):
            H[~known, m, axis] = np.interp(frames[~known], frames[known], H[known, m, axis])
    return H


def lowpass(X: np.ndarray, fps: float, cutoff_hz: float = LOWPASS_HZ) -> np.ndarray:
    """The zero-lag low-pass of ``X`` along its first axis (frames at ``fps`` Hz); sequences too short
    to filter (fewer than 2 frames) are returned as they are."""
    if not 0.0 < cutoff_hz < fps / 2.0:
        raise InvalidInputError(f"cutoff_hz must be in (0, {fps / 2:g}) Hz (below the Nyquist frequency); got "
                                f"{cutoff_hz!r}")
    X = np.asarray(X, dtype=float)
    if len(X) < 2:
        return X.copy()
    b, a = butter(FILTER_ORDER, cutoff_hz / (fps / 2.0))
    return filtfilt(b, a, X, axis=0, padlen=min(len(X) - 1, 3 * max(len(a), len(b))))


def measured_jitter(demos: Demonstrations) -> float:
    """The object's jitter (m): the median over episodes of the RMS of its pose above :data:`LOWPASS_HZ`,
    position and rotation (rad times :data:`ROTATION_RADIUS_M`) alike."""
    jitter = []
    for episode in demos.episodes:
        residual = episode.O - lowpass(episode.O, demos.fps)
        residual[:, 3:] *= ROTATION_RADIUS_M
        jitter.append(float(np.sqrt(np.mean(residual[:, :3] ** 2) + np.mean(residual[:, 3:] ** 2))))
    return float(np.median(jitter))


def clean_demonstrations(demos: Demonstrations) -> Demonstrations:
    """``demos`` as discovery and learning should read them (module docstring): unchanged when they
    declare and show no noise; otherwise gaps bridged and poses low-passed. Warns
    (:class:`NoiseAboveDeclaredWarning`, naming the episode and the figure) when the object jitters far
    more than the recording declares."""
    if demos.exact:
        measured = measured_jitter(demos)
        if measured <= NOISE_FLOOR_M:
            return demos
        warnings.warn(f"the recording declares no noise, but its object jitters by {measured * 1000:.2f} mm (median "
                      f"RMS above {LOWPASS_HZ:g} Hz, over {NOISE_FLOOR_M * 1000:g} mm): cleaned as a noisy one",
                      NoiseAboveDeclaredWarning, stacklevel=2)
    declared = float(demos.noise.get("object_sd_m", 0.0))
    episodes = []
    for index, episode in enumerate(demos.episodes):
        O = lowpass(episode.O, demos.fps)
        jitter = float(np.sqrt(np.mean((episode.O[:, :3] - O[:, :3]) ** 2)))
        if jitter > NOISE_FACTOR * declared + NOISE_FLOOR_M:
            warnings.warn(f"episode {index}: the object jitters by {jitter * 1000:.2f} mm (RMS above {LOWPASS_HZ:g} "
                          "Hz), "
                          f"far above the recording's declared {declared * 1000:.2f} mm: the recording is noisier than "
                          "its noise model says", NoiseAboveDeclaredWarning, stacklevel=2)
        H = lowpass(fill_gaps(episode.H).reshape(episode.T, -1), demos.fps).reshape(episode.H.shape)
        episodes.append(dataclasses.replace(episode, H=H, O=O))
    logger.info("cleaned %d noisy episodes: gaps bridged, %g Hz low-pass", len(episodes), LOWPASS_HZ)
    return dataclasses.replace(demos, episodes=tuple(episodes))
