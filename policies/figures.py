"""The paper's Fig. 9 for one episode: the overhead image with what the robot located and the hand
paths it synthesised, drawn with OpenCV."""

from __future__ import annotations

from collections.abc import Mapping

import cv2
import numpy as np

from hoap_actions.envs import scene as scene_module
from hoap_actions.envs.camera import Camera
from hoap_actions.vision.perception import Detections, rays_to_plane

__all__ = ["PATH_COLOURS", "SCALE_BAR_M", "draw_episode", "scale_bar_ends"]

PATH_COLOURS = {"approach": (255, 200, 0), "move": (255, 0, 255), "remove": (0, 220, 255)}  # rgb
SCALE = 3  # the 320 x 240 overhead image is drawn on at 3x, so the lines and labels are legible
SCALE_BAR_M = 0.10  # the scale bar's length on the table top


def _pixels(camera: Camera, points: np.ndarray) -> np.ndarray:
    return np.round(SCALE * camera.project(points)).astype(np.int32)


def draw_episode(rgb: np.ndarray, camera: Camera, detections: Detections, paths: Mapping[str, np.ndarray],
                 executed: Mapping[str, np.ndarray] | None = None, target: tuple[str, int] | None = None) -> np.ndarray:
    """``rgb`` (H, W, 3) from ``camera`` enlarged 3x, with every located peg (a ring on its top face,
    labelled with its colour and confidence: the share of its top face seen) and hole (a square at its
    opening, thin if inferred), the synthesised hand ``paths`` (name -> (T, 3) m; thick) and the
    ``executed`` hand paths (thin white), ``target`` = (peg colour, hole index) marked, a legend of
    every mark and a scale bar of :data:`SCALE_BAR_M` on the table top."""
    image = cv2.resize(np.ascontiguousarray(rgb), None, fx=SCALE, fy=SCALE, interpolation=cv2.INTER_LINEAR)
    half = scene_module.HOLE_SIZE / 2
    for index, hole in enumerate(detections.holes):
        corners = hole.position_m + np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]])
        colour = (255, 255, 0) if target is not None and index == target[1] else (200, 200, 200)
        cv2.polylines(image, [_pixels(camera, corners)], True, colour, 1 if hole.inferred else 2, cv2.LINE_AA)
    for peg in detections.pegs:
        top = peg.position_m + [0.0, 0.0, scene_module.PEG_LENGTH / 2]
        centre = tuple(int(v) for v in _pixels(camera, top)[0])
        thick = 3 if target is not None and peg.colour == target[0] else 1
        cv2.circle(image, centre, 9 * SCALE // 2, (255, 255, 255), thick, cv2.LINE_AA)
        cv2.putText(image, f"{peg.colour} {peg.confidence:.2f}", (centre[0] + 16, centre[1] - 12),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    for name, path in paths.items():
        cv2.polylines(image, [_pixels(camera, path)], False, PATH_COLOURS.get(name, (255, 255, 255)), 3, cv2.LINE_AA)
    for path in (executed or {}).values():
        if len(path) > 1:
            cv2.polylines(image, [_pixels(camera, np.asarray(path))], False, (255, 255, 255), 1, cv2.LINE_AA)
    y = 24
    for name, colour in PATH_COLOURS.items():
        if name in paths:
            cv2.putText(image, f"{name} (synthesised)", (12, y), cv2.FONT_HERSHEY_SIMPLEX, 0.6, colour, 2, cv2.LINE_AA)
            y += 24
    if executed:
        cv2.putText(image, "executed hand path", (12, y), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1,
                    cv2.LINE_AA)
        y += 24
    for text in ("ring: peg located (colour, share of its top seen)",
                 "square: hole located (yellow: target, thin: inferred)"):
        cv2.putText(image, text, (12, y), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
        y += 20
    _draw_scale_bar(image, camera)
    return image


def scale_bar_ends(camera: Camera) -> np.ndarray:
    """Pixels (2, 2) of the enlarged image between which :data:`SCALE_BAR_M` of the table top lies, along
    the image's rows, near its lower left corner."""
    u0, v0 = 0.04 * camera.width, 0.95 * camera.height
    start, towards = rays_to_plane(camera, np.array([u0, u0 + 10.0]), np.array([v0, v0]), 0.0)
    along = (towards - start) / np.linalg.norm(towards - start)
    return _pixels(camera, np.stack([start, start + SCALE_BAR_M * along]))


def _draw_scale_bar(image: np.ndarray, camera: Camera) -> None:
    a, b = (tuple(int(c) for c in end) for end in scale_bar_ends(camera))
    cv2.line(image, a, b, (0, 0, 0), 7, cv2.LINE_AA)
    cv2.line(image, a, b, (255, 255, 255), 3, cv2.LINE_AA)
    cv2.putText(image, f"{100 * SCALE_BAR_M:.0f} cm", (a[0], a[1] - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                (255, 255, 255), 2, cv2.LINE_AA)
