"""The action models shipped in the package: what ships is what the documented command made, and it works."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hoap_actions
from hoap_actions.apps.cli import main
from hoap_actions.models.shipped import (
    LEARN_PARAMS,
    PROVENANCE,
    TRAINING_PRESET,
    TRAINING_SEEDS,
    build_default_models,
    default_models_path,
    load_default_models,
    sha256,
)
from hoap_actions.models.shipped import main as build_main
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.models.action_models import ActionModels


def test_shipped_files_are_the_ones_the_build_command_recorded():
    path = default_models_path()
    provenance = json.loads((path / PROVENANCE).read_text())
    assert provenance["preset"] == TRAINING_PRESET and tuple(provenance["seeds"]) == TRAINING_SEEDS
    assert provenance["hoap_actions_version"] == hoap_actions.__version__
    assert set(provenance["recordings_sha256"]) == {f"{TRAINING_PRESET}-s{s}.h5" for s in TRAINING_SEEDS}
    shipped = {p.name for p in path.iterdir()} - {PROVENANCE}
    assert shipped == set(provenance["files_sha256"])
    for name, digest in provenance["files_sha256"].items():
        assert sha256(path / name) == digest, f"{name} differs from the file the build command wrote"


def test_shipped_models_were_discovered_with_the_library_s_defaults():
    shipped = PrimitiveDiscovery.load(default_models_path() / "discovery.json")
    assert shipped.get_params() == PrimitiveDiscovery().get_params()


def test_shipped_models_load_and_are_small():
    models = load_default_models()
    assert len(models.classes_) == json.loads((default_models_path() / PROVENANCE).read_text())["classes"]
    # bytes in the wheel: 6 MB of recognition models and discovery, 15 MB of the tracker's thin-plate pose classes
    # (40 kernel weights per state and marker coordinate, for every class), 16 MB of their refits per hand mode
    assert sum(p.stat().st_size for p in default_models_path().iterdir()) < 40e6


@pytest.fixture(scope="module")
def small(small_recording):
    return small_recording


def test_recognize_without_models_uses_the_shipped_ones(small, tmp_path, capsys):
    out = tmp_path / "r.json"
    assert main(["recognize", "--demos", str(small), "--json", str(out), "--no-oracle"]) == 0
    report = json.loads(out.read_text())
    assert report["models"] == "shipped default models" and report["episodes"] == 4
    # the small preset's push, move and rotate are pieces the paper preset's models know
    assert report["frame_accuracy"] > 0.5


@pytest.mark.slow
def test_the_build_command_remakes_the_shipped_models(tmp_path):
    """Records the ten training recordings and learns again (about 10 minutes on 2 cores)."""
    built = build_default_models(tmp_path / "models", tmp_path / "data")
    shipped = json.loads((default_models_path() / PROVENANCE).read_text())
    again = json.loads((built / PROVENANCE).read_text())
    assert again["recordings_sha256"] == shipped["recordings_sha256"]  # the simulator is deterministic
    a, b = ActionModels.load(built), load_default_models()
    assert sorted(a.classes_) == sorted(b.classes_)
    for cid in a.classes_:
        np.testing.assert_allclose(a.classes_[cid].phmm.mean_bar_, b.classes_[cid].phmm.mean_bar_, rtol=1e-6, atol=1e-9)
    assert sorted(a.pose_classes_) == sorted(b.pose_classes_) == sorted(b.classes_)  # every class, for the tracker
    for cid in a.pose_classes_:
        np.testing.assert_allclose(a.pose_classes_[cid].phmm.mean_bar_, b.pose_classes_[cid].phmm.mean_bar_, rtol=1e-6,
                                   atol=1e-9)
    np.testing.assert_allclose(a.hand_modes_.centres, b.hand_modes_.centres, atol=1e-9)
    assert sorted(a.hand_modes_.classes) == sorted(b.hand_modes_.classes)
    for key, refit in a.hand_modes_.classes.items():
        np.testing.assert_allclose(refit.phmm.mean_bar_, b.hand_modes_.classes[key].phmm.mean_bar_, rtol=1e-6,
                                   atol=1e-9)


def test_the_shipped_models_pose_every_class_with_thin_plate_classes():
    models = load_default_models()
    assert sorted(models.pose_classes_) == sorted(models.classes_)
    for cid, pose in models.pose_classes_.items():
        assert pose.phmm.mean_model == "tps" and models.classes_[cid].phmm.mean_model == "linear"


def test_the_shipped_models_pose_the_arm_per_way_of_holding_the_hand():
    """Four hand modes, each refit a thin-plate pose class of its class's kind and chain; the tracker holds the
    ends of the approaches whose refits leave a direction of the end out."""
    from hoap_actions.tracking.effect_bounds import EndHold

    models = load_default_models()
    modes = models.hand_modes_
    assert modes.n_modes == LEARN_PARAMS["pose_hand_modes"] == 4
    np.testing.assert_allclose(modes.prior.sum(), 1.0)
    approach = next(cid for cid, c in models.classes_.items() if c.kind == "approach")
    assert {(approach, m) for m in range(4)} <= set(modes.classes)  # the approach refitted for every mode
    for (cid, _), refit in modes.classes.items():
        pose = models.pose_classes_[cid]
        assert refit.kind == pose.kind and refit.phmm.n_states == pose.phmm.n_states
        assert refit.phmm.mean_model == "tps"
    held = EndHold(models.pose_classes_, modes.classes, 4).held
    assert held and all(cid == approach for cid, _ in held)


def test_the_build_command_refuses_a_wrong_hand_mode_count_before_recording_anything(tmp_path, capsys):
    args = ["--data", str(tmp_path / "data"), "--out", str(tmp_path / "models"), "--pose-hand-modes", "-1"]
    assert build_main(args) == 2
    assert capsys.readouterr().err.strip() == "error: pose_hand_modes must be an int >= 0; got -1"
    assert not (tmp_path / "data").exists() and not (tmp_path / "models").exists()
