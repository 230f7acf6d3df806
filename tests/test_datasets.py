"""The demonstration file format: round trip, hmmlearn-style views, refusing to overwrite, atomic
writes, and a clear error for every kind of bad file."""

from __future__ import annotations

import dataclasses

import h5py
import numpy as np
import pytest

from hoap_actions.demonstration import datasets
from hoap_actions.demonstration.datasets import (
    Demonstrations,
    Episode,
    GroundTruth,
    load_demonstrations,
    write_demonstrations,
)
from hoap_actions.errors import DataExistsError, DataFileError, InvalidInputError

PHASES = ("approach", "push-left", "remove")
MARKERS = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")


def make_episode(rng: np.random.Generator, T: int) -> Episode:
    labels = np.repeat([0, 1, 2], [T // 3, T // 3, T - 2 * (T // 3)])
    O = np.tile([0.0, 0.0, 0.025, 0.0, 0.0, 0.1], (T, 1)) + rng.normal(0.0, 0.01, (T, 6))
    truth = GroundTruth(
        labels=labels, phase_names=PHASES, action="push", direction="left", distance=0.1, angle=0.0,
        object_start=O[0], object_end=O[-1], object_target=O[0] + [0.0, 0.1, 0, 0, 0, 0],
        hand_rest=np.array([-0.3, -0.2, -0.3]), repetition=1,
    )
    return Episode(H=rng.normal(0.0, 0.3, (T, 6, 3)), O=O, ground_truth=truth, seed=(7, 1))


@pytest.fixture
def demos() -> Demonstrations:
    rng = np.random.default_rng(0)
    episodes = tuple(make_episode(rng, T) for T in (30, 45, 12))
    return Demonstrations(
        episodes=episodes, fps=100.0, marker_names=MARKERS, phase_names=PHASES, seed=7,
        scene={"table": [0.6, 1.2]}, generator={"preset": "unit-test", "seed": 7},
    )


@pytest.fixture
def written(tmp_path, demos):
    return write_demonstrations(tmp_path / "demos.h5", demos)


def test_round_trip_keeps_everything(written, demos):
    loaded = load_demonstrations(written)
    assert len(loaded) == len(demos) and loaded.fps == 100.0 and loaded.seed == 7
    assert loaded.marker_names == MARKERS and loaded.phase_names == PHASES
    assert loaded.scene == demos.scene and loaded.generator == demos.generator
    for a, b in zip(loaded, demos):
        assert np.array_equal(a.H, b.H) and np.array_equal(a.O, b.O) and a.seed == b.seed
        ga, gb = a.ground_truth, b.ground_truth
        assert np.array_equal(ga.labels, gb.labels)
        assert (ga.action, ga.direction, ga.distance, ga.repetition, ga.grid) == ("push", "left", 0.1, 1, "")
        for name in ("object_start", "object_end", "object_target", "hand_rest", "grid_index"):
            assert np.array_equal(getattr(ga, name), getattr(gb, name))
    assert list(loaded[0].ground_truth.phases()[:1]) == ["approach"]
    assert [s[0] for s in loaded[0].ground_truth.segments()] == list(PHASES)


JOINTS = ("lumbar", "shoulder", "elbow")


def with_joint_angles(demos: Demonstrations) -> Demonstrations:
    rng = np.random.default_rng(1)
    episodes = tuple(dataclasses.replace(e, Q=rng.normal(0.0, 0.5, (e.T, len(JOINTS)))) for e in demos)
    return dataclasses.replace(demos, episodes=episodes, joint_names=JOINTS)


def test_joint_angles_round_trip(tmp_path, demos):
    posed = with_joint_angles(demos)
    loaded = load_demonstrations(write_demonstrations(tmp_path / "posed.h5", posed))
    assert loaded.joint_names == JOINTS
    for a, b in zip(loaded, posed):
        assert np.array_equal(a.Q, b.Q)
    assert all(e.Q is None for e in load_demonstrations(write_demonstrations(tmp_path / "bare.h5", demos)))


def test_version_1_files_load_without_joint_angles(written):
    with h5py.File(written, "r+") as f:
        f.attrs["format_version"] = 1
        del f.attrs["joint_names"]
    loaded = load_demonstrations(written)
    assert loaded.joint_names == () and all(e.Q is None for e in loaded)


def test_joint_angles_must_match_their_names(tmp_path, demos):
    posed = with_joint_angles(demos)
    short = dataclasses.replace(posed, episodes=(dataclasses.replace(posed[0], Q=posed[0].Q[:, :2]),))
    with pytest.raises(InvalidInputError, match="Q must be finite with shape"):
        write_demonstrations(tmp_path / "short.h5", short)
    with pytest.raises(InvalidInputError, match="Q must be given exactly when joint_names are"):
        write_demonstrations(tmp_path / "nameless.h5", dataclasses.replace(posed, joint_names=()))
    path = write_demonstrations(tmp_path / "posed.h5", posed)
    with h5py.File(path, "r+") as f:
        del f["episode_00001/Q"]
        f["episode_00001/Q"] = np.zeros((45, 2))
    with pytest.raises(DataFileError, match="episode_00001: entry Q has shape"):
        load_demonstrations(path)
    with h5py.File(path, "r+") as f:
        del f["episode_00001/Q"]
        f["episode_00001/Q"] = np.full((45, len(JOINTS)), 1e300)
    with pytest.raises(DataFileError, match="episode_00001: Q frame 0 has a joint angle of 1e"):
        load_demonstrations(path)


def test_hmmlearn_views(written):
    loaded = load_demonstrations(written)
    X, lengths = loaded.movement_data()
    assert X.shape == (30 + 45 + 12, 18) and lengths.tolist() == [30, 45, 12]
    assert np.array_equal(X[:30], loaded[0].H.reshape(30, 18))
    X, lengths = loaded.object_data()
    assert X.shape == (87, 6) and lengths.sum() == len(X)


def test_layout_is_readable_without_this_package(written):
    with h5py.File(written, "r") as f:
        assert f.attrs["format"] == "hoap-actions-demonstrations" and f.attrs["format_version"] == 2
        assert list(f.attrs["marker_names"]) == list(MARKERS)
        assert f["episode_00000/H"].shape == (30, 6, 3) and f["episode_00000/O"].shape == (30, 6)
        assert f["episode_00000/ground_truth/labels"].shape == (30,)
        assert "rotvec" in f.attrs["rotation_convention"]


def test_refuses_to_overwrite(written, demos):
    with pytest.raises(DataExistsError, match="overwrite"):
        write_demonstrations(written, demos)
    assert write_demonstrations(written, demos, overwrite=True) == written


def test_interrupted_write_leaves_no_file(tmp_path, demos, monkeypatch):
    calls = []

    def failing(group, episode):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("disk on fire")
        return real(group, episode)

    real = datasets._write_episode
    monkeypatch.setattr(datasets, "_write_episode", failing)
    with pytest.raises(RuntimeError):
        write_demonstrations(tmp_path / "half.h5", demos)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "change",
    [
        lambda e: Episode(e.H[:, :5], e.O, e.ground_truth),
        lambda e: Episode(e.H, e.O[:-1], e.ground_truth),
        lambda e: Episode(np.where(np.arange(e.T)[:, None, None] == 3, np.nan, e.H), e.O, e.ground_truth),
    ],
    ids=["markers", "length", "nan"],
)
def test_writer_rejects_bad_episodes(tmp_path, demos, change):
    bad = Demonstrations((change(demos[0]),), 100.0, MARKERS, PHASES)
    with pytest.raises(InvalidInputError):
        write_demonstrations(tmp_path / "bad.h5", bad)
    assert not (tmp_path / "bad.h5").exists()


def test_missing_file(tmp_path):
    with pytest.raises(DataFileError, match="no demonstrations file"):
        load_demonstrations(tmp_path / "nothing.h5")


def test_truncated_file(written):
    data = written.read_bytes()
    written.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataFileError, match="truncated or corrupt"):
        load_demonstrations(written)


def test_corrupt_bytes(written):
    data = bytearray(written.read_bytes())
    rng = np.random.default_rng(1)
    start = len(data) // 4
    data[start : len(data) - 64] = rng.integers(0, 256, len(data) - 64 - start, dtype=np.uint8).tobytes()
    written.write_bytes(bytes(data))
    with pytest.raises(DataFileError):
        load_demonstrations(written)


def test_flipped_data_bytes_fail_the_checksum(written):
    with h5py.File(written, "r") as f:
        offset = f["episode_00001/H"].id.get_chunk_info(0).byte_offset
    data = bytearray(written.read_bytes())
    data[offset + 10] ^= 0xFF
    written.write_bytes(bytes(data))
    with pytest.raises(DataFileError, match="corrupt"):
        load_demonstrations(written)


def test_not_hdf5(tmp_path):
    path = tmp_path / "notes.h5"
    path.write_text("these are not demonstrations")
    with pytest.raises(DataFileError):
        load_demonstrations(path)


@pytest.mark.parametrize(
    "attr, value, message",
    [("format", "something-else", "format is"), ("format_version", 4, "format_version 4 is not supported")],
)
def test_wrong_format_or_version(written, attr, value, message):
    with h5py.File(written, "r+") as f:
        f.attrs[attr] = value
    with pytest.raises(DataFileError, match=message):
        load_demonstrations(written)


def _replace(path, name, data):
    with h5py.File(path, "r+") as f:
        del f[name]
        f.create_dataset(name, data=data)


def test_nan_in_file(written):
    with h5py.File(written, "r") as f:
        H = f["episode_00000/H"][()]
    H[5, 2, 1] = np.nan
    _replace(written, "episode_00000/H", H)
    with pytest.raises(DataFileError, match="NaN"):
        load_demonstrations(written)


@pytest.mark.parametrize(
    "name, shape, message",
    [
        ("episode_00000/H", (30, 5, 3), "H has shape"),
        ("episode_00000/O", (29, 6), "O has shape"),
        ("episode_00000/ground_truth/labels", (31,), "labels have shape"),
    ],
)
def test_wrong_shapes_in_file(written, name, shape, message):
    _replace(written, name, np.zeros(shape, dtype=np.int16 if "labels" in name else float))
    with pytest.raises(DataFileError, match=message):
        load_demonstrations(written)


def test_labels_outside_the_phase_table(written):
    _replace(written, "episode_00002/ground_truth/labels", np.full(12, 9, dtype=np.int16))
    with pytest.raises(DataFileError, match="phase table"):
        load_demonstrations(written)


def test_missing_array(written):
    with h5py.File(written, "r+") as f:
        del f["episode_00001/O"]
    with pytest.raises(DataFileError, match="episode_00001|corrupt"):
        load_demonstrations(written)


NOISE = {"marker_sd_m": 0.001, "skin_offset_sd_m": 0.0, "gap_rate_hz": 0.5, "gap_frames": [3, 5],
         "object_sd_m": 0.001, "object_sd_rad": 0.01}


def with_gap(demos: Demonstrations) -> Demonstrations:
    first = demos.episodes[0]
    H = first.H.copy()
    H[4:7, 2] = np.nan  # the wrist hidden for three frames
    return dataclasses.replace(demos, episodes=(dataclasses.replace(first, H=H), *demos.episodes[1:]),
                               noise=NOISE)


def test_an_exact_recording_is_version_2_and_a_noisy_one_version_3_with_its_noise_model(tmp_path, demos):
    exact = write_demonstrations(tmp_path / "exact.h5", demos)
    noisy = write_demonstrations(tmp_path / "noisy.h5", with_gap(demos))
    with h5py.File(exact) as f:
        assert f.attrs["format_version"] == 2 and "noise" not in f.attrs
    with h5py.File(noisy) as f:
        assert f.attrs["format_version"] == 3 and "noise" in f.attrs
    assert load_demonstrations(exact).exact
    loaded = load_demonstrations(noisy)
    assert not loaded.exact and loaded.has_gaps and loaded.noise == NOISE
    assert np.isnan(loaded[0].H[4:7, 2]).all() and np.isfinite(loaded[0].H[7:]).all()


def test_missing_markers_are_refused_where_the_recording_declares_no_gaps(tmp_path, demos):
    gappy = with_gap(demos)
    with pytest.raises(InvalidInputError, match="missing markers only in a recording whose noise model has occlusion"):
        write_demonstrations(tmp_path / "a.h5", dataclasses.replace(gappy, noise={}))
    path = write_demonstrations(tmp_path / "b.h5", gappy)
    with h5py.File(path, "r+") as f:
        del f.attrs["noise"]
        f.attrs["format_version"] = 2
    with pytest.raises(DataFileError, match="episode_00000: H frame 4 contains NaN"):
        load_demonstrations(path)


def test_a_marker_half_missing_too_many_gaps_or_a_bad_noise_model_are_named(tmp_path, demos):
    path = write_demonstrations(tmp_path / "c.h5", with_gap(demos))
    with h5py.File(path, "r+") as f:
        H = f["episode_00001/H"][()]
        H[3, 1, 0] = np.nan  # one coordinate of the elbow
        _replace(path, "episode_00001/H", H)
    with pytest.raises(DataFileError, match="episode_00001: H frame 3 has a marker with some coordinates missing"):
        load_demonstrations(path)
    path = write_demonstrations(tmp_path / "d.h5", with_gap(demos))
    H = load_demonstrations(path)[2].H
    H[:, :2] = np.nan  # shoulder and elbow never seen: a third of the marker frames
    _replace(path, "episode_00002/H", H)
    with pytest.raises(DataFileError, match="episode_00002: 33% of the marker frames are missing; accepted: at most "
                                            "20%"):
        load_demonstrations(path)
    path = write_demonstrations(tmp_path / "e.h5", with_gap(demos))
    with h5py.File(path, "r+") as f:
        f.attrs["noise"] = '{"marker_sd_m": -1}'
    with pytest.raises(DataFileError, match="attribute noise is not a motion-capture error model"):
        load_demonstrations(path)
