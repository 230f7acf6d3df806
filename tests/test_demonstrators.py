"""Demonstrators of different sizes and ways of moving: profiles, scaled bodies, recordings."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from hoap_actions.demonstration.bodies import (
    DEMONSTRATORS,
    REFERENCE_HEIGHT_M,
    DemonstratorProfile,
    demonstrator_profile,
    human_urdf,
)
from hoap_actions.errors import InvalidInputError
from hoap_actions.urdf import urdf_path


def test_named_and_random_profiles():
    assert demonstrator_profile("reference") == DemonstratorProfile()
    assert demonstrator_profile("tall").height_m == 1.88
    drawn = [demonstrator_profile("random", seed) for seed in range(20)]
    assert drawn[3] == demonstrator_profile("random", 3)  # seeded
    assert len({p.height_m for p in drawn}) > 10 and all(1.55 <= p.height_m <= 1.90 for p in drawn)
    assert all(p.proximal_sd_rad > 0 for p in drawn)
    with pytest.raises(InvalidInputError, match="unknown demonstrator 'giant'; choose one of"):
        demonstrator_profile("giant")
    with pytest.raises(InvalidInputError, match="height_m must be a number in"):
        DemonstratorProfile(height_m=2.5)


def joint_origin(root: ET.Element, name: str) -> np.ndarray:
    joint = next(j for j in root.iter("joint") if j.get("name") == name)
    return np.array([float(v) for v in joint.find("origin").get("xyz").split()])


def link_mass(root: ET.Element, name: str) -> float:
    link = next(k for k in root.iter("link") if k.get("name") == name)
    return float(link.find("inertial/mass").get("value"))


def test_a_taller_body_has_longer_trunk_and_arm_and_the_same_hand():
    assert human_urdf(REFERENCE_HEIGHT_M) == urdf_path("human_arm.urdf")
    reference = ET.parse(urdf_path("human_arm.urdf")).getroot()
    tall = ET.parse(human_urdf(1.88)).getroot()
    s = 1.88 / REFERENCE_HEIGHT_M
    for joint in ("r_shoulder_flexion", "r_elbow", "r_wrist_flexion", "marker_elbow_joint", "lumbar_flexion"):
        np.testing.assert_allclose(joint_origin(tall, joint), s * joint_origin(reference, joint), rtol=1e-5)
    for joint in ("r_index_mcp", "r_thumb_cmc", "marker_index_tip_joint", "grasp_site_joint"):
        np.testing.assert_array_equal(joint_origin(tall, joint), joint_origin(reference, joint))
    assert link_mass(tall, "r_upper_arm") == pytest.approx(s**3 * link_mass(reference, "r_upper_arm"), rel=1e-5)
    assert link_mass(tall, "r_palm") == link_mass(reference, "r_palm")


@pytest.fixture(scope="module")
def short_recording(tmp_path_factory):
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.demonstration.recording import record

    folder = tmp_path_factory.mktemp("demonstrators")
    reference = load_demonstrations(record("small", folder / "reference.h5", seed=1, progress=False))
    short = load_demonstrations(record("small", folder / "short.h5", seed=1, progress=False, demonstrator="short"))
    return reference, short, folder


def test_a_short_demonstrator_does_every_task_with_a_shorter_arm_and_is_named_in_the_file(short_recording):
    reference, short, _ = short_recording
    assert "demonstrator" not in reference.generator and reference.demonstrator == DEMONSTRATORS["reference"].to_dict()
    assert short.generator["demonstrator"] == DEMONSTRATORS["short"].to_dict()
    assert short.generator["missed_grasp_episodes"] == [] and short.generator["table_contact_episodes"] == []
    upper_arm = [np.linalg.norm(d[0].H[:, 1] - d[0].H[:, 0], axis=1).mean() for d in (reference, short)]
    assert upper_arm[1] == pytest.approx(upper_arm[0] * 1.60 / REFERENCE_HEIGHT_M, rel=1e-3)
    for e in short:
        truth = e.ground_truth
        if truth.action != "approach":  # the block ends where the task put it, within 1 cm
            assert np.linalg.norm(e.O[-1, :2] - truth.object_target[:2]) < 0.01
    # slower (speed 0.9): every episode lasts longer than the reference's on average
    assert np.mean([e.T for e in short]) > np.mean([e.T for e in reference])


def test_the_demonstrator_and_the_scene_must_hold_the_same_body():
    from hoap_actions.demonstration.demonstrator import Demonstrator
    from hoap_actions.demonstration.scene import DemoScene

    scene = DemoScene()
    try:
        with pytest.raises(InvalidInputError, match="make the scene with DemoScene"):
            Demonstrator(scene, DEMONSTRATORS["tall"])
    finally:
        scene.close()


def test_record_command_names_the_demonstrators_it_accepts(tmp_path, capsys):
    from hoap_actions.apps.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["record", "--preset", "small", "--out", str(tmp_path / "x.h5"), "--demonstrator", "giant"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'giant'" in capsys.readouterr().err and not (tmp_path / "x.h5").exists()


def test_models_know_who_they_learned_from_and_warn_about_anyone_else(short_recording, tmp_path):
    import warnings

    from hoap_actions.errors import UnseenDemonstratorWarning
    from hoap_actions.primitives.models.action_models import ActionModels
    from hoap_actions.primitives.pipelines.learn import learn
    from hoap_actions.primitives.pipelines.recognize import recognize_recording

    reference, short, folder = short_recording
    models, _ = learn([folder / "reference.h5"])
    assert models.demonstrators_ == (DEMONSTRATORS["reference"].to_dict(),)
    models.save(tmp_path / "models")
    assert ActionModels.load(tmp_path / "models").demonstrators_ == models.demonstrators_
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnseenDemonstratorWarning)
        recognize_recording(models, reference, oracle=False)  # the demonstrator it learned from: no warning
    with pytest.warns(UnseenDemonstratorWarning, match="demonstrator 'short' .* none of those the models learned from"):
        recognize_recording(models, short, oracle=False)
