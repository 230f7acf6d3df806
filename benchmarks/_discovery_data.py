"""Where the discovery benchmarks keep their recordings, and re-recording them when the demonstrator changed.

Datasets live outside the repository, in ``$HOAP_ACTIONS_DATA/discovery/`` (default ``/work/data``).
A recording older than any of the demonstrator's sources is recorded again, so the figures always
describe the current demonstrator.
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path

logger = logging.getLogger(__name__)

DATA_DIR = Path(os.environ.get("HOAP_ACTIONS_DATA", "/work/data")) / "discovery"


def demonstrator_sources() -> list[Path]:
    """The files that decide what a recording contains."""
    from hoap_actions.envs import demo_scene, demonstrator, recording
    from hoap_actions.primitives import datasets

    return [Path(m.__file__) for m in (demonstrator, recording, demo_scene, datasets)]


def sources_digest() -> str:
    """A short hash of the demonstrator's sources, stored beside the figures they produced."""
    digest = hashlib.sha256()
    for path in demonstrator_sources():
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def paper_dataset(seed: int = 0, path: Path | None = None, rerecord_if_stale: bool = True) -> Path:
    """The ``paper`` preset recorded with ``seed``: loaded from ``path`` (default in :data:`DATA_DIR`), recorded if
    missing or older than the demonstrator's sources."""
    from hoap_actions.envs.recording import record

    path = Path(path) if path is not None else DATA_DIR / f"paper-seed{seed}.h5"
    newest_source = max(p.stat().st_mtime for p in demonstrator_sources())
    if path.exists() and (not rerecord_if_stale or path.stat().st_mtime >= newest_source):
        return path
    logger.warning("recording the paper preset (seed %d) to %s (%s)", seed, path,
                   "missing" if not path.exists() else "older than the demonstrator")
    path.parent.mkdir(parents=True, exist_ok=True)
    return record("paper", path, seed=seed, overwrite=True, progress=True)
