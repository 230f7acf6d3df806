"""The models directory of :class:`~hoap_actions.primitives.models.action_models.ActionModels`: its files
and the checks every entry of its manifest gets on load (each error names the file and the entry).

Layout (``format_version`` 3; version 1 directories, which have no action level, and version 2
ones, which have no grasp offset, still load): ``manifest.json`` (``kind`` "ActionModels", ``format_version``,
``params`` the hyper-parameters, ``fps``, ``marker_names``, ``covars_prior`` (D,) or null, and
``classes``: per class its ``id``, ``kind``, ``file``, ``effect_centre`` (6,), ``effect_basis``
(6, r) and ``exit_probability``; and ``actions``, the whole actions of
:mod:`~hoap_actions.primitives.models.whole_actions`, the same with ``lift_m``; optionally ``demonstrators``, the
profiles of who demonstrated, absent from models learned before it was kept; ``grasp_offset``
(3,) m or null, the object's centre in the hand's frame, :mod:`~hoap_actions.primitives.models.object_estimate`),
``discovery.json`` (the fitted
:class:`~hoap_actions.primitives.discovery.estimator.PrimitiveDiscovery`, which also cuts new object
trajectories), ``grammar.json`` (the :class:`~hoap_actions.primitives.discovery.grammar.ActionGrammar`) and
one ``class_<id>.npz`` (a :class:`~hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM`) per class
and one ``action_<id>.npz`` per action.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hoap_actions.errors import DataFileError
from hoap_actions.primitives.json_files import read_json_model

__all__ = ["FORMAT_VERSION", "KIND", "MANIFEST", "MODELS_FILES", "check_manifest", "finite_array", "names",
           "positive", "read_manifest"]

FORMAT_VERSION = 3
KIND = "ActionModels"
MANIFEST = "manifest.json"
MODELS_FILES = (MANIFEST, "discovery.json", "grammar.json")
"""The files of a models directory besides one ``class_<id>.npz`` per class."""


def read_manifest(path: Path) -> dict:
    """The manifest as a JSON object (its kind and version are checked by the estimator base)."""
    if not path.is_file():
        raise DataFileError(f"{path} is missing: a models directory holds {', '.join(MODELS_FILES)} and class_<id>.npz")
    return read_json_model(path, f"{KIND} manifest")


def check_manifest(path: Path, document: dict) -> None:
    """Every entry the manifest must hold is there, of the right kind."""
    for key in ("params", "fps", "marker_names", "covars_prior", "classes"):
        if key not in document:
            raise DataFileError(f"{path}: entry {key} is missing")
    if not isinstance(document["params"], dict) or not isinstance(document["classes"], list) or not document["classes"]:
        raise DataFileError(f"{path}: params must be an object and classes a non-empty list")


def positive(path: Path, name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise DataFileError(f"{path}: entry {name} must be a positive number; got {value!r}")
    return float(value)


def names(path: Path, name: str, value: object) -> list[str]:
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise DataFileError(f"{path}: entry {name} must be a non-empty list of names; got {value!r}")
    return value


def finite_array(path: Path, name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise DataFileError(f"{path}: entry {name} is not numeric") from None
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise DataFileError(f"{path}: entry {name} must be {shape} finite numbers; got shape {array.shape}")
    return array
