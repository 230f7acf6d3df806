"""Files that would make a reader run away or crash: a link to a device that never ends, archives whose
headers declare huge arrays, JSON nested past Python's recursion limit, and particle counts no
machine holds. Each is refused with the project's error before anything large is read or allocated."""

from __future__ import annotations

import io
import os
import time
import zipfile

import numpy as np
import pytest

from hoap_actions.apps.cli import main
from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.errors import DataFileError, InvalidInputError
from hoap_actions.models.shipped import default_models_path, load_default_models
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.tracking.action_tracker import MAX_PARTICLES, ActionTracker
from hoap_actions.vision.body_model import BodyModel


def test_a_model_file_linked_to_a_device_is_refused(tmp_path):
    link = tmp_path / "discovery.json"
    os.symlink("/dev/zero", link)
    with pytest.raises(DataFileError, match="not a file"):
        PrimitiveDiscovery.load(link)


def test_json_nested_past_the_recursion_limit_is_refused(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(DataFileError, match="nested too deeply"):
        PrimitiveDiscovery.load(path)


def test_an_archive_declaring_a_trillion_floats_is_refused_before_numpy_allocates(tmp_path):
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (10**12,)})
    path = tmp_path / "huge.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("W_.npy", header.getvalue())  # the header alone: no data follows
    with pytest.raises(DataFileError, match="declares arrays of"):
        ParametricHMM.load(path)


def test_the_command_line_refuses_a_device_as_models(tmp_path, capsys):
    folder = tmp_path / "models"
    folder.mkdir()
    os.symlink("/dev/zero", folder / "manifest.json")
    assert main(["recognize", "--demos", str(tmp_path / "none.h5"), "--models", str(folder)]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_a_models_folder_file_linking_outside_the_folder_is_refused(tmp_path):
    import shutil

    folder = tmp_path / "models"
    shutil.copytree(default_models_path(), folder)
    (folder / "grammar.json").rename(folder / "grammar_v1.json")
    os.symlink("grammar_v1.json", folder / "grammar.json")  # a link inside the folder is part of it
    assert ActionModels.load(folder).grammar_.symbols_ == load_default_models().grammar_.symbols_
    (folder / "grammar_v1.json").rename(tmp_path / "grammar.json")
    (folder / "grammar.json").unlink()
    os.symlink(tmp_path / "grammar.json", folder / "grammar.json")
    with pytest.raises(DataFileError, match="links outside its folder"):
        ActionModels.load(folder)


def test_a_render_larger_than_the_free_memory_is_refused_before_pybullet_allocates(monkeypatch):
    import gymnasium

    from hoap_actions.envs import camera

    monkeypatch.setattr(camera, "_free_memory", lambda: 100 * 2**20)
    with pytest.raises(InvalidInputError, match="MiB free"):
        gymnasium.make("hoap_actions/PegInsert-v0", render_mode="rgb_array", render_width=2048, render_height=1536)
    camera.check_image_size(640, 480)  # 19 MiB: fits


def test_a_tracker_refuses_more_particles_than_it_can_hold():
    models = load_default_models()
    body = BodyModel(models.marker_names_, torso_base=np.zeros(3))
    with pytest.raises(InvalidInputError, match=f"1..{MAX_PARTICLES}"):
        ActionTracker(models, body, [], n_particles=10_000_000)


def _edited(small_recording, tmp_path, attribute, value):
    import shutil

    import h5py

    path = tmp_path / "edited.h5"
    shutil.copyfile(small_recording, path)
    with h5py.File(path, "r+") as f:
        f.attrs[attribute] = value
    return path


@pytest.mark.parametrize("fps", [0.0, -100.0, float("nan"), 1e9])
def test_a_recording_with_an_impossible_frame_rate_is_refused(small_recording, tmp_path, fps, capsys):
    path = _edited(small_recording, tmp_path, "fps", fps)
    with pytest.raises(DataFileError, match="fps"):
        load_demonstrations(path)
    assert main(["discover", "--demos", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "fps" in capsys.readouterr().err


def test_a_generator_attribute_that_is_not_an_object_is_refused(small_recording, tmp_path):
    with pytest.raises(DataFileError, match="generator is not a JSON object"):
        load_demonstrations(_edited(small_recording, tmp_path, "generator", "[1, 2]"))


def test_an_episode_array_declaring_terabytes_is_refused_before_it_is_read(small_recording, tmp_path):
    import shutil

    import h5py

    path = tmp_path / "huge.h5"
    shutil.copyfile(small_recording, path)
    with h5py.File(path, "r+") as f:
        del f["episode_00000/H"]
        f["episode_00000"].create_dataset("H", shape=(10**12, 6, 3), dtype="f8", chunks=(1000, 6, 3))
    with pytest.raises(DataFileError, match="declares"):
        load_demonstrations(path)


def test_an_output_that_is_a_dangling_link_is_refused_before_any_work(tmp_path, capsys):
    os.symlink(tmp_path / "nowhere" / "x.h5", tmp_path / "out.h5")
    started = time.monotonic()
    assert main(["record", "--preset", "paper", "--out", str(tmp_path / "out.h5")]) == 2
    assert time.monotonic() - started < 5.0  # refused at the claim, not after a recording
    assert "does not exist" in capsys.readouterr().err


def test_a_models_manifest_linked_to_a_device_makes_the_folder_foreign_without_reading_it(tmp_path):
    from hoap_actions.primitives.models.models_directory import foreign_entries

    os.symlink("/dev/zero", tmp_path / "manifest.json")
    assert foreign_entries(tmp_path) == ["manifest.json"]
