"""The robot, demonstrator and scene models, shipped as package data (URDF, primitive shapes only)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from hoap_actions.errors import DataFileError


def urdf_path(name: str) -> Path:
    """Absolute path of the packaged URDF file ``name`` (e.g. ``"hoap3.urdf"``)."""
    path = Path(str(files(__name__).joinpath(name)))
    if not path.is_file():
        available = sorted(p.name for p in path.parent.glob("*.urdf"))
        raise DataFileError(f"no packaged URDF named {name!r}; available: {available}")
    return path
