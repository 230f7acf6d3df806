"""Fixtures shared by the test modules: recordings simulated once per test run."""

from __future__ import annotations

from pathlib import Path

import pytest

from hoap_actions.demonstration.datasets import Demonstrations, load_demonstrations
from hoap_actions.demonstration.recording import record


@pytest.fixture(scope="session")
def small_recording(tmp_path_factory) -> Path:
    """The ``small`` preset recorded with seed 0 (4 episodes: approach, push, move, rotate), made once per
    run and read-only: a test that edits a recording copies it first."""
    path = record("small", tmp_path_factory.mktemp("recordings") / "small.h5", seed=0, progress=False)
    path.chmod(0o444)
    return path


@pytest.fixture(scope="session")
def small_demos(small_recording: Path) -> Demonstrations:
    """The ``small`` recording loaded."""
    return load_demonstrations(small_recording)
