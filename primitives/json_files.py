"""Versioned JSON model files: one place that writes them safely and reads them with clear errors.

Every file is a JSON object with ``"kind"`` (which class wrote it) and ``"format_version"``; which
kinds and versions an estimator reads is checked by :meth:`hoap_actions.primitives.base.Estimator.load`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from hoap_actions.errors import DataFileError
from hoap_actions.inputs import MAX_JSON_BYTES, checked_input_file
from hoap_actions.outputs import claimed_file


def write_json_model(path: str | os.PathLike, kind: str, version: int, body: dict[str, Any], overwrite: bool) -> Path:
    """Write ``body`` under ``kind``/``version``; refuse to replace a file unless ``overwrite``.

    Written through :func:`hoap_actions.outputs.claimed_file`: an interrupted write never leaves a
    half-written model under the final name, and of two concurrent writers one gets DataExistsError.
    """
    document = {"format_version": version, "kind": kind, **body}
    with claimed_file(path, overwrite, what=f"{kind} file") as partial:
        partial.write_text(json.dumps(document, indent=1))
    return Path(path)


def read_json_model(path: str | os.PathLike, kind: str) -> dict[str, Any]:
    """The JSON object in a file written by :func:`write_json_model` (``kind`` names it in errors)."""
    label = f"{kind} file"
    path = checked_input_file(path, label, MAX_JSON_BYTES)
    try:
        document = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise DataFileError(f"{path} is not a readable JSON {label}: {exc}") from exc
    except RecursionError:  # nesting deeper than any file this project writes
        raise DataFileError(f"{path} is not a {label}: its JSON is nested too deeply") from None
    if not isinstance(document, dict):
        raise DataFileError(f"{path} is not a {label}: it holds a JSON {type(document).__name__}, not an object")
    return document


class JsonModelFile:
    """Mixin for an :class:`~hoap_actions.primitives.base.Estimator` whose file is one JSON object written
    by :func:`write_json_model`: its ``_read`` returns ``(kind, format_version, document)``."""

    _file_kind: str

    @classmethod
    def _read(cls, path: Path) -> tuple[Any, Any, dict[str, Any]]:
        document = read_json_model(path, cls._file_kind)
        return document.get("kind"), document.get("format_version"), document
