"""What an optical motion-capture system adds to the exact poses of a simulated demonstration.

A recording made in simulation knows every marker and the object exactly; a camera-based system does
not. :class:`MocapNoise` describes the errors it adds, and :func:`add_mocap_noise` draws them:

- **marker jitter**: white noise on every marker coordinate (``marker_sd_m``), as reconstruction from
  several cameras gives it (sub-millimetre to 1 mm for a calibrated VICON-class system);
- **skin markers**: a marker sits on the skin, not at the joint centre; each marker gets a fixed
  offset for the whole session (``skin_offset_sd_m`` per coordinate, scene frame), so every episode
  of a recording shares it, as a marker set glued on once would;
- **occlusion gaps**: a marker hidden from the cameras for a few frames is missing, stored as NaN
  (never as zeros); gaps start at ``gap_rate_hz`` per marker per second and last ``gap_frames``;
- **object pose noise**: the rigid body fitted to the object's markers is off by white noise in
  position (``object_sd_m``) and orientation (``object_sd_rad``, a rotation about a random axis).

Every draw comes from a generator seeded by the recording's seed and the episode's index, so the
same seed gives the same noisy recording, and it is independent of the demonstrator's own draws: a
noisy recording is its exact twin plus the noise. The model is stored with the data (the dataset's
``noise`` attribute), so exact and noisy recordings cannot be confused.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError

__all__ = ["NOISE_MODELS", "MocapNoise", "add_mocap_noise", "parse_noise"]

# The noise generators' seeds have four entries, (seed, index, _NOISE_STREAM, kind), so they never
# meet the demonstrator's (seed, index + 1) nor the preset's (seed, 0).
_NOISE_STREAM = 7
_SKIN, _EPISODE = 0, 1
MAX_NOISE_SD_M = 0.05  # beyond 5 cm a "marker" says nothing of the joint it is on: a typo, not a model


def _check_number(name: str, value: object, high: float) -> None:
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if not (ok and np.isfinite(value) and 0.0 <= value <= high):
        raise InvalidInputError(f"{name} must be a number in [0, {high:g}]; got {value!r}")


@dataclass(frozen=True)
class MocapNoise:
    """The errors a motion-capture system adds (module docstring); all zero: the exact poses."""

    marker_sd_m: float = 0.0
    skin_offset_sd_m: float = 0.0
    gap_rate_hz: float = 0.0
    gap_frames: tuple[int, int] = (3, 15)
    object_sd_m: float = 0.0
    object_sd_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("marker_sd_m", "skin_offset_sd_m", "object_sd_m"):
            _check_number(name, getattr(self, name), MAX_NOISE_SD_M)
        _check_number("object_sd_rad", self.object_sd_rad, math.radians(30.0))
        _check_number("gap_rate_hz", self.gap_rate_hz, 10.0)
        low, high = self.gap_frames if len(self.gap_frames) == 2 else (0, -1)
        if (not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in (low, high))
                or not 1 <= low <= high):
            raise InvalidInputError(f"gap_frames must be two ints 1 <= shortest <= longest; got {self.gap_frames!r}")
        object.__setattr__(self, "gap_frames", (int(low), int(high)))

    @property
    def exact(self) -> bool:
        """No error of any kind: the recording is the simulation's poses."""
        return not any((self.marker_sd_m, self.skin_offset_sd_m, self.gap_rate_hz, self.object_sd_m,
                        self.object_sd_rad))

    @property
    def has_gaps(self) -> bool:
        return self.gap_rate_hz > 0.0

    def to_dict(self) -> dict:
        return {**dataclasses.asdict(self), "gap_frames": list(self.gap_frames)}

    @classmethod
    def from_dict(cls, values: dict) -> MocapNoise:
        """The model :meth:`to_dict` wrote; an unknown or malformed entry raises InvalidInputError."""
        known = {f.name for f in dataclasses.fields(cls)}
        if not isinstance(values, dict) or not set(values) <= known:
            raise InvalidInputError(f"a noise model is a mapping with keys among {sorted(known)}; got {values!r}")
        values = dict(values)
        if "gap_frames" in values:
            values["gap_frames"] = tuple(values["gap_frames"])
        return cls(**values)


NOISE_MODELS: dict[str, MocapNoise] = {
    "none": MocapNoise(),
    # a calibrated optical system in a table-top volume: 0.7 mm jitter, markers 5 mm off the joint
    # centres, a short occlusion every 5 s per marker; the object's rigid body 0.7 mm and 0.7 deg
    "mocap": MocapNoise(marker_sd_m=0.0007, skin_offset_sd_m=0.005, gap_rate_hz=0.2, gap_frames=(3, 15),
                        object_sd_m=0.0007, object_sd_rad=math.radians(0.7)),
}
_SPEC_KEYS = {"marker": "marker_sd_m", "skin": "skin_offset_sd_m", "gaps": "gap_rate_hz",
              "object": "object_sd_m", "angle": "object_sd_rad"}
_SPEC_UNITS = {"marker": 1e-3, "skin": 1e-3, "gaps": 1.0, "object": 1e-3, "angle": math.pi / 180.0}


def parse_noise(spec: str) -> MocapNoise:
    """A noise model from a name of :data:`NOISE_MODELS` or magnitudes such as
    ``"marker=1,object=1,angle=1,gaps=0.2,skin=5"`` (mm, mm, deg, gaps per marker per second, mm;
    the keys left out are 0)."""
    if not isinstance(spec, str):
        raise InvalidInputError(f"a noise model is a name or key=value list (str); got {spec!r}")
    if spec in NOISE_MODELS:
        return NOISE_MODELS[spec]
    values = {}
    for item in spec.split(","):
        match = re.fullmatch(r"\s*(\w+)\s*=\s*([0-9.eE+-]+)\s*", item)
        if match is None or match.group(1) not in _SPEC_KEYS:
            raise InvalidInputError(
                f"unknown noise model {spec!r}; accepted: {', '.join(sorted(NOISE_MODELS))}, or key=value pairs "
                f"with keys {', '.join(_SPEC_KEYS)} (mm, mm, gaps/s, mm, deg), e.g. 'marker=1,object=1,angle=1'")
        try:
            value = float(match.group(2))
        except ValueError:
            raise InvalidInputError(f"noise {match.group(1)}={match.group(2)!r} is not a number") from None
        values[_SPEC_KEYS[match.group(1)]] = value * _SPEC_UNITS[match.group(1)]
    return MocapNoise(**values)


def add_mocap_noise(H: np.ndarray, O: np.ndarray, noise: MocapNoise, fps: float, seed: int, index: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Episode ``index`` of the recording with ``seed`` (frames at ``fps`` Hz) as the system would see
    it: markers ``H`` ``(T, M, 3)`` (m) with gaps as NaN, object poses ``O`` ``(T, 6)`` (m, rotation vector)."""
    H, O = np.array(H, dtype=float), np.array(O, dtype=float)
    if noise.exact:
        return H, O
    T, M, _ = H.shape
    skin = np.random.default_rng([seed, 0, _NOISE_STREAM, _SKIN]).normal(0.0, noise.skin_offset_sd_m, (M, 3))
    rng = np.random.default_rng([seed, index, _NOISE_STREAM, _EPISODE])
    H = H + skin + rng.normal(0.0, noise.marker_sd_m, H.shape)
    if noise.has_gaps:
        H[_gap_mask(rng, T, M, noise, fps)] = np.nan
    position = O[:, :3] + rng.normal(0.0, noise.object_sd_m, (T, 3))
    axis = rng.normal(size=(T, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    tilt = Rotation.from_rotvec(axis * rng.normal(0.0, noise.object_sd_rad, (T, 1)))
    rotation = (tilt * Rotation.from_rotvec(O[:, 3:])).as_rotvec()
    return H, np.hstack([position, rotation])


def _gap_mask(rng: np.random.Generator, T: int, M: int, noise: MocapNoise, fps: float) -> np.ndarray:
    """(T, M) True where a marker is hidden: gaps start as a Poisson process per marker."""
    mask = np.zeros((T, M), dtype=bool)
    starts = rng.random((T, M)) < noise.gap_rate_hz / fps
    lengths = rng.integers(noise.gap_frames[0], noise.gap_frames[1] + 1, size=(T, M))
    for t, m in zip(*np.nonzero(starts)):
        mask[t:t + lengths[t, m], m] = True
    return mask

