"""The models directory of :class:`~hoap_actions.primitives.models.action_models.ActionModels`: its files
and the checks every entry of its manifest gets on load (each error names the file and the entry).

Layout (``format_version`` 6; version 1 directories, which have no action level, version 2
ones, which have no grasp offset, version 3 ones, which have no pose classes, version 4 ones, which have
no approach ends, and version 5 ones, which have no hand modes, still load):
``manifest.json`` (``kind`` "ActionModels", ``format_version``,
``params`` the hyper-parameters, ``fps``, ``marker_names``, ``covars_prior`` (D,) or null, and
``classes``: per class its ``id``, ``kind``, ``file``, ``effect_centre`` (6,), ``effect_basis``
(6, r) and ``exit_probability``; and ``actions``, the whole actions of
:mod:`~hoap_actions.primitives.models.whole_actions`, the same with ``lift_m``; optionally ``demonstrators``, the
profiles of who demonstrated, absent from models learned before it was kept; ``grasp_offset``
(3,) m or null, the object's centre in the hand's frame, :mod:`~hoap_actions.primitives.models.object_estimate`;
``approach_ends`` (n, 3) m or null, :mod:`~hoap_actions.primitives.models.approach_ends`; ``hand_modes``
null or the ways of holding the hand, :mod:`~hoap_actions.primitives.models.hand_modes`: ``centres`` (K, 6),
``prior`` (K,) and ``classes``, the pose classes refitted per mode, each with its ``mode`` and file
``mode_<id>_<mode>.npz``),
``discovery.json`` (the fitted
:class:`~hoap_actions.primitives.discovery.estimator.PrimitiveDiscovery`, which also cuts new object
trajectories), ``grammar.json`` (the :class:`~hoap_actions.primitives.discovery.grammar.ActionGrammar`) and
one ``class_<id>.npz`` (a :class:`~hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM`) per class
and one ``action_<id>.npz`` per action.
"""

from __future__ import annotations

import json
import os
import re
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.errors import DataFileError, InvalidInputError, MissingModelPartWarning
from hoap_actions.inputs import checked_folder_member
from hoap_actions.primitives.base import file_params
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.json_files import read_json_model
from hoap_actions.primitives.models.class_models import EFFECT_DIM, ClassModel
from hoap_actions.primitives.models.hand_modes import HandModes

__all__ = ["FORMAT_VERSION", "KIND", "MANIFEST", "MODELS_FILES", "check_manifest", "finite_array", "foreign_entries",
           "models_from_directory", "names", "positive", "profiles_entry", "read_manifest", "read_models_directory",
           "unique_profiles", "write_models_directory"]

FORMAT_VERSION = 6
KIND = "ActionModels"
MANIFEST = "manifest.json"
MODELS_FILES = (MANIFEST, "discovery.json", "grammar.json")
"""The files of a models directory besides one ``class_<id>.npz`` per class."""


def foreign_entries(folder: Path) -> list[str]:
    """The entries of ``folder`` that a models directory does not hold (besides ``PROVENANCE.json``,
    which the shipped models carry), or every entry when it has no manifest of action models."""
    entries = sorted(os.listdir(folder))
    try:  # read as every model file is: a manifest linked to a device is refused, not read without end
        kind = read_json_model(folder / MANIFEST, f"{KIND} manifest").get("kind")
    except DataFileError:
        kind = None
    if kind != KIND:
        return entries
    ours = re.compile(r"^((class|action|pose)_\d+|mode_\d+_\d+)\.npz$")
    return [name for name in entries
            if not (name in (*MODELS_FILES, "PROVENANCE.json") or ours.match(name)) or not (folder / name).is_file()]


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


def write_models_directory(models: Any, folder: Path) -> None:
    """Write fitted action models' files into ``folder``, an empty directory the caller has claimed."""
    manifest = {
        "format_version": FORMAT_VERSION,
        "kind": KIND,
        "params": file_params(models),
        "fps": models.fps_,
        "marker_names": list(models.marker_names_),
        "covars_prior": None if models.covars_prior_ is None else models.covars_prior_.tolist(),
        **({"demonstrators": list(models.demonstrators_)} if models.demonstrators_ else {}),
        "grasp_offset": None if models.grasp_offset_ is None else models.grasp_offset_.tolist(),
        "approach_ends": None if models.approach_ends_ is None else models.approach_ends_.tolist(),
        "classes": [
            {"id": cid, "kind": m.kind, "file": f"class_{cid}.npz", "effect_centre": m.centre.tolist(),
             "effect_basis": m.basis.tolist(), "exit_probability": m.exit_probability,
             "action": models.action_of_class_.get(cid)}
            for cid, m in models.classes_.items()
        ],
        "actions": [
            {"id": aid, "kind": m.kind, "file": f"action_{aid}.npz", "effect_centre": m.centre.tolist(),
             "effect_basis": m.basis.tolist(), "exit_probability": m.exit_probability,
             "lift_m": models.action_lifts_[aid]}
            for aid, m in models.actions_.items()
        ],
        "pose_classes": [
            {"id": cid, "kind": m.kind, "file": f"pose_{cid}.npz", "effect_centre": m.centre.tolist(),
             "effect_basis": m.basis.tolist(), "exit_probability": m.exit_probability}
            for cid, m in models.pose_classes_.items()
        ],
        "hand_modes": _hand_modes_entry(models.hand_modes_),
    }
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    models.discovery_.save(folder / "discovery.json")
    models.grammar_.save(folder / "grammar.json")
    for cid, model in models.classes_.items():
        model.phmm.save(folder / f"class_{cid}.npz")
    for aid, model in models.actions_.items():
        model.phmm.save(folder / f"action_{aid}.npz")
    for cid, model in models.pose_classes_.items():
        model.phmm.save(folder / f"pose_{cid}.npz")
    for (cid, mode), model in ({} if models.hand_modes_ is None else models.hand_modes_.classes).items():
        model.phmm.save(folder / f"mode_{cid}_{mode}.npz")


def _hand_modes_entry(modes: HandModes | None) -> dict | None:
    if modes is None:
        return None
    return {"centres": modes.centres.tolist(), "prior": modes.prior.tolist(), "classes": [
        {"id": cid, "mode": mode, "kind": m.kind, "file": f"mode_{cid}_{mode}.npz", "effect_centre": m.centre.tolist(),
         "effect_basis": m.basis.tolist(), "exit_probability": m.exit_probability}
        for (cid, mode), m in modes.classes.items()]}

def read_models_directory(path: Path) -> tuple[object, object, dict]:
    """The directory's ``kind``, ``format_version`` and manifest (checked further by :func:`models_from_directory`)."""
    if not path.is_dir():
        raise DataFileError(f"no models directory at {path}; make one with `hoap-actions learn`")
    manifest = read_manifest(checked_folder_member(path, MANIFEST, "manifest"))
    return manifest.get("kind"), manifest.get("format_version"), manifest

def models_from_directory(cls: type, path: Path, manifest: dict, version: int) -> Any:
    """The ``cls`` models of the directory ``path``: every file validated, each error naming its file and entry."""
    directory = path
    manifest_path = directory / MANIFEST
    check_manifest(manifest_path, manifest)
    try:
        params = dict(manifest["params"])
        if isinstance(params.get("speed_augmentation"), list):  # JSON has no tuples
            params["speed_augmentation"] = tuple(params["speed_augmentation"])
        models = cls(**params)
        models._check_params()
    except (TypeError, InvalidInputError) as exc:
        raise DataFileError(f"{manifest_path}: entry params: {exc}; accepted: {cls._param_names()}") from None
    models.fps_ = positive(manifest_path, "fps", manifest["fps"])
    models.marker_names_ = tuple(names(manifest_path, "marker_names", manifest["marker_names"]))
    width = (2 if models.velocity else 1) * 3 * len(models.marker_names_)
    prior = manifest["covars_prior"]
    models.covars_prior_ = None if prior is None else finite_array(manifest_path, "covars_prior", prior, (width,))
    models.demonstrators_ = profiles_entry(manifest_path, manifest.get("demonstrators", []))
    offset = manifest.get("grasp_offset") if version >= 3 else None
    models.grasp_offset_ = None if offset is None else finite_array(manifest_path, "grasp_offset", offset, (3,))
    ends = manifest.get("approach_ends") if version >= 5 else None
    if ends is not None and not (isinstance(ends, list) and ends):
        raise DataFileError(f"{manifest_path}: entry approach_ends must be null or a non-empty list of (x, y, z) rows; "
                            f"got {ends!r}")
    models.approach_ends_ = None if ends is None else finite_array(manifest_path, "approach_ends", ends, (len(ends), 3))
    models.discovery_ = PrimitiveDiscovery.load(checked_folder_member(directory, "discovery.json", "discovery file"))
    models.grammar_ = ActionGrammar.load(checked_folder_member(directory, "grammar.json", "grammar file"))
    classes = {e["id"]: _entry_model(directory, e, "classes", "class", width)
               for e in _entries(manifest_path, manifest, "classes")}
    actions = {e["id"]: _entry_model(directory, e, "actions", "action", width)
               for e in (_entries(manifest_path, manifest, "actions") if version >= 2 else [])}
    models.actions_ = dict(sorted(actions.items()))
    models.action_lifts_ = {}
    for entry in (manifest["actions"] if version >= 2 else []):
        lift = entry.get("lift_m")
        if isinstance(lift, bool) or not isinstance(lift, (int, float)) or not np.isfinite(lift):
            raise DataFileError(f"{manifest_path}: entry actions[{entry['id']}]: lift_m must be a number (m); got "
                                f"{lift!r}")
        models.action_lifts_[entry["id"]] = float(lift)
    models.action_of_class_ = {}
    for entry in (manifest["classes"] if version >= 2 and actions else []):
        if entry.get("action") not in actions:
            raise DataFileError(f"{manifest_path}: entry classes[{entry['id']}]: action must be one of the "
                                f"actions {sorted(actions)}; got {entry.get('action')!r}")
        models.action_of_class_[entry["id"]] = entry["action"]
    known = {c.primitive_id for c in models.discovery_.classes_}
    if set(classes) != known or set(models.grammar_.symbols_) - set(classes):
        raise DataFileError(
            f"{manifest_path}: classes {sorted(classes)} do not match the discovery's {sorted(known)} "
            "or the grammar's symbols"
        )
    models.classes_ = dict(sorted(classes.items()))
    models.pose_classes_ = _pose_classes(directory, manifest, models.classes_, width) if version >= 4 else {}
    models.hand_modes_ = _hand_modes(directory, manifest, models.classes_, width) if version >= 6 else None
    if version < 6:
        warnings.warn(f"{manifest_path}: written before hand modes (format {version}): the models recognise and act as "
                      "before, and the tracker poses each class by one mean over every way of holding the hand; learn "
                      "them again (pose_hand_modes=4, as the shipped models) for the tracker's figures",
                      MissingModelPartWarning, stacklevel=4)
    return models


def _hand_modes(directory: Path, manifest: dict, classes: Mapping[int, ClassModel], width: int) -> HandModes | None:
    """The manifest's hand modes (null: none), each refitted class checked to stand for a class of the same kind
    and states."""
    entry = manifest.get("hand_modes")
    if entry is None:
        return None
    where = f"{directory / MANIFEST}: entry hand_modes"
    if not isinstance(entry, dict) or not isinstance(entry.get("prior"), list) or not isinstance(entry.get("classes"),
                                                                                                   list):
        raise DataFileError(f"{where} must be null or hold centres, prior and classes")
    k = len(entry["prior"])
    prior = finite_array(directory / MANIFEST, "hand_modes.prior", entry["prior"], (k,))
    centres = finite_array(directory / MANIFEST, "hand_modes.centres", entry.get("centres"), (k, 6))
    refitted = {}
    for item in entry["classes"]:
        if (not isinstance(item, dict) or not isinstance(item.get("id"), int) or not isinstance(item.get("mode"), int)
                or item.get("file") != f"mode_{item.get('id')}_{item.get('mode')}.npz"):
            raise DataFileError(f"{where}: each class must hold an int id and mode and its file mode_<id>_<mode>.npz; "
                                f"got {item!r}")
        model = _entry_model(directory, item, "hand_modes.classes", "mode", width)
        same = classes.get(model.class_id)
        if same is None or same.kind != model.kind or same.phmm.n_states != model.phmm.n_states:
            raise DataFileError(f"{where}: class {model.class_id} in mode {item['mode']} must refit a class of the "
                                f"same kind and states; the classes are {sorted(classes)}")
        refitted[(model.class_id, item["mode"])] = model
    try:
        return HandModes(centres, prior, refitted)
    except InvalidInputError as exc:
        raise DataFileError(f"{where}: {exc}") from None


def _pose_classes(directory: Path, manifest: dict, classes: Mapping[int, ClassModel], width: int
                  ) -> dict[int, ClassModel]:
    """The manifest's pose classes, each checked to stand for a class of the same kind and states."""
    poses = {}
    for entry in _entries(directory / MANIFEST, manifest, "pose_classes"):
        pose = _entry_model(directory, entry, "pose_classes", "pose", width)
        same = classes.get(pose.class_id)
        if same is None or same.kind != pose.kind or same.phmm.n_states != pose.phmm.n_states:
            raise DataFileError(f"{directory / MANIFEST}: entry pose_classes[{pose.class_id}] must refit a class of "
                                f"the same kind and states; the classes are {sorted(classes)}")
        poses[pose.class_id] = pose
    return dict(sorted(poses.items()))

def _entries(manifest_path: Path, manifest: dict, key: str) -> list[dict]:
    """The manifest's list ``key`` of models, each an object with an int id and its file ``<prefix>_<id>.npz``."""
    prefix = {"classes": "class", "actions": "action", "pose_classes": "pose"}[key]
    entries = manifest.get(key)
    if not isinstance(entries, list):
        raise DataFileError(f"{manifest_path}: entry {key} must be a list of models")
    for entry in entries:
        if (not isinstance(entry, dict) or not isinstance(entry.get("id"), int)
                or entry.get("file") != f"{prefix}_{entry.get('id')}.npz"):
            raise DataFileError(f"{manifest_path}: entry "
                                f"{key}[{entry.get('id') if isinstance(entry, dict) else entry!r}] "
                                f"must hold an int id and its file {prefix}_<id>.npz")
    return entries


def _entry_model(directory: Path, entry: dict, key: str, prefix: str, width: int) -> ClassModel:
    """One model of the manifest, its numbers checked and its PHMM loaded and matched against them."""
    manifest_path = directory / MANIFEST
    where = f"{manifest_path}: entry {key}[{entry['id']}]"
    centre = finite_array(manifest_path, f"{key}[{entry['id']}].effect_centre", entry.get("effect_centre"),
                          (EFFECT_DIM,))
    basis = np.asarray(entry.get("effect_basis"), dtype=float)
    if basis.ndim != 2 or basis.shape[0] != EFFECT_DIM or not np.all(np.isfinite(basis)):
        raise DataFileError(f"{where}: effect_basis must be a finite (6, r) matrix; got shape {basis.shape}")
    phmm = ParametricHMM.load(checked_folder_member(directory, entry["file"], "model file"))
    if phmm.mean_bar_.shape[1] != width or phmm.W_.shape[2] != basis.shape[1]:
        raise DataFileError(
            f"{directory / entry['file']}: the model has {phmm.mean_bar_.shape[1]} features and "
            f"{phmm.W_.shape[2]} effect directions; the manifest says {width} and {basis.shape[1]}"
        )
    leave = entry.get("exit_probability")
    if isinstance(leave, bool) or not isinstance(leave, (int, float)) or not 0.0 < leave <= 1.0:
        raise DataFileError(f"{where}: exit_probability must be a probability in (0, 1]; got {leave!r}")
    return ClassModel(entry["id"], str(entry["kind"]), phmm, centre, basis, float(leave))


def unique_profiles(profiles: Sequence[Mapping]) -> tuple[dict, ...]:
    """Distinct demonstrator profiles in first-seen order, as JSON-ready dicts."""
    unique: list[dict] = []
    for profile in profiles:
        if not isinstance(profile, Mapping) or "name" not in profile:
            raise InvalidInputError(f"a demonstrator is a profile mapping with a name; got {profile!r}")
        if dict(profile) not in unique:
            unique.append(dict(profile))
    return tuple(unique)


def profiles_entry(manifest_path: Path, value: object) -> tuple[dict, ...]:
    """The manifest's optional ``demonstrators`` entry (absent in models learned before it existed)."""
    try:
        return unique_profiles(value) if isinstance(value, list) else unique_profiles([value])
    except InvalidInputError as exc:
        raise DataFileError(f"{manifest_path}: entry demonstrators: {exc}; accepted: a list of profiles") from None
