"""The demonstration as the robot took it, for the video of ``hoap-actions imitate``: every camera frame
with the arm the robot estimated (or read from markers) drawn on it, and what it took the action to be."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.demonstrations import Demonstration

__all__ = ["ARM_LINKS", "annotated_frames", "caption"]

ARM_LINKS = (("shoulder", "elbow"), ("elbow", "wrist"), ("wrist", "index_knuckle"), ("index_knuckle", "index_tip"),
             ("wrist", "thumb_tip"))
"""Marker pairs drawn as the arm's links."""
ARM_COLOUR = (255, 220, 0)  # rgb
MARKER_COLOUR = (255, 60, 60)
TEXT_COLOUR = (255, 255, 255)


def caption(image: np.ndarray, lines: Sequence[str]) -> np.ndarray:
    """``image`` (H, W, 3) uint8 with ``lines`` written at its top left on a dark band, legible at any size."""
    out = np.ascontiguousarray(image).copy()
    if not lines:
        return out
    scale = max(0.35, out.shape[0] / 600)
    height = int(22 * scale) + 4
    band = len(lines) * height + 6
    out[:band] = (out[:band] * 0.35).astype(np.uint8)
    for i, line in enumerate(lines):
        cv2.putText(out, line, (6, (i + 1) * height), cv2.FONT_HERSHEY_SIMPLEX, scale, TEXT_COLOUR,
                    max(1, round(scale * 1.5)), cv2.LINE_AA)
    return out


def annotated_frames(demonstration: Demonstration, markers: np.ndarray | None, marker_names: Sequence[str],
                     lines: Sequence[str]) -> list[np.ndarray]:
    """The demonstration's frames, each with ``markers`` (T, M, 3) m of that frame drawn over it (dots, and
    the :data:`ARM_LINKS` between them; None draws none) and the caption ``lines``."""
    frames = np.asarray(demonstration.frames)
    if markers is not None:
        markers = np.asarray(markers, dtype=float)
        if markers.ndim != 3 or markers.shape[0] != len(frames) or markers.shape[1:] != (len(marker_names), 3):
            raise InvalidInputError(f"markers must be (T, M, 3) with T = {len(frames)} frames and M = "
                                    f"{len(marker_names)} names; got {markers.shape}")
    index = {name: i for i, name in enumerate(marker_names)}
    links = [(index[a], index[b]) for a, b in ARM_LINKS if a in index and b in index]
    out = []
    for t, frame in enumerate(frames):
        image = np.ascontiguousarray(frame).copy()
        if markers is not None and np.isfinite(markers[t]).all():
            pixels = np.round(demonstration.camera.pixels(markers[t])).astype(np.int32)
            for a, b in links:
                cv2.line(image, tuple(map(int, pixels[a])), tuple(map(int, pixels[b])), ARM_COLOUR, 2, cv2.LINE_AA)
            for point in pixels:
                cv2.circle(image, tuple(map(int, point)), 3, MARKER_COLOUR, -1, cv2.LINE_AA)
        out.append(caption(image, lines))
    return out
