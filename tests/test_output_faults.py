"""--overwrite replaces only what the command itself wrote: a folder holding anything else, the
command's own input included, is refused before any work, and nothing in it is lost."""

from __future__ import annotations

import shutil

import pytest

from hoap_actions.apps.cli import main
from hoap_actions.errors import DataExistsError
from hoap_actions.models.shipped import default_models_path
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.models.models_directory import foreign_entries


def test_learn_refuses_to_overwrite_the_folder_of_its_own_input(small_recording, tmp_path, capsys):
    folder = tmp_path / "work"
    folder.mkdir()
    recording = folder / "rec.h5"
    shutil.copyfile(small_recording, recording)
    before = recording.read_bytes()
    assert main(["learn", "--demos", str(recording), "--out", str(folder), "--overwrite"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "rec.h5" in err and "not action models" in err
    assert recording.read_bytes() == before and sorted(p.name for p in folder.iterdir()) == ["rec.h5"]


def test_a_models_directory_is_replaced_and_a_foreign_file_beside_it_refused(tmp_path):
    models = ActionModels.load(default_models_path())
    target = tmp_path / "models"
    models.save(target)
    assert foreign_entries(target) == []
    models.save(target, overwrite=True)  # a models directory: replaced
    (target / "notes.txt").write_text("mine")
    with pytest.raises(DataExistsError, match="notes.txt"):
        models.save(target, overwrite=True)
    assert (target / "notes.txt").read_text() == "mine"


def test_a_folder_without_a_models_manifest_is_all_foreign(tmp_path):
    (tmp_path / "manifest.json").write_text('{"kind": "SomethingElse"}')
    (tmp_path / "class_0.npz").write_bytes(b"")
    assert foreign_entries(tmp_path) == ["class_0.npz", "manifest.json"]
