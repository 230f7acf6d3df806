"""Who demonstrates: body size and way of moving, by name or drawn from a seed.

Real demonstration data come from people of different sizes who move differently; a model learned
from one body and one style has seen none of that. A :class:`DemonstratorProfile` sets

- **body height**: trunk, upper arm and forearm scale with it (Winter's segment lengths are fractions
  of body height; ``human_arm.urdf`` is the 1.75 m reference). The hand keeps its size: it grips the
  same 5 cm block the same way, and an adult hand varies less than an arm;
- **speed**: every movement's duration is divided by it (on top of the per-episode +-15 %);
- **trunk use**: how readily the trunk leans and twists (the IK's trunk posture weight is divided by it);
- **elbow height**: added to the shoulder abduction of the working posture (rad): elbow out and up, or
  tucked in;
- **repetition spread of trunk and elbow** (``proximal_sd_rad``): per episode, the trunk's rest
  target and the elbow's working height move by this much (standard deviation, rad), so the shoulder
  and elbow vary from one repetition to the next at least as much as the hand, as people's do.

:data:`DEMONSTRATORS` names a few; ``"random"`` draws one from the recording's seed
(:func:`demonstrator_profile`). The ``reference`` profile is the demonstrator every earlier recording
was made with, draw for draw.
"""

from __future__ import annotations

import dataclasses
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.urdf import urdf_path

__all__ = ["DEMONSTRATORS", "REFERENCE_HEIGHT_M", "DemonstratorProfile", "demonstrator_profile", "human_urdf"]

REFERENCE_HEIGHT_M = 1.75  # the body of human_arm.urdf
HEIGHT_RANGE_M = (1.50, 2.00)  # the adult range a profile may take (the 1st to beyond the 99th percentile)
SCALED_LINKS = ("pelvis", "lumbar_link1", "lumbar_link2", "thorax", "r_shoulder_link1", "r_shoulder_link2",
                "r_upper_arm", "r_elbow_link", "r_forearm")
"""The links that scale with body height: everything from the pelvis to the wrist (not the hand)."""
_RANDOM_STREAM = 11  # the random profile's generator: (seed, 0, _RANDOM_STREAM), apart from the episodes'


@dataclass(frozen=True)
class DemonstratorProfile:
    """A demonstrator's body and way of moving (module docstring)."""

    name: str = "reference"
    height_m: float = REFERENCE_HEIGHT_M
    speed: float = 1.0
    trunk_use: float = 1.0
    elbow_lift_rad: float = 0.0
    proximal_sd_rad: float = 0.0

    def __post_init__(self) -> None:
        checks = {"height_m": HEIGHT_RANGE_M, "speed": (0.5, 2.0), "trunk_use": (0.1, 10.0),
                  "elbow_lift_rad": (-0.3, 0.4), "proximal_sd_rad": (0.0, 0.2)}
        for name, (low, high) in checks.items():
            value = getattr(self, name)
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
            if not (ok and np.isfinite(value) and low <= value <= high):
                raise InvalidInputError(f"demonstrator {name} must be a number in [{low}, {high}]; got {value!r}")

    @property
    def scale(self) -> float:
        """Length scale of the trunk and arm against the reference body."""
        return self.height_m / REFERENCE_HEIGHT_M

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)


DEMONSTRATORS: dict[str, DemonstratorProfile] = {
    "reference": DemonstratorProfile(),
    # a 1.60 m adult (about the 25th percentile of women) who leans in and keeps the elbow in
    "short": DemonstratorProfile("short", height_m=1.60, speed=0.9, trunk_use=2.0, elbow_lift_rad=-0.1,
                                 proximal_sd_rad=0.06),
    # a 1.88 m adult (about the 95th percentile of men), brisk, trunk still, elbow out
    "tall": DemonstratorProfile("tall", height_m=1.88, speed=1.2, trunk_use=0.6, elbow_lift_rad=0.2,
                                proximal_sd_rad=0.04),
    # the reference body moving differently: slower, with more trunk and a higher elbow
    "relaxed": DemonstratorProfile("relaxed", height_m=1.75, speed=0.8, trunk_use=3.0, elbow_lift_rad=0.15,
                                   proximal_sd_rad=0.08),
}


def demonstrator_profile(name: str | DemonstratorProfile, seed: int = 0) -> DemonstratorProfile:
    """A profile of :data:`DEMONSTRATORS`, or with ``"random"`` one drawn from ``seed``: height from a
    normal adult distribution (mean 1.71 m, sd 0.09 m, clipped to 1.55-1.90 m) and a way of moving
    drawn uniformly within the named profiles' span."""
    if isinstance(name, DemonstratorProfile):
        return name
    if name in DEMONSTRATORS:
        return DEMONSTRATORS[name]
    if name != "random":
        raise InvalidInputError(f"unknown demonstrator {name!r}; choose one of {sorted(DEMONSTRATORS)} or 'random'")
    rng = np.random.default_rng([seed, 0, _RANDOM_STREAM])
    return DemonstratorProfile(
        name=f"random-{seed}",
        height_m=round(float(np.clip(rng.normal(1.71, 0.09), 1.55, 1.90)), 3),
        speed=round(float(rng.uniform(0.8, 1.2)), 3),
        trunk_use=round(float(np.exp(rng.uniform(np.log(0.6), np.log(3.0)))), 3),
        elbow_lift_rad=round(float(rng.uniform(-0.1, 0.2)), 3),
        proximal_sd_rad=round(float(rng.uniform(0.04, 0.08)), 3),
    )


def human_urdf(height_m: float = REFERENCE_HEIGHT_M) -> Path:
    """The demonstrator's URDF for a body ``height_m`` tall: the packaged reference, or a copy with the
    trunk and arm scaled (lengths by ``height_m / REFERENCE_HEIGHT_M``, masses by its cube, inertias by
    its fifth power), written once to a cache folder and reused."""
    reference = urdf_path("human_arm.urdf")
    if height_m == REFERENCE_HEIGHT_M:
        return reference
    DemonstratorProfile(height_m=height_m)  # checks the height
    folder = Path(tempfile.gettempdir()) / "hoap_actions_urdf"
    folder.mkdir(exist_ok=True)
    path = folder / f"human_arm_{height_m * 1000:.0f}mm.urdf"
    if not path.exists():
        text = _scaled(reference, round(height_m * 1000) / 1000 / REFERENCE_HEIGHT_M)
        partial = path.with_name(f".{path.name}.{os.getpid()}")
        partial.write_text(text)
        os.replace(partial, path)  # whole or not at all, whoever writes it
    return path


def _scaled(reference: Path, s: float) -> str:
    tree = ET.parse(reference)
    root = tree.getroot()
    for link in root.iter("link"):
        if link.get("name") not in SCALED_LINKS:
            continue
        for origin in link.iter("origin"):
            _scale_attribute(origin, "xyz", s)
        for mass in link.iter("mass"):
            _scale_attribute(mass, "value", s**3)
        for inertia in link.iter("inertia"):
            for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                _scale_attribute(inertia, key, s**5)
        for shape, keys in (("box", ("size",)), ("cylinder", ("radius", "length")), ("sphere", ("radius",))):
            for element in link.iter(shape):
                for key in keys:
                    _scale_attribute(element, key, s)
    for joint in root.iter("joint"):
        if joint.find("parent").get("link") in SCALED_LINKS:
            _scale_attribute(joint.find("origin"), "xyz", s)
    return ET.tostring(root, encoding="unicode")


def _scale_attribute(element: ET.Element | None, key: str, factor: float) -> None:
    if element is None or element.get(key) is None:
        return
    element.set(key, " ".join(f"{float(v) * factor:.6g}" for v in element.get(key).split()))
