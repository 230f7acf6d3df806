"""The JSON file of a fitted :class:`~hoap_actions.primitives.discovery.estimator.PrimitiveDiscovery`
(``kind`` "PrimitiveDiscovery", ``format_version`` 2; version 1 files are the paper's fold): its
hyper-parameters, the joint HMM (state means, covariances, rest flags, transitions, start), the decoded
state strings, the primitives and their kinds, each demonstration's segmentation, and the classes with
their segments (demonstration, frames, initial and final location, the effect's source)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.errors import DataFileError
from hoap_actions.primitives.base import file_params
from hoap_actions.primitives.discovery.primitive_classes import OBJECT_DIM, PrimitiveClass, Segment, xyz
from hoap_actions.primitives.json_files import write_json_model

__all__ = ["discovery_from_document", "write_discovery"]


def write_discovery(model: Any, path: Path, overwrite: bool) -> None:
    """Write a fitted discovery's versioned JSON file."""
    body = {
        "params": file_params(model),
        "joint_means": model.joint_means_.tolist(),
        "joint_covars": model.joint_covars_.tolist(),
        "joint_at_rest": model.joint_at_rest_.tolist(),
        "transmat": model.transmat_.tolist(),
        "startprob": model.startprob_.tolist(),
        "state_sequences": [list(s) for s in model.state_sequences_],
        "primitives": [list(p) for p in model.primitives_],
        "primitive_kinds": model.primitive_kinds_,
        "segmentations": [[list(s) for s in seg] for seg in model.segmentations_],
        "classes": [
            {
                "primitive_id": c.primitive_id,
                "kind": c.kind,
                "states": list(c.states),
                "segments": [
                    [s.demo, s.start, s.end, list(s.initial), list(s.final), s.source] for s in c.segments
                ],
            }
            for c in model.classes_
        ],
    }
    write_json_model(path, model._file_kind, model._format_version, body, overwrite)

def discovery_from_document(cls: type, path: Path, document: dict[str, Any], version: int) -> Any:
    """The ``cls`` model held in a readable discovery file's JSON document."""
    try:
        params = document["params"] if version > 1 else {"merging": "fold", **document["params"]}
        model = cls(**params)
        model.joint_means_ = np.array(document["joint_means"], float).reshape(-1, OBJECT_DIM)
        model.joint_covars_ = np.array(document["joint_covars"], float).reshape(-1, OBJECT_DIM, OBJECT_DIM)
        model.joint_at_rest_ = np.array(document["joint_at_rest"], bool)
        model.transmat_ = np.array(document["transmat"], float)
        model.startprob_ = np.array(document["startprob"], float)
        model.state_sequences_ = [tuple(s) for s in document["state_sequences"]]
        model.primitives_ = [tuple(p) for p in document["primitives"]]
        model.primitive_kinds_ = list(document["primitive_kinds"])
        model.segmentations_ = [[tuple(s) for s in seg] for seg in document["segmentations"]]
        model.classes_ = [
            PrimitiveClass(
                c["primitive_id"],
                c["kind"],
                tuple(c["states"]),
                tuple(Segment(d, a, b, xyz(i), xyz(f), src) for d, a, b, i, f, src in c["segments"]),
            )
            for c in document["classes"]
        ]
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        raise DataFileError(f"{path} is a corrupt PrimitiveDiscovery model file: {exc}") from exc
    return model
