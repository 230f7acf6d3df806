"""Fixtures shared by the test modules: recordings simulated once per test run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hoap_actions.demonstration.datasets import Demonstrations, load_demonstrations
from hoap_actions.demonstration.recording import record
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.models.action_models import ActionModels


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


@pytest.fixture(scope="session")
def small(small_recording, small_demos):
    """The ``small`` preset (push, move, rotate, approach), its discovery, and models fitted on it."""
    path, demos = small_recording, small_demos
    lengths = [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    discovery = PrimitiveDiscovery().fit(np.concatenate([e.O for e in demos]), lengths, H)
    models = ActionModels().fit(H, lengths, discovery, demos.fps, demos.marker_names)
    return demos, discovery, models, path


@pytest.fixture(scope="session")
def posed(small):
    """The small preset's models with pose classes (approach and remove refitted with a thin-plate mean)."""
    demos, discovery, _, _ = small
    lengths = [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    return ActionModels(pose_mean_model="tps", smoothing=0.5).fit(H, lengths, discovery, demos.fps, demos.marker_names)
