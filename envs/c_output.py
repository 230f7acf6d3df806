"""Silencing what C extensions print straight to a file descriptor, which Python's redirects miss."""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def c_output_silenced(fd: int = 2) -> Iterator[None]:
    """Send what C code writes to file descriptor ``fd`` (2: stderr, 1: stdout) to /dev/null meanwhile
    (Python's own errors still raise)."""
    try:
        (sys.stderr if fd == 2 else sys.stdout).flush()
        saved = os.dup(fd)
    except (OSError, ValueError, AttributeError):  # no usable stream: nothing to silence
        yield
        return
    try:
        with open(os.devnull, "w") as devnull:
            os.dup2(devnull.fileno(), fd)
            yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)
