"""Locate the pegs and the board's holes in world coordinates from one overhead rgb-d image.

Its one job: turn a rendered ``rgb`` (H, W, 3) uint8 image, its ``depth`` (H, W, metres along the
camera's view axis) and the :class:`~hoap_actions.envs.camera.Camera` that took it into peg and hole
positions (m) with a confidence, never guessing a position it did not see.

Method (OpenCV): every pixel is back-projected to a world point with its depth and the camera's
inverse projection (:func:`backproject`). Pegs are found by colour: saturated pixels whose hue lies
nearest a peg's known colour (``scene.PEG_COLOURS``), kept only where their world points lie on the
table at a peg's height; of each colour the largest such blob is the peg. Holes are the openings of
the board's top surface: pixels whose world height is the board's top (``scene.BOARD_SIZE[2]``),
joined into components; a gap that the top surface encloses and whose size is an opening's is a
hole. Holes hidden by the arm are inferred from the seen ones and the board's known hole row, and
flagged as inferred with a lower confidence.

What "the centre" means (and what the simulator's truth is compared with):

* a peg's centre is its centre of mass, the PyBullet base position of ``peg_<colour>``. A standing
  peg's x-y is the mean of its top-face points (the face at the highest measured height, which
  nothing hides but a hand), its z that height minus half the peg's length. A lying peg's x-y is
  its silhouette's centroid on the plane of its axis, its z its highest point minus its radius.
  A top face partly covered by a hand is fitted by a circle of the peg's radius through its
  uncovered rim.
* a hole's centre is its axis at the board's top surface (``Scene.hole_positions``): the centroid
  of its opening's pixels, each intersected with the plane of the measured top surface. That plane
  is parallel to the image of a downward camera, so the centroid is the opening's true centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from functools import lru_cache

import cv2
import numpy as np
from scipy.optimize import OptimizeResult, least_squares

from hoap_actions.envs import scene, world
from hoap_actions.envs.camera import PIXEL_SAMPLE_UV, Camera
from hoap_actions.errors import InvalidInputError

PEG_COLOURS_RGB: dict[str, np.ndarray] = {name: np.array(rgba[:3]) for name, rgba in scene.PEG_COLOURS.items()}
MIN_PEG_SATURATION = 0.45  # HSV saturation (0..1) of a peg pixel: the table (0.31), board and robot are duller
MAX_HUE_DISTANCE_DEG = 20.0  # a peg pixel's hue lies within this of its colour's hue (the colours are >= 100 deg apart)
HEIGHT_TOLERANCE = 0.0015  # m, how far a surface point may lie from the height it is expected at
PEG_HEIGHT_MARGIN = 0.004  # m, a peg's highest point lies between 2 r and L, give or take this
OCCLUDER_CLEARANCE = 0.003  # m, a neighbour this much higher than a peg's top face covers it
MIN_TOP_FACE_FRACTION = 0.25  # a peg whose visible top face is smaller than this part of a full face is not located
MIN_BOARD_FRACTION = 0.2  # of the board's top area that must be seen for holes to be looked for
MIN_BOARD_PIECE_AREA = 20e-6  # m^2, smaller patches at the board's height are peg sides or the robot's edges
BOARD_SEARCH_PX = 4  # pixels around the seen top surface whose non-top points must lie off the board
BOARD_FIT_SCALE = 0.001  # m, residual beyond which the board fit counts a point as an outlier (soft L1)
# Mean soft-L1 cost per seen point (m^2) below which a board fit explains them and the other orientation is
# not tried: as if one point in a hundred lay BOARD_FIT_SCALE off. Rendered boards' fits stay under 3 % of it
# (seeds 0-49, 12000-12049, arm in view or not); a board fitted across leaves hundreds of points that far off.
BOARD_EXPLAINED_COST = 0.01 * (math.sqrt(2.0) - 1.0) * BOARD_FIT_SCALE**2
MIN_SEEN_OPENING_FRACTION = 0.5  # a hole whose opening is less seen than this is flagged as inferred
# TinyRenderer draws a peg's top face this far above its true top (measured: 50.98 mm for pegs whose
# top is at 49.99 mm on seeds 0-49; the board's top is drawn where it is).
PEG_TOP_RENDER_OFFSET = 0.001  # m
FACE_TOLERANCE = 0.0005  # m, a top-face point's distance from the face's fitted plane (rendered faces are flat)
MIN_LEAN = math.radians(3.0)  # rad, a top face tilted less is taken as level (12 px faces give ~1 deg of noise)
TOP_FACE_REFITS = 2  # plane fits of a peg's top face: the second picks up a leaning face's lower side
TABLE_XY_MARGIN = 0.01  # m, points this far beyond the table's edges are not on the table
BLOB_MARGIN_PX = 2  # pixels around a colour blob's bounding box that its peg's fit reads


@dataclass(frozen=True)
class PegDetection:
    """A peg of ``colour`` (a key of ``scene.PEG_COLOURS``): centre of mass ``position_m`` (3,) (m),
    ``standing`` upright or lying, ``confidence`` in (0, 1] (the seen part of its top face or silhouette)."""

    colour: str
    position_m: np.ndarray
    standing: bool
    confidence: float


@dataclass(frozen=True)
class HoleDetection:
    """A hole: its axis at the board's top surface ``position_m`` (3,) (m), ``confidence`` in (0, 1];
    ``inferred`` when it was hidden and placed from the seen holes and the board's hole row."""

    position_m: np.ndarray
    confidence: float
    inferred: bool = False


@dataclass(frozen=True)
class Detections:
    """What one image shows: pegs in the asked colours' order, holes along the board's row, and what
    was asked for but not found (``missing_colours``; ``board_found`` False when no board was seen)."""

    pegs: tuple[PegDetection, ...]
    holes: tuple[HoleDetection, ...]
    missing_colours: tuple[str, ...] = ()
    board_found: bool = True
    notes: tuple[str, ...] = field(default=())

    @property
    def complete(self) -> bool:
        """Every asked peg and every hole of the board was located."""
        return not self.missing_colours and self.board_found and len(self.holes) == scene.N_HOLES

    def peg(self, colour: str) -> PegDetection | None:
        """The peg of ``colour``, or None when it was not found."""
        return next((p for p in self.pegs if p.colour == colour), None)


# ---------------------------------------------------------------------------------------- geometry
def backproject(camera: Camera, u: np.ndarray, v: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """World points (..., 3) (m) of pixel coordinates ``u`` (right), ``v`` (down), in the continuous
    convention of :meth:`Camera.project` (pixel ``j`` spans ``[j, j + 1)``), at ``depth`` (m along the
    view axis, as :meth:`Sim.render` gives it). Inverse of ``camera.project``."""
    u, v, depth = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (u, v, depth)))
    projection = camera.projection_matrix()
    ndc_x = 2.0 * u / camera.width - 1.0
    ndc_y = 1.0 - 2.0 * v / camera.height
    eye = np.stack([ndc_x * depth / projection[0, 0], ndc_y * depth / projection[1, 1], -depth], axis=-1)
    view = camera.view_matrix()
    return (eye - view[:3, 3]) @ view[:3, :3]  # rows of R are the camera axes: R^T (p - t)


def rays_to_plane(camera: Camera, u: np.ndarray, v: np.ndarray, height: float) -> np.ndarray:
    """World points (..., 3) where the rays through pixel coordinates ``u``, ``v`` meet the plane
    ``z = height`` (m); used for openings, which have no surface of their own to give a depth."""
    eye = np.asarray(camera.eye, dtype=float)
    direction = backproject(camera, u, v, np.ones_like(np.asarray(u, dtype=float))) - eye
    t = (height - eye[2]) / direction[..., 2]
    return eye + t[..., None] * direction


def _pixel_points(camera: Camera, depth: np.ndarray) -> np.ndarray:
    """World points (H, W, 3) of every pixel's sample point: linear in depth along each pixel's ray
    (one coordinate plane at a time: numpy broadcasts over a last axis of 3 slowly)."""
    rays, origin = _pixel_rays(_camera_key(camera))
    points = np.empty((*depth.shape, 3))
    for axis in range(3):
        np.multiply(depth, rays[axis], out=points[..., axis])
        points[..., axis] += origin[axis]
    return points


def _camera_key(camera: Camera) -> tuple:
    """The camera's fields in order, made hashable (eye, target and up may be lists): what its rays and
    checks are cached under."""
    return tuple(tuple(map(float, value)) if isinstance(value, (list, tuple, np.ndarray)) else value
                 for value in (getattr(camera, f.name) for f in fields(camera)))


@lru_cache(maxsize=4)  # each entry is one image's points in size; the robot has one overhead camera
def _pixel_rays(key: tuple) -> tuple[np.ndarray, np.ndarray]:
    """Per world axis and pixel the offset per metre of depth (3, H, W), and the constant term (3,),
    of :func:`backproject`: fixed for a fixed camera, so kept (read-only) rather than redone per image."""
    camera = Camera(*key)
    v, u = np.mgrid[0 : camera.height, 0 : camera.width]
    origin = backproject(camera, 0.0, 0.0, 0.0)
    rays = np.moveaxis(backproject(camera, u + PIXEL_SAMPLE_UV[0], v + PIXEL_SAMPLE_UV[1], 1.0) - origin, -1, 0)
    rays = np.ascontiguousarray(rays)
    rays.setflags(write=False)
    origin.setflags(write=False)
    return rays, origin


# -------------------------------------------------------------------------------------- validation
def _check_inputs(rgb: object, depth: object, camera: object) -> tuple[np.ndarray, np.ndarray]:
    if not isinstance(camera, Camera):
        raise InvalidInputError(f"camera must be a hoap_actions.envs.camera.Camera; got {type(camera).__name__}")
    shape = (camera.height, camera.width)
    if not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8 or rgb.shape != (*shape, 3):
        got = f"{rgb.dtype} {rgb.shape}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise InvalidInputError(f"rgb must be a uint8 array of shape {(*shape, 3)} (the camera's H, W, 3); got {got}")
    if not isinstance(depth, np.ndarray) or depth.dtype.kind != "f" or depth.shape != shape:
        got = f"{depth.dtype} {depth.shape}" if isinstance(depth, np.ndarray) else type(depth).__name__
        raise InvalidInputError(f"depth must be a float array of shape {shape} in metres; got {got}")
    if not np.all(np.isfinite(depth)) or depth.min() <= 0.0:
        raise InvalidInputError("depth must be finite and positive (metres along the view axis)")
    if not _sees_work_area(_camera_key(camera)):
        raise InvalidInputError(
            "the camera does not see the whole work area of the table (its corners at "
            f"{world.WORK_AREA_LOW} .. {world.WORK_AREA_HIGH} m); accepted: a camera looking down on it, "
            "such as the scene's 'overhead' camera"
        )
    return rgb, np.asarray(depth, dtype=float)


@lru_cache(maxsize=4)
def _sees_work_area(key: tuple) -> bool:
    """Whether the camera of ``key`` (:func:`_camera_key`) sees the table's whole work area in front of it."""
    camera = Camera(*key)
    corners = np.array([[x, y, 0.0] for x in (world.WORK_AREA_LOW[0], world.WORK_AREA_HIGH[0])
                        for y in (world.WORK_AREA_LOW[1], world.WORK_AREA_HIGH[1])])
    in_front = (np.c_[corners, np.ones(4)] @ camera.view_matrix().T)[:, 2] < -camera.near
    pixels = camera.project(corners)
    inside = (pixels >= 0).all(axis=1) & (pixels[:, 0] <= camera.width) & (pixels[:, 1] <= camera.height)
    return bool(np.all(in_front & inside))


def _on_table(points: np.ndarray) -> np.ndarray:
    x, y = points[..., 0], points[..., 1]
    x_low = world.TABLE_NEAR_EDGE_X - TABLE_XY_MARGIN
    x_high = world.TABLE_NEAR_EDGE_X + world.TABLE_SIZE[0] + TABLE_XY_MARGIN
    return (x >= x_low) & (x <= x_high) & (np.abs(y) <= world.TABLE_SIZE[1] / 2 + TABLE_XY_MARGIN)


def _components(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Labels (H, W) and per-label stats (as ``cv2.connectedComponentsWithStats``, 8-connected) of
    ``mask``'s components, found within its bounding box: OpenCV's statistics pass costs the whole
    image's size, the box is small. Row 0 of the stats, the background, covers only the box."""
    left, top, width, height = cv2.boundingRect(mask.astype(np.uint8))
    labels = np.zeros(mask.shape, np.int32)
    if width == 0:  # OpenCV rejects an empty image
        return labels, np.array([[0, 0, mask.shape[1], mask.shape[0], mask.size]], np.int32)
    box = (slice(top, top + height), slice(left, left + width))
    _, labels[box], stats, _ = cv2.connectedComponentsWithStats(mask[box].astype(np.uint8), connectivity=8)
    stats[1:, cv2.CC_STAT_LEFT] += left
    stats[1:, cv2.CC_STAT_TOP] += top
    return labels, stats


# -------------------------------------------------------------------------------------------- pegs
def _hue_distance_deg(hue: np.ndarray, reference_rgb: np.ndarray) -> np.ndarray:
    ref = cv2.cvtColor(np.uint8(np.round(reference_rgb * 255))[None, None], cv2.COLOR_RGB2HSV_FULL)[0, 0, 0]
    delta = np.abs(hue.astype(float) - float(ref)) * 360.0 / 256.0
    return np.minimum(delta, 360.0 - delta)


def _hue_labels() -> np.ndarray:
    """Per 8-bit hue the index of the peg colour it belongs to (nearest, within
    :data:`MAX_HUE_DISTANCE_DEG`), else 255: a lookup table, as hue takes only 256 values."""
    hues = np.arange(256, dtype=np.uint8)
    distances = np.stack([_hue_distance_deg(hues, rgb) for rgb in PEG_COLOURS_RGB.values()])
    nearest = np.argmin(distances, axis=0)
    close = distances[nearest, np.arange(256)] <= MAX_HUE_DISTANCE_DEG
    return np.where(close, nearest, 255).astype(np.uint8)


_HUE_LABELS = _hue_labels()


def _colour_masks(rgb: np.ndarray, colours: tuple[str, ...]) -> dict[str, np.ndarray]:
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL)
    saturated = (hsv[..., 1] >= MIN_PEG_SATURATION * 255) & (hsv[..., 2] >= 40)
    labels = cv2.LUT(hsv[..., 0], _HUE_LABELS)
    names = list(PEG_COLOURS_RGB)
    return {name: saturated & (labels == names.index(name)) for name in colours}


def _peg_height_points(points: np.ndarray, on_table: np.ndarray) -> np.ndarray:
    """Pixels whose points lie on the table no higher than a standing peg's top."""
    z = points[..., 2]
    return on_table & (z <= scene.PEG_LENGTH + PEG_HEIGHT_MARGIN) & (z >= -PEG_HEIGHT_MARGIN)


def _locate_peg(colour: str, plausible: np.ndarray, points: np.ndarray) -> PegDetection | None:
    """The peg in the largest blob of ``plausible`` (its colour's pixels at a peg's height) that looks
    like one, or None."""
    radius, length = scene.PEG_RADIUS, scene.PEG_LENGTH
    labels, stats = _components(plausible)
    best: PegDetection | None = None
    for label in np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1:
        window = _blob_window(stats[label], plausible.shape)
        blob, blob_points = labels[window] == label, points[window]
        top_z = float(np.max(blob_points[..., 2][blob]))
        if not 2 * radius - PEG_HEIGHT_MARGIN <= top_z <= length + PEG_HEIGHT_MARGIN:
            continue
        standing = top_z > (2 * radius + length) / 2
        best = (_standing_peg if standing else _lying_peg)(colour, blob, blob_points, top_z)
        if best is not None:
            break
    return best


def _blob_window(stat: np.ndarray, shape: tuple[int, int]) -> tuple[slice, slice]:
    """The image window of a blob's bounding box and ``BLOB_MARGIN_PX`` around it: what a peg's fit
    reads (its face's ring and rim lie within a pixel of it), so the fit need not touch the whole image."""
    left, top, width, height = (int(x) for x in stat[:4])
    return (slice(max(top - BLOB_MARGIN_PX, 0), min(top + height + BLOB_MARGIN_PX, shape[0])),
            slice(max(left - BLOB_MARGIN_PX, 0), min(left + width + BLOB_MARGIN_PX, shape[1])))


def _standing_peg(colour: str, blob: np.ndarray, points: np.ndarray, top_z: float) -> PegDetection | None:
    """A standing (or leaning) peg from its top face: the blob's points in the plane fitted to those
    near its highest point; the centre lies half a length below the face's centre along its normal."""
    radius, length = scene.PEG_RADIUS, scene.PEG_LENGTH
    top = blob & (np.abs(points[..., 2] - top_z) <= HEIGHT_TOLERANCE)
    for _ in range(TOP_FACE_REFITS):
        face = points[top]
        if len(face) < 3:  # no plane through fewer points (a sliver of a face peeping past a hand)
            return None
        middle = face.mean(axis=0)
        normal = np.linalg.svd(face - middle, full_matrices=False)[2][2]
        normal = normal if normal[2] > 0 else -normal
        if normal[2] > math.cos(MIN_LEAN):  # a face this level is noise in the fit: take it as level
            normal = np.array([0.0, 0.0, 1.0])
        top = blob & (np.abs((points - middle) @ normal) <= FACE_TOLERANCE)
    pixel_area = _pixel_area(points, top)
    fraction = min(1.0, top.sum() * pixel_area / (math.pi * radius**2))
    if fraction < MIN_TOP_FACE_FRACTION:
        return None
    middle = points[top].mean(axis=0)
    ring = cv2.dilate(top.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~top
    covered = ring & ((points - middle) @ normal > OCCLUDER_CLEARANCE)
    if covered.any():
        rim = top & cv2.dilate((ring & ~covered).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        rim = rim & ~cv2.dilate(covered.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        xy = _fit_circle(points[rim][:, :2], radius - math.sqrt(pixel_area) / 2, middle[:2])
        middle = np.array([*xy, middle[2]])
    centre = middle - (length / 2 + PEG_TOP_RENDER_OFFSET) * normal
    return PegDetection(colour, centre, True, float(fraction))


def _lying_peg(colour: str, blob: np.ndarray, points: np.ndarray, top_z: float) -> PegDetection:
    radius, length = scene.PEG_RADIUS, scene.PEG_LENGTH
    xy = points[blob][:, :2]
    fraction = min(1.0, len(xy) * _pixel_area(points, blob) / (2 * radius * length))
    return PegDetection(colour, np.array([*xy.mean(axis=0), top_z - radius]), False, float(fraction))


def _pixel_area(points: np.ndarray, where: np.ndarray) -> float:
    """Mean world area (m^2) a pixel covers around ``where`` (from its neighbours' points to the right and below)."""
    v, u = np.nonzero(where)
    v, u = np.minimum(v, points.shape[0] - 2), np.minimum(u, points.shape[1] - 2)
    here = points[v, u]
    dx = np.linalg.norm(points[v, u + 1] - here, axis=-1)
    dy = np.linalg.norm(points[v + 1, u] - here, axis=-1)
    return float(np.median(dx) * np.median(dy))


def _fit_circle(xy: np.ndarray, radius: float, start: np.ndarray) -> np.ndarray:
    """Centre of the circle of ``radius`` through points ``xy`` (N, 2), by Gauss-Newton from ``start``."""
    centre = np.asarray(start, dtype=float).copy()
    for _ in range(20):
        offset = xy - centre
        distance = np.maximum(np.linalg.norm(offset, axis=1), 1e-9)
        residual = distance - radius
        jacobian = -offset / distance[:, None]
        step, *_ = np.linalg.lstsq(jacobian, -residual, rcond=None)
        centre += step
        if np.linalg.norm(step) < 1e-7:
            break
    return centre


# ------------------------------------------------------------------------------------------- holes
def _opening_side() -> float:
    """Side (m) of an opening as seen: the chamfer's outer square less the part of the chamfer within
    :data:`HEIGHT_TOLERANCE` of the top, which counts as top surface."""
    return scene.HOLE_SIZE + 2 * scene.CHAMFER - 2 * HEIGHT_TOLERANCE


def _opening_area() -> float:
    return _opening_side() ** 2


def _locate_holes(
    camera: Camera, points: np.ndarray, on_table: np.ndarray
) -> tuple[tuple[HoleDetection, ...], bool, list[str]]:
    """The holes from the board's pose, fitted to its seen top surface and to what is seen around it."""
    board_top = scene.BOARD_SIZE[2]
    z = points[..., 2]
    top = (np.abs(z - board_top) <= HEIGHT_TOLERANCE) & on_table
    if not top.any():
        return (), False, ["no board top surface in view"]
    pixel_area = _pixel_area(points, top)
    board_area = scene.BOARD_SIZE[0] * scene.BOARD_SIZE[1] - scene.N_HOLES * _opening_area()
    labels, stats = _components(top)
    pieces = np.isin(labels, 1 + np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] * pixel_area >= MIN_BOARD_PIECE_AREA))
    if pieces.sum() * pixel_area < MIN_BOARD_FRACTION * board_area:
        return (), False, ["no board top surface in view"]
    surface_z = float(np.median(z[pieces]))
    near = cv2.dilate(pieces.astype(np.uint8), np.ones((3, 3), np.uint8), iterations=BOARD_SEARCH_PX) > 0
    covered = z > surface_z + OCCLUDER_CLEARANCE
    inside_xy = points[pieces][:, :2]
    v, u = np.nonzero(near & ~pieces & ~covered)
    outside_xy = rays_to_plane(camera, u + PIXEL_SAMPLE_UV[0], v + PIXEL_SAMPLE_UV[1], surface_z)[:, :2]
    centre, yaw = _fit_board(inside_xy, outside_xy)
    holes_xy = centre + scene.HOLE_LOCAL_XY @ _rotation(yaw).T
    holes = []
    notes: list[str] = []
    for xy, covered_fraction in zip(holes_xy, _covered_fractions(camera, covered, holes_xy, surface_z)):
        seen = 1.0 - covered_fraction
        inferred = seen < MIN_SEEN_OPENING_FRACTION
        holes.append(HoleDetection(np.array([*xy, surface_z]), float(seen), inferred=inferred))
        if inferred:
            notes.append(f"hole at {np.round(xy, 4)} m is mostly hidden: placed from the board's seen pose")
    holes.sort(key=lambda h: h.position_m[1])
    return tuple(holes), True, notes


class _BoardModel:
    """The board fit's residuals for one set of seen points: how far (m) seen top-surface points
    (``inside_xy``) lie off the board's top (beyond its rectangle or in an opening) and seen points
    that are not top surface (``outside_xy``) lie within it, for a board at ``pose`` = (x, y, yaw).
    The exact Jacobian comes with them, for the fit needs no finite differences (three more residual
    evaluations per step), and both are computed once per pose (the fit asks for them one after the other)."""

    def __init__(self, inside_xy: np.ndarray, outside_xy: np.ndarray) -> None:
        self.inside_xy, self.outside_xy = inside_xy, outside_xy
        self._pose: np.ndarray | None = None
        self._residuals = self._jacobian = np.empty(0)

    def residuals(self, pose: np.ndarray) -> np.ndarray:
        """Residuals (N,) (m): the inside points' first, as ``least_squares``' ``fun``."""
        self._evaluate(pose)
        return self._residuals

    def jacobian(self, pose: np.ndarray) -> np.ndarray:
        """Their derivatives (N, 3) w.r.t. (x, y, yaw), as ``least_squares``' ``jac``."""
        self._evaluate(pose)
        return self._jacobian

    def _evaluate(self, pose: np.ndarray) -> None:
        if self._pose is not None and np.array_equal(pose, self._pose):
            return
        c, s = math.cos(pose[2]), math.sin(pose[2])
        errors, rows = [], []
        for xy, error in ((self.inside_xy, _inside_error), (self.outside_xy, _outside_error)):
            dx, dy = xy[:, 0] - pose[0], xy[:, 1] - pose[1]
            px, py = dx * c + dy * s, dy * c - dx * s  # the points in the board's frame
            value, grad_x, grad_y = error(px, py)
            errors.append(value)
            rows.append(np.column_stack([s * grad_y - c * grad_x, -s * grad_x - c * grad_y, py * grad_x - px * grad_y]))
        self._pose = np.array(pose, dtype=float)
        self._residuals, self._jacobian = np.concatenate(errors), np.concatenate(rows)


def _inside_error(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far (m) top-surface points at board coordinates ``px``, ``py`` lie off the top (beyond the
    rectangle, or into the opening they are in up to its nearer side), and its gradient along ``px``, ``py``."""
    over_x = np.maximum(np.abs(px) - scene.BOARD_SIZE[0] / 2, 0.0)
    over_y = np.maximum(np.abs(py) - scene.BOARD_SIZE[1] / 2, 0.0)
    error = np.hypot(over_x, over_y)
    grad_x, grad_y = np.zeros_like(px), np.zeros_like(py)
    off = np.flatnonzero(error > 0.0)
    grad_x[off] = np.copysign(over_x[off] / error[off], px[off])
    grad_y[off] = np.copysign(over_y[off] / error[off], py[off])
    half_opening = _opening_side() / 2
    for hole_x, hole_y in scene.HOLE_LOCAL_XY:  # the openings lie within the top: at most one holds a point
        rel_x, rel_y = px - hole_x, py - hole_y
        in_x, in_y = half_opening - np.abs(rel_x), half_opening - np.abs(rel_y)
        hit = np.flatnonzero((in_x > 0.0) & (in_y > 0.0))
        along_x = in_x[hit] <= in_y[hit]
        error[hit] = np.minimum(in_x[hit], in_y[hit])
        grad_x[hit] = np.where(along_x, -np.sign(rel_x[hit]), 0.0)
        grad_y[hit] = np.where(along_x, 0.0, -np.sign(rel_y[hit]))
    return error, grad_x, grad_y


def _outside_error(px: np.ndarray, py: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far (m) points that are not top surface lie within the top (to the nearer of its edge and an
    opening), and its gradient along ``px``, ``py``."""
    in_x, in_y = scene.BOARD_SIZE[0] / 2 - np.abs(px), scene.BOARD_SIZE[1] / 2 - np.abs(py)
    error, grad_x, grad_y = np.zeros_like(px), np.zeros_like(px), np.zeros_like(py)
    on = np.flatnonzero((in_x > 0.0) & (in_y > 0.0))  # only these can lie within the top
    along_x = in_x[on] <= in_y[on]
    on_error = np.where(along_x, in_x[on], in_y[on])
    on_grad_x = np.where(along_x, -np.sign(px[on]), 0.0)
    on_grad_y = np.where(along_x, 0.0, -np.sign(py[on]))
    half_opening = _opening_side() / 2
    for hole_x, hole_y in scene.HOLE_LOCAL_XY:
        rel_x, rel_y = px[on] - hole_x, py[on] - hole_y
        off_x, off_y = np.maximum(np.abs(rel_x) - half_opening, 0.0), np.maximum(np.abs(rel_y) - half_opening, 0.0)
        to_opening = np.hypot(off_x, off_y)
        nearer = np.flatnonzero(to_opening < on_error)
        on_error[nearer] = to_opening[nearer]
        scale = np.divide(1.0, to_opening[nearer], out=np.zeros(nearer.size), where=to_opening[nearer] > 0.0)
        on_grad_x[nearer] = np.copysign(off_x[nearer] * scale, rel_x[nearer])
        on_grad_y[nearer] = np.copysign(off_y[nearer] * scale, rel_y[nearer])
    error[on], grad_x[on], grad_y[on] = on_error, on_grad_x, on_grad_y
    return error, grad_x, grad_y


def _fit_board(inside_xy: np.ndarray, outside_xy: np.ndarray) -> tuple[np.ndarray, float]:
    """Board centre (2,) and yaw (rad, within +-90 degrees) that best explain the seen points, fitted from
    their bounding rectangle's orientation and, unless that fit explains them, from the other one too."""
    (cx, cy), (w, h), angle = cv2.minAreaRect(inside_xy.astype(np.float32))
    yaw0 = math.radians(angle) + (0.0 if h >= w else math.pi / 2)  # the long side is the board's y axis
    yaw0 = (yaw0 + math.pi / 2) % math.pi - math.pi / 2
    model = _BoardModel(inside_xy, outside_xy)
    best = _fit_pose(model, np.array([cx, cy, yaw0]))
    if best.cost > (len(inside_xy) + len(outside_xy)) * BOARD_EXPLAINED_COST:
        turned = _fit_pose(model, np.array([cx, cy, yaw0 + math.pi / 2]))
        best = turned if turned.cost < best.cost else best
    x, y, yaw = best.x
    return np.array([x, y]), float((yaw + math.pi / 2) % math.pi - math.pi / 2)


def _fit_pose(model: _BoardModel, start: np.ndarray) -> OptimizeResult:
    """Robust (soft L1) least-squares board pose from ``start`` = (x, y, yaw)."""
    return least_squares(model.residuals, start, jac=model.jacobian, loss="soft_l1", f_scale=BOARD_FIT_SCALE,
                         x_scale=np.array([0.01, 0.01, 0.1]))


def _rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


def _covered_fractions(camera: Camera, covered: np.ndarray, holes_xy: np.ndarray, surface_z: float) -> list[float]:
    """Per opening centred at ``holes_xy`` (K, 2) the part of its image that something above the board covers."""
    half = _opening_side() / 2
    offsets = np.array([[dx, dy] for dx in (-half, half) for dy in (-half, half)])
    corners = (holes_xy[:, None, :] + offsets).reshape(-1, 2)
    pixels = camera.project(np.c_[corners, np.full(len(corners), surface_z)]).reshape(len(holes_xy), 4, 2)
    fractions = []
    for box in pixels:
        u0, v0 = np.clip(np.floor(box.min(axis=0)).astype(int), 0, None)
        u1, v1 = np.ceil(box.max(axis=0)).astype(int)
        window = covered[v0:v1, u0:u1]
        fractions.append(float(window.mean()) if window.size else 1.0)
    return fractions


# ------------------------------------------------------------------------------------------ facade
def locate(
    rgb: np.ndarray, depth: np.ndarray, camera: Camera, colours: tuple[str, ...] | None = None
) -> Detections:
    """Pegs of ``colours`` (default: every colour of ``scene.PEG_COLOURS``) and the board's holes seen
    in one image. Raises :class:`InvalidInputError` for an image that does not match ``camera`` or a
    camera that does not see the table's work area; what is not seen is flagged, never made up."""
    colours = tuple(scene.PEG_COLOURS) if colours is None else tuple(colours)
    unknown = [c for c in colours if c not in scene.PEG_COLOURS]
    if unknown:
        raise InvalidInputError(f"unknown peg colour(s) {unknown}; accepted: {list(scene.PEG_COLOURS)}")
    rgb, depth = _check_inputs(rgb, depth, camera)
    points = _pixel_points(camera, depth)
    on_table = _on_table(points)
    masks = _colour_masks(rgb, colours)
    peg_height = _peg_height_points(points, on_table)
    found = {colour: _locate_peg(colour, masks[colour] & peg_height, points) for colour in colours}
    holes, board_found, notes = _locate_holes(camera, points, on_table)
    return Detections(
        pegs=tuple(p for p in found.values() if p is not None),
        holes=holes,
        missing_colours=tuple(c for c, p in found.items() if p is None),
        board_found=board_found,
        notes=tuple(notes),
    )
