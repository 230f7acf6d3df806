"""The fingertip detector: its windows and features, what it learns, its file, and the shipped one on new frames."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import DataExistsError, DataFileError, InvalidInputError, NotFittedError
from hoap_actions.tracking.fingertip_training import fingertip_windows
from hoap_actions.vision.fingertip import (
    WINDOW_HALF_PX,
    FingertipDetector,
    shipped_fingertip_detector,
    window_features,
    windows,
)

SIDE = 2 * WINDOW_HALF_PX


def test_windows_are_the_image_about_their_centres_with_the_border_repeated():
    image = np.arange(60 * 80 * 3, dtype=np.int64).reshape(60, 80, 3) % 251
    image = image.astype(np.uint8)
    inside = windows(image, np.array([[40.2, 30.4]]))[0]
    np.testing.assert_array_equal(inside, image[30 - WINDOW_HALF_PX:30 + WINDOW_HALF_PX,
                                                40 - WINDOW_HALF_PX:40 + WINDOW_HALF_PX])
    corner = windows(image, np.array([[0.0, 0.0]]))[0]
    np.testing.assert_array_equal(corner[:WINDOW_HALF_PX, :WINDOW_HALF_PX], np.broadcast_to(image[0, 0], (24, 24, 3)))
    with pytest.raises(InvalidInputError, match="uint8"):
        windows(image.astype(float), np.zeros((1, 2)))
    with pytest.raises(InvalidInputError, match="finite"):
        windows(image, np.array([[np.nan, 3.0]]))


def test_features_see_an_edge_s_orientation_and_nothing_in_a_flat_window():
    flat = np.full((1, SIDE, SIDE, 3), 120.0)
    assert np.all(window_features(flat) == 0.0)
    vertical = flat.copy()
    vertical[:, :, SIDE // 2:] = 200.0  # a vertical edge: a horizontal gradient, orientation 0
    horizontal = np.swapaxes(vertical, 1, 2)
    f_vertical, f_horizontal = window_features(vertical)[0], window_features(horizontal)[0]
    bins = 9
    by_bin_v = f_vertical[: f_vertical.size // 2].reshape(-1, bins).sum(axis=0)
    by_bin_h = f_horizontal[: f_horizontal.size // 2].reshape(-1, bins).sum(axis=0)
    assert np.argmax(by_bin_v) == 0 and np.argmax(by_bin_h) == bins // 2  # 0 and pi/2
    with pytest.raises(InvalidInputError, match="windows"):
        window_features(np.zeros((2, 10, 10, 3)))


def _dots(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Grey windows with a skin-coloured disc (radius 4 px) at a random offset from the centre."""
    rng = np.random.default_rng(seed)
    offsets = rng.uniform(-12, 12, (n, 2))
    rows, cols = np.mgrid[0:SIDE, 0:SIDE]
    crops = np.full((n, SIDE, SIDE, 3), 90.0, np.float32)
    for crop, (du, dv) in zip(crops, offsets):
        disc = (cols - (WINDOW_HALF_PX + du)) ** 2 + (rows - (WINDOW_HALF_PX + dv)) ** 2 <= 16
        crop[disc] = (220.0, 180.0, 150.0)
    return crops, offsets


def test_the_detector_learns_where_a_dot_is():
    """A known answer: a disc's place in its window, learned from 1500 windows, within a few pixels on 300 others
    (predicting the centre would be 8 px off on average)."""
    crops, offsets = _dots(1500, 0)
    detector = FingertipDetector(hidden=(64,), epochs=30, random_state=0).fit(crops, offsets)
    test_crops, test_offsets = _dots(300, 1)
    error = np.linalg.norm(detector.predict(test_crops) - test_offsets, axis=1)
    assert np.median(error) < 2.5 < 8.0 < np.mean(np.linalg.norm(test_offsets, axis=1)) + 1.0
    again = FingertipDetector(hidden=(64,), epochs=30, random_state=0).fit(crops, offsets)
    np.testing.assert_array_equal(again.predict(test_crops), detector.predict(test_crops))  # seeded
    image = np.full((100, 120, 3), 90, np.uint8)
    image[(np.mgrid[0:100, 0:120][0] - 40) ** 2 + (np.mgrid[0:100, 0:120][1] - 60) ** 2 <= 16] = (220, 180, 150)
    found = detector.locate(image, np.array([[55.0, 45.0]]))[0]
    assert np.linalg.norm(found - [60, 40]) < 3.0


def test_a_saved_detector_loads_to_the_same_predictions_and_bad_files_are_refused(tmp_path):
    crops, offsets = _dots(200, 2)
    detector = FingertipDetector(hidden=(16,), epochs=2).fit(crops, offsets)
    path = detector.save(tmp_path / "tip.npz")
    np.testing.assert_array_equal(FingertipDetector.load(path).predict(crops), detector.predict(crops))
    with pytest.raises(DataExistsError):
        detector.save(path)
    (tmp_path / "bad.npz").write_bytes(b"not a detector")
    with pytest.raises(DataFileError):
        FingertipDetector.load(tmp_path / "bad.npz")
    np.savez(tmp_path / "short.npz", format_version=np.array(1))
    with pytest.raises(DataFileError, match="lacks"):
        FingertipDetector.load(tmp_path / "short.npz")
    with pytest.raises(NotFittedError):
        FingertipDetector().predict(crops)
    with pytest.raises(InvalidInputError, match="epochs"):
        FingertipDetector(epochs=0).fit(crops, offsets)
    with pytest.raises(InvalidInputError, match="offsets"):
        FingertipDetector().fit(crops, offsets[:5])


def test_the_shipped_detector_finds_the_fingertip_nearer_than_its_guess_on_recordings_it_never_saw(small_demos):
    """The `small` preset's frames (never trained on), windows about the true tip moved 2 cm: the shipped detector's
    finding is nearer the true tip than the window's centre in most windows and on average."""
    crops, offsets = fingertip_windows(small_demos, every=25, spread_m=0.02, seed=5)
    found = shipped_fingertip_detector().predict(crops)
    error, guess = np.linalg.norm(found - offsets, axis=1), np.linalg.norm(offsets, axis=1)
    assert len(crops) > 40
    assert np.median(error) < 0.7 * np.median(guess) and np.mean(error < guess) > 0.7


def test_the_shipped_detector_is_the_file_its_provenance_names():
    import hashlib
    import json
    from pathlib import Path

    import hoap_actions.vision.fingertip as module
    from hoap_actions.tracking.fingertip_training import TRAINING_SEEDS

    folder = Path(module.__file__).parent
    provenance = json.loads((folder / "fingertip_detector.json").read_text())
    assert provenance["sha256"] == hashlib.sha256((folder / "fingertip_detector.npz").read_bytes()).hexdigest()
    assert provenance["seeds"] == list(TRAINING_SEEDS) and provenance["samples"] > 10_000


def test_building_the_detector_refuses_an_existing_output_before_any_work(tmp_path):
    from hoap_actions.errors import DataExistsError
    from hoap_actions.tracking.fingertip_training import build_fingertip_detector

    (tmp_path / "tip.json").write_text("{}")
    with pytest.raises(DataExistsError, match="overwrite"):
        build_fingertip_detector(tmp_path / "no-recordings-here", tmp_path / "tip.npz")
    assert not (tmp_path / "no-recordings-here").exists()  # nothing recorded
