"""Files a user hands in, checked before they are read: a regular file (not a device, a pipe or a link
to one: ``/dev/zero`` never ends), of a size a model or dataset of this project can have."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from hoap_actions.errors import DataFileError

__all__ = ["MAX_JSON_BYTES", "checked_input_file", "checked_folder_member"]

MAX_JSON_BYTES = 256 * 2**20
"""Largest JSON model file read (the shipped models' largest is under 1 MB)."""


def checked_input_file(path: str | os.PathLike, what: str, max_bytes: int) -> Path:
    """``path`` once it is a regular file (links followed) of at most ``max_bytes``; else DataFileError."""
    path = Path(path)
    try:
        info = path.stat()
    except FileNotFoundError:
        raise DataFileError(f"no {what} at {path}") from None
    except OSError as exc:
        raise DataFileError(f"cannot read the {what} {path}: {exc.strerror}") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "a device, pipe or socket"
        raise DataFileError(f"the {what} {path} is {kind}, not a file; give the file itself")
    if info.st_size > max_bytes:
        raise DataFileError(f"the {what} {path} is {info.st_size / 2**20:.0f} MiB, more than the "
                            f"{max_bytes / 2**20:.0f} MiB such a file can have; is it the right file?")
    return path


def checked_folder_member(folder: str | os.PathLike, name: str, what: str) -> Path:
    """``folder / name`` once it stays inside ``folder`` with links followed: a file of a models folder
    that links elsewhere (another user's file, a device) is refused, not read as part of the folder."""
    folder = Path(folder)
    path = folder / name
    try:
        inside = path.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError) as exc:  # a loop of links
        raise DataFileError(f"cannot read the {what} {path}: {exc}") from None
    if not inside:
        raise DataFileError(f"the {what} {path} links outside its folder {folder}; copy the file into the "
                            "folder instead of linking to it")
    return path
