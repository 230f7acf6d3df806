"""hoap_actions.outputs: claims that check before the work and publish whole, or not at all."""

from __future__ import annotations

import os

import pytest

from hoap_actions.errors import DataExistsError, InvalidInputError
from hoap_actions.outputs import PARTIAL_MARK, claimed_directory, claimed_file, claimed_files


def test_claimed_file_publishes_on_success_and_keeps_the_suffix_for_format_sniffing(tmp_path):
    with claimed_file(tmp_path / "video.mp4") as partial:
        assert partial.suffix == ".mp4" and PARTIAL_MARK in partial.name
        partial.write_text("frames")
    assert (tmp_path / "video.mp4").read_text() == "frames"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["video.mp4"]


def test_claimed_file_overwrites_only_when_asked(tmp_path):
    target = tmp_path / "report.json"
    target.write_text("old")
    with pytest.raises(DataExistsError, match="already exists"):
        with claimed_file(target):
            raise AssertionError("the job must not start")
    with claimed_file(target, overwrite=True) as partial:
        partial.write_text("new")
    assert target.read_text() == "new"


def test_a_failed_job_leaves_the_previous_file_and_no_partial(tmp_path):
    target = tmp_path / "report.json"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with claimed_file(target, overwrite=True) as partial:
            partial.write_text("half")
            raise RuntimeError("crash")
    assert [p.name for p in tmp_path.iterdir()] == ["report.json"] and target.read_text() == "old"


def test_claimed_directory_is_published_whole_and_replaced_whole(tmp_path):
    target = tmp_path / "models"
    with claimed_directory(target) as staging:
        (staging / "a.npz").write_text("1")
        (staging / "b.npz").write_text("1")
    assert sorted(p.name for p in target.iterdir()) == ["a.npz", "b.npz"]
    with pytest.raises(DataExistsError, match="already exists"):
        with claimed_directory(target):
            raise AssertionError("the job must not start")
    with pytest.raises(DataExistsError, match="a.npz, b.npz"):  # nothing says what the folder may hold
        with claimed_directory(target, overwrite=True):
            raise AssertionError("the job must not start")

    def foreign(folder):
        return sorted(p.name for p in folder.iterdir() if p.suffix != ".npz")

    with pytest.raises(RuntimeError):  # a failed replacement keeps the old directory
        with claimed_directory(target, overwrite=True, foreign=foreign) as staging:
            (staging / "c.npz").write_text("2")
            raise RuntimeError("crash")
    assert sorted(p.name for p in target.iterdir()) == ["a.npz", "b.npz"]
    with claimed_directory(target, overwrite=True, foreign=foreign) as staging:
        (staging / "c.npz").write_text("2")
    assert sorted(p.name for p in target.iterdir()) == ["c.npz"]  # no stale file of the old models
    assert sorted(p.name for p in tmp_path.iterdir()) == ["models"]


def test_claimed_directory_refuses_a_second_writer(tmp_path):
    with claimed_directory(tmp_path / "models") as staging:
        with pytest.raises(DataExistsError, match="another process is writing"):
            with claimed_directory(tmp_path / "models"):
                raise AssertionError("the second job must not start")
        (staging / "a.npz").write_text("1")
    assert [p.name for p in (tmp_path / "models").iterdir()] == ["a.npz"]


def test_claimed_directory_never_merges_into_a_folder_that_appeared_meanwhile(tmp_path):
    with pytest.raises(DataExistsError, match="already exists"):
        with claimed_directory(tmp_path / "models") as staging:
            (staging / "ours.npz").write_text("1")
            (tmp_path / "models").mkdir()
            (tmp_path / "models" / "theirs.txt").write_text("2")
    assert [p.name for p in (tmp_path / "models").iterdir()] == ["theirs.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["models"]


@pytest.mark.parametrize("path", ["", "file.txt"])
def test_claimed_directory_needs_a_folder_path(tmp_path, path):
    (tmp_path / "file.txt").write_text("x")
    with pytest.raises(InvalidInputError):
        with claimed_directory(tmp_path / path if path else path):
            raise AssertionError("the job must not start")


@pytest.mark.parametrize("claim", [claimed_file, claimed_directory, lambda p: claimed_files(p, ["a.txt"])])
def test_a_path_with_a_nul_character_is_refused(tmp_path, claim):
    with pytest.raises(InvalidInputError, match="NUL character"):
        with claim(str(tmp_path / "a\0b")):
            raise AssertionError("the job must not start")


def test_files_a_killed_run_had_begun_to_publish_are_taken_back(tmp_path):
    """A run killed while publishing (its lock gone with it) left a.json published, b.json still staged
    and c.json linked but not yet unlinked from the staging folder; the next claim starts afresh."""
    names = ["a.json", "b.json", "c.json"]
    (tmp_path / "mine.txt").write_text("not the run's")
    staging = tmp_path / f".results{PARTIAL_MARK}"
    staging.mkdir()
    (staging / ".publishing").write_text("\n".join(names))
    (tmp_path / "a.json").write_text("old a")
    (staging / "b.json").write_text("old b")
    (staging / "c.json").write_text("old c")
    os.link(staging / "c.json", tmp_path / "c.json")
    with claimed_files(tmp_path, names, what="results") as fresh:
        assert sorted(p.name for p in fresh.iterdir()) == []
        for name in names:
            (fresh / name).write_text("new")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == {"a.json": "new", "b.json": "new", "c.json": "new",
                                                                    "mine.txt": "not the run's"}


def test_a_folder_claim_and_a_files_claim_on_one_folder_exclude_each_other(tmp_path):
    target = tmp_path / "out"
    with claimed_files(target, ["a.json"], what="results") as staging:
        (staging / "a.json").write_text("1")
        with pytest.raises(DataExistsError, match="another process is writing into"):
            with claimed_directory(target, overwrite=True, foreign=lambda folder: []):
                raise AssertionError("the job must not start")
    with claimed_directory(tmp_path / "models") as staging:
        with pytest.raises(DataExistsError, match="another process is writing into"):
            with claimed_files(tmp_path / "models", ["a.json"], what="results"):
                raise AssertionError("the job must not start")
