"""The discovery benchmarks' recordings: ``paper`` recordings in the ``--data`` folder (the checkout's
``data/``), made there on demand, and a digest of the demonstrator's sources stored beside the figures.

A recording older than any of the demonstrator's sources may no longer describe the current
demonstrator: it is named in a warning, and recorded again only when asked (``rerecord_stale``).
"""

from __future__ import annotations

import hashlib
import logging
from pathlib import Path

from _results import ensure_recording

logger = logging.getLogger(__name__)


def demonstrator_sources() -> list[Path]:
    """The files that decide what a recording contains."""
    from hoap_actions.demonstration import datasets, demonstrator, recording
    from hoap_actions.demonstration import scene as demo_scene

    return [Path(m.__file__) for m in (demonstrator, recording, demo_scene, datasets)]


def sources_digest() -> str:
    """A short hash of the demonstrator's sources, stored beside the figures they produced."""
    digest = hashlib.sha256()
    for path in demonstrator_sources():
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def paper_recording(seed: int, data: Path, rerecord_stale: bool = False) -> Path:
    """``data/paper-s<seed>.h5``, recorded if missing (and, with ``rerecord_stale``, if older than the
    demonstrator's sources)."""
    path = ensure_recording("paper", seed, data)
    if path.stat().st_mtime >= max(p.stat().st_mtime for p in demonstrator_sources()):
        return path
    if not rerecord_stale:
        logger.warning("%s is older than the demonstrator's sources; its figures may not describe the current "
                       "demonstrator (--rerecord-stale records it again)", path)
        return path
    from hoap_actions.demonstration.recording import record

    logger.warning("recording the paper preset (seed %d) again to %s (older than the demonstrator)", seed, path)
    return record("paper", path, seed=seed, overwrite=True)
