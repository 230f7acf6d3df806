"""Motion-capture noise in recordings, and the cleaning that discovery and learning apply to it."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.demonstration.mocap import NOISE_MODELS, MocapNoise, add_mocap_noise, parse_noise
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.pipelines.mocap_cleaning import (
    NOISE_FLOOR_M,
    NoiseAboveDeclaredWarning,
    clean_demonstrations,
    fill_gaps,
    lowpass,
    measured_jitter,
)

FPS = 100.0


def test_noise_models_by_name_or_magnitudes():
    assert parse_noise("none").exact and not parse_noise("mocap").exact
    noise = parse_noise("marker=1,object=2,angle=1,gaps=0.5,skin=5")
    assert noise == MocapNoise(marker_sd_m=0.001, skin_offset_sd_m=0.005, gap_rate_hz=0.5, object_sd_m=0.002,
                               object_sd_rad=math.radians(1.0))
    assert MocapNoise.from_dict(noise.to_dict()) == noise


@pytest.mark.parametrize("spec", ["loud", "marker=x", "marker=1,volume=2", "marker=-1", "marker=80", "angle=nan"])
def test_a_bad_noise_model_says_what_is_accepted(spec):
    with pytest.raises(InvalidInputError, match="none|must be a number|not a number"):
        parse_noise(spec)


def test_noise_has_the_declared_magnitudes_and_gaps_are_whole_markers():
    T = 20000
    H = np.zeros((T, 6, 3))
    O = np.tile([0.1, 0.2, 0.03, 0.0, 0.0, 0.3], (T, 1))
    noise = MocapNoise(marker_sd_m=0.001, gap_rate_hz=0.2, gap_frames=(3, 15), object_sd_m=0.0005,
                       object_sd_rad=math.radians(1.0))
    noisy_H, noisy_O = add_mocap_noise(H, O, noise, FPS, seed=3, index=0)
    seen = np.isfinite(noisy_H)
    assert (seen.all(axis=2) | ~seen.any(axis=2)).all()  # a marker is missing as a whole
    # gaps start 0.2 times a second per marker and last 9 frames on average (overlaps aside)
    assert 0.8 * 0.2 * 9 / FPS < 1 - seen[..., 0].mean() < 1.2 * 0.2 * 9 / FPS
    assert np.nanstd(noisy_H) == pytest.approx(0.001, rel=0.05)
    assert np.std(noisy_O[:, :3] - O[:, :3]) == pytest.approx(0.0005, rel=0.05)
    tilt = (Rotation.from_rotvec(noisy_O[:, 3:]) * Rotation.from_rotvec(O[:, 3:]).inv()).magnitude()
    assert np.sqrt(np.mean(tilt**2)) == pytest.approx(math.radians(1.0), rel=0.05)  # the angle about a random axis


def test_noise_is_seeded_and_skin_offsets_are_shared_by_a_recordings_episodes():
    H, O = np.zeros((50, 6, 3)), np.zeros((50, 6))
    skin = MocapNoise(skin_offset_sd_m=0.005)
    a, _ = add_mocap_noise(H, O, skin, FPS, seed=1, index=0)
    b, _ = add_mocap_noise(H, O, skin, FPS, seed=1, index=7)
    c, _ = add_mocap_noise(H, O, skin, FPS, seed=2, index=0)
    assert np.array_equal(a, b) and not np.allclose(a, c)
    assert np.ptp(a, axis=0).max() == 0.0  # an offset, not jitter
    jitter = NOISE_MODELS["mocap"]
    first = add_mocap_noise(H, O, jitter, FPS, seed=1, index=0)
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip(first, add_mocap_noise(H, O, jitter, FPS, 1, 0)))
    assert not np.allclose(first[1], add_mocap_noise(H, O, jitter, FPS, 1, 1)[1])
    assert all(np.array_equal(x, y) for x, y in zip((H, O), add_mocap_noise(H, O, MocapNoise(), FPS, 1, 0)))


def test_fill_gaps_bridges_linearly_and_holds_the_ends():
    H = np.zeros((6, 2, 3))
    H[:, 0, 0] = [np.nan, 1.0, np.nan, np.nan, 4.0, np.nan]
    H[np.isnan(H[:, 0, 0]), 0] = np.nan
    filled = fill_gaps(H)
    np.testing.assert_allclose(filled[:, 0, 0], [1.0, 1.0, 2.0, 3.0, 4.0, 4.0])
    np.testing.assert_array_equal(filled[:, 1], 0.0)
    H[:, 1] = np.nan
    with pytest.raises(InvalidInputError, match="marker 1 is missing in every frame"):
        fill_gaps(H)


def test_lowpass_keeps_slow_movement_without_lag_and_removes_jitter():
    t = np.arange(2000) / FPS
    slow = 0.05 * np.sin(2 * np.pi * 0.5 * t)  # a 2 s back-and-forth
    jitter = np.random.default_rng(0).normal(0.0, 0.001, t.size)
    smoothed = lowpass((slow + jitter)[:, None], FPS)[:, 0]
    assert np.abs(lowpass(slow[:, None], FPS)[:, 0] - slow)[100:-100].max() < 1e-4  # no lag, no loss
    assert np.std(smoothed - slow) < 0.4 * 0.001  # the 6 Hz filter keeps about 0.35 of white noise at 100 Hz
    with pytest.raises(InvalidInputError, match="below the Nyquist"):
        lowpass(slow[:, None], FPS, cutoff_hz=60.0)


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    from hoap_actions.demonstration.recording import record

    folder = tmp_path_factory.mktemp("mocap")
    exact = load_demonstrations(record("small", folder / "exact.h5", seed=4, progress=False))
    noisy = load_demonstrations(record("small", folder / "noisy.h5", seed=4, progress=False, noise="mocap"))
    return exact, noisy


def test_a_noisy_recording_is_its_exact_twin_plus_the_declared_noise(recordings):
    exact, noisy = recordings
    assert exact.exact and exact.noise == {}
    assert noisy.noise == NOISE_MODELS["mocap"].to_dict()
    for a, b in zip(exact, noisy):
        assert np.array_equal(a.Q, b.Q) and np.array_equal(a.ground_truth.labels, b.ground_truth.labels)
        residual = b.O[:, :3] - a.O[:, :3]
        assert 0.0 < np.std(residual) < 0.002
        offset = np.nanmean(b.H - a.H, axis=0)  # the skin offsets: the same in every episode
        np.testing.assert_allclose(offset, np.nanmean(noisy[0].H - exact[0].H, axis=0), atol=0.001)


def test_cleaning_a_noisy_recording_brings_it_back_near_the_exact_one(recordings):
    exact, noisy = recordings
    assert clean_demonstrations(exact) is exact  # exact data pass unchanged
    with warnings.catch_warnings():
        warnings.simplefilter("error", NoiseAboveDeclaredWarning)  # noise as declared: no warning
        cleaned = clean_demonstrations(noisy)
    for a, b, c in zip(exact, noisy, cleaned):
        assert np.isfinite(c.H).all()
        raw = np.sqrt(np.mean((b.O[:, :3] - a.O[:, :3]) ** 2))
        assert np.sqrt(np.mean((c.O[:, :3] - a.O[:, :3]) ** 2)) < 0.6 * raw


def test_a_recording_noisier_than_declared_is_named(recordings):
    _, noisy = recordings
    rng = np.random.default_rng(0)
    louder = tuple(dataclasses.replace(e, O=e.O + np.hstack([rng.normal(0, 0.005, (e.T, 3)), np.zeros((e.T, 3))]))
                   for e in noisy)
    with pytest.warns(NoiseAboveDeclaredWarning, match="episode 0: the object jitters by"):
        clean_demonstrations(dataclasses.replace(noisy, episodes=louder))


def test_record_command_takes_a_noise_model(tmp_path, capsys):
    from hoap_actions.apps.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["record", "--preset", "small", "--out", str(tmp_path / "x.h5"), "--noise", "loud"])
    assert exit_info.value.code == 2 and "unknown noise model 'loud'" in capsys.readouterr().err
    assert not (tmp_path / "x.h5").exists()


def test_noise_nobody_declared_is_measured_and_cleaned(small_demos):
    """An exact recording passes unchanged; the same with 1 mm / 1 degree added after recording (the file
    still says exact) is measured as noisy, cleaned, and a warning says so."""
    assert small_demos.exact and measured_jitter(small_demos) < NOISE_FLOOR_M
    assert clean_demonstrations(small_demos) is small_demos
    noise = parse_noise("marker=1,object=1,angle=1")
    episodes = []
    for i, e in enumerate(small_demos.episodes):
        H, O = add_mocap_noise(e.H, e.O, noise, small_demos.fps, 99, i)
        episodes.append(dataclasses.replace(e, H=H, O=O))
    noisy = dataclasses.replace(small_demos, episodes=tuple(episodes))
    assert noisy.exact and measured_jitter(noisy) > 2 * NOISE_FLOOR_M
    with pytest.warns(NoiseAboveDeclaredWarning, match="declares no noise"):
        cleaned = clean_demonstrations(noisy)
    assert measured_jitter(cleaned) < NOISE_FLOOR_M / 2
    for clean, raw, truth in zip(cleaned.episodes, noisy.episodes, small_demos.episodes):
        assert np.abs(clean.O[:, :3] - truth.O[:, :3]).mean() < np.abs(raw.O[:, :3] - truth.O[:, :3]).mean()
