"""Tracking a recorded episode from the demonstration camera: the pipeline and its scores."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.demonstration.recording import record
from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA
from hoap_actions.errors import InvalidInputError
from hoap_actions.models.shipped import load_default_models
from hoap_actions.tracking import track_episode, track_markers_episode, tracking_video_frames
from hoap_actions.vision.body_model import BodyModel

SHORT_FRAMES = 145  # episode 3's approach (frames 0-138) and the start of its remove
TINY_FRAMES = 40  # the start of episode 3's approach: enough for the command's plumbing


@pytest.fixture(scope="module")
def small(small_demos):
    return small_demos


def _cut(demos, frames=SHORT_FRAMES):
    """``demos`` with episode 3 cut to its first ``frames`` frames."""
    episode = demos[3]
    truth = dataclasses.replace(episode.ground_truth, labels=episode.ground_truth.labels[:frames])
    cut = dataclasses.replace(episode, H=episode.H[:frames], O=episode.O[:frames], Q=episode.Q[:frames],
                              ground_truth=truth)
    return dataclasses.replace(demos, episodes=(*demos.episodes[:3], cut))


@pytest.fixture(scope="module")
def short(small_demos):
    """The small recording with episode 3 cut to its approach and the start of its remove: the tests that
    track it from images check a tracked episode's shape, its determinism and the plumbing, not its scores."""
    return _cut(small_demos)


@pytest.fixture(scope="module")
def tiny(small_demos):
    """The small recording with episode 3 cut to the first :data:`TINY_FRAMES` frames of its approach."""
    return _cut(small_demos, TINY_FRAMES)


def test_tracks_an_episode_from_rendered_frames(short):
    models = load_default_models()
    episode = 3  # the small preset's bare approach, cut
    result = track_episode(models, short, episode, particles=50, seed=0)
    summary = result.summary()
    T = short[episode].T
    assert summary["frames"] == T == len(summary["recognized"]) == len(summary["truth"])
    assert set(summary["rms_m"]) == {"shoulder", "elbow", "index_tip"}
    # the shoulder hardly moves and the torso is big in the image: it is found within a few cm
    assert summary["rms_m"]["shoulder"] < 0.05
    assert 0.0 < summary["rms_m_all"] < 0.5 and summary["hz"] > 0
    assert summary["approaches"] == 1 and summary["cues"] == ["edges", "silhouette"]
    filmed = track_episode(models, short, episode, particles=50, seed=0, keep_images=True)
    again = filmed.summary()  # the same seed gives the same track, filmed or not
    assert again["rms_m_all"] == summary["rms_m_all"] and again["recognized"] == summary["recognized"]
    body = BodyModel(models.marker_names_, torso_base=filmed.torso_base)
    frames = tracking_video_frames(filmed, body, every=4)
    assert len(frames) == -(-T // 4) and frames[0].shape == (240, 640, 3) and frames[0].dtype == np.uint8
    assert len({frame.tobytes() for frame in frames}) > len(frames) // 2  # the picture moves


def test_several_views_are_scored_together(short):
    """Eq. (9): a second camera's edge image joins the first's; the track stays as good on the trunk."""
    from hoap_actions.envs.camera import Camera

    side = Camera(eye=(-0.2, -0.9, 0.45), target=(-0.30, 0.0, 0.10), fov_deg=55.0, width=160, height=120)
    summary = track_episode(load_default_models(), short, 3, particles=50, seed=0, more_cameras=(side,)).summary()
    assert summary["rms_m"]["shoulder"] < 0.05 and summary["frames"] == short[3].T


def test_clutter_and_image_noise_are_part_of_the_seeded_episode(short):
    models = load_default_models()
    camera = dataclasses.replace(DEMONSTRATOR_CAMERA, width=160, height=120)  # determinism needs no detail
    runs = [track_episode(models, short, 3, particles=50, seed=2, camera=camera, clutter=True,
                          image_noise=0.03).summary() for _ in range(2)]
    assert runs[0]["rms_m_all"] == runs[1]["rms_m_all"] and runs[0]["recognized"] == runs[1]["recognized"]
    clean = track_episode(models, short, 3, particles=50, seed=2, camera=camera).summary()
    assert clean["rms_m_all"] != runs[0]["rms_m_all"]  # the noise and clutter reach the filter
    with pytest.raises(InvalidInputError, match="image_noise must be"):
        track_episode(models, short, 3, image_noise=-0.1)


def test_a_depth_camera_is_part_of_the_seeded_episode_and_reaches_the_estimate(short):
    from hoap_actions.vision.depth_sensor import DepthSensor

    models = load_default_models()
    camera = dataclasses.replace(DEMONSTRATOR_CAMERA, width=160, height=120)
    runs = [track_episode(models, short, 3, particles=50, seed=2, camera=camera,
                          depth_sensor=DepthSensor()).summary() for _ in range(2)]
    assert runs[0]["rms_m_all"] == runs[1]["rms_m_all"] and runs[0]["recognized"] == runs[1]["recognized"]
    colour = track_episode(models, short, 3, particles=50, seed=2, camera=camera).summary()
    assert colour["rms_m_all"] != runs[0]["rms_m_all"]  # the depth images reach the pose estimate


def test_the_refined_estimate_is_seeded_moves_only_the_pose_and_refuses_bad_settings(short):
    """With ``refine``, the smoothed estimates are also refined against their frame's images: the same seed gives the
    same poses, the filter and its smoothed estimates are as without it, and the arm moves where the images say
    (within a few centimetres of the unrefined estimate)."""
    models = load_default_models()
    camera = dataclasses.replace(DEMONSTRATOR_CAMERA, width=160, height=120)
    plain = track_episode(models, short, 3, particles=50, seed=2, camera=camera, lag=5)
    runs = [track_episode(models, short, 3, particles=50, seed=2, camera=camera, lag=5, refine={"samples": 16})
            for _ in range(2)]
    poses = [np.stack([f.markers for f in run.refined]) for run in runs]
    np.testing.assert_array_equal(poses[0], poses[1])
    unrefined = np.stack([f.markers for f in plain.smoothed])
    np.testing.assert_array_equal(np.stack([f.markers for f in runs[0].smoothed]), unrefined)  # the filter as it was
    assert [f.class_id for f in runs[0].refined] == [f.class_id for f in plain.smoothed] and not plain.refined
    moved = np.linalg.norm(poses[0] - unrefined, axis=2)
    assert moved.max() > 0.001 and np.median(moved) < 0.05
    summary = runs[0].summary()
    assert summary["refined"]["hz"] < summary["hz"] and set(summary["refined"]["rms_m"]) == set(summary["rms_m"])
    with pytest.raises(InvalidInputError, match="prior_sd"):
        track_episode(models, short, 3, particles=50, camera=camera, refine={"prior_sd": (0.0, 0.1, 0.1)})
    with pytest.raises(InvalidInputError, match="refine takes a mapping of"):
        track_episode(models, short, 3, particles=50, camera=camera, refine={"sharpness": 2})


def test_refuses_what_it_cannot_track(small):
    models = load_default_models()
    bare = dataclasses.replace(small, joint_names=(), episodes=tuple(dataclasses.replace(e, Q=None) for e in small))
    with pytest.raises(InvalidInputError, match="no joint angles"):
        track_episode(models, bare, 0)
    with pytest.raises(InvalidInputError, match=r"episode must be in \[0, 3\]"):
        track_episode(models, small, 4)
    with pytest.raises(InvalidInputError, match="n_particles"):
        track_episode(models, small, 0, particles=0)


def test_track_command_writes_the_figures_and_explains_mistakes(tiny, tmp_path, capsys):
    from hoap_actions.apps.cli import main
    from hoap_actions.demonstration.datasets import write_demonstrations

    path = tmp_path / "tiny.h5"
    write_demonstrations(path, tiny)
    out = tmp_path / "track.json"
    assert main(["track", "--demos", str(path), "--episode", "3", "--particles", "50", "--json", str(out),
                 "--figure", str(tmp_path / "fig11.png")]) == 0
    report = json.loads(out.read_text())
    assert {"rms_m", "rms_m_all", "hz", "particles", "frames", "phi_error_m", "frames_to_converge", "recognized",
            "truth"} <= set(report)
    assert report["particles"] == 50 and len(report["recognized"]) == report["frames"] == tiny[3].T
    assert (tmp_path / "fig11.png").stat().st_size > 0
    assert report["cues"] == ["edges", "silhouette"] and report["views"] == 1
    edges_only = tmp_path / "edges.json"
    assert main(["track", "--demos", str(path), "--episode", "3", "--particles", "50", "--edges-only",
                 "--side-camera", "--refine", "--fingertip", "--json", str(edges_only)]) == 0
    two_views = json.loads(edges_only.read_text())
    assert two_views["cues"] == ["edges"] and two_views["views"] == 2
    assert two_views["refine"] and two_views["fingertip"]
    assert set(two_views["refined"]["rms_m"]) == set(two_views["rms_m"])
    assert "refined against each frame's images" in capsys.readouterr().out
    assert main(["track", "--demos", str(path), "--episode", "3", "--json", str(out)]) == 2  # exists: not replaced
    assert main(["track", "--demos", str(path), "--episode", "9"]) == 2
    assert main(["track", "--demos", str(path), "--episode", "3", "--fingertip"]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert len(errors) == 3 and "episode must be in [0, 3]" in errors[1]
    assert "--fingertip goes with --refine" in errors[2]


def test_a_noisy_recording_with_gaps_is_tracked_against_its_bridged_markers(tmp_path):
    noisy = _cut(load_demonstrations(record("small", tmp_path / "noisy.h5", seed=0, progress=False,
                                            noise="marker=1,gaps=2,object=1,angle=1")), TINY_FRAMES)
    assert np.isnan(noisy[3].H).any()  # markers missing in some frames
    summary = track_episode(load_default_models(), noisy, 3, particles=50, seed=0).summary()
    assert np.isfinite(summary["rms_m_all"]) and summary["rms_m"]["shoulder"] < 0.05


def test_tracks_from_the_recorded_markers_and_block(small, tmp_path, capsys):
    """Recognition from motion capture: on the push, the pose is a small share of the arm's motion, the
    kind of primitive is right on most frames, and a frame whose class is right has the right kind; the
    command writes the same report and refuses image options."""
    from hoap_actions.apps.cli import main
    from hoap_actions.demonstration.datasets import write_demonstrations

    models = load_default_models()
    result = track_markers_episode(models, small, 0, particles=100, seed=0)
    summary = result.summary()
    held = np.sqrt(np.mean(np.linalg.norm(result.truth_markers[:1] - result.truth_markers, axis=2) ** 2))
    assert summary["rms_m_all"] < 0.15 * held
    assert summary["kind_accuracy"] > 0.8 and summary["kind_accuracy"] >= summary["frame_accuracy"]
    known = result.truth_classes != -1
    kind = {cid: c.kind for cid, c in models.classes_.items()}
    recognized = np.array(summary["recognized"])[known]
    assert summary["kind_accuracy"] == pytest.approx(np.mean([kind[a] == kind[b] for a, b in
                                                              zip(recognized, result.truth_classes[known])]))
    assert dataclasses.replace(result, kinds={}).summary()["kind_accuracy"] is None  # no kinds: no figure, not 100 %
    assert summary["cues"] == ["markers"] and summary["views"] == 0
    path = tmp_path / "small.h5"
    write_demonstrations(path, small)
    out = tmp_path / "markers.json"
    assert main(["track", "--demos", str(path), "--episode", "0", "--particles", "100", "--from-markers",
                 "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["rms_m_all"] == summary["rms_m_all"] and report["recognized"] == summary["recognized"]
    assert main(["track", "--demos", str(path), "--from-markers", "--video", str(tmp_path / "v.mp4")]) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "--from-markers tracks without images" in error and not (tmp_path / "v.mp4").exists()
    assert main(["track", "--demos", str(path), "--from-markers", "--depth"]) == 2
    assert "--depth" in capsys.readouterr().err.strip().splitlines()[-1]
    smoothed = tmp_path / "smoothed.json"
    assert main(["track", "--demos", str(path), "--episode", "0", "--particles", "100", "--from-markers", "--lag",
                 "10", "--json", str(smoothed)]) == 0
    lagged = json.loads(smoothed.read_text())
    assert lagged["rms_m_all"] == summary["rms_m_all"]  # the filter is the same run; smoothing is read beside it
    assert lagged["smoothed"]["lag"] == 10 and len(lagged["smoothed"]["recognized"]) == result.truth_markers.shape[0]
    assert np.isfinite(lagged["smoothed"]["rms_m_all"]) and lagged["smoothed"]["rms_m_all"] != summary["rms_m_all"]
    assert main(["track", "--demos", str(path), "--from-markers", "--lag", "-1"]) == 2
    assert "--lag must be 0.." in capsys.readouterr().err.strip().splitlines()[-1]


def test_pose_floor_agrees_with_the_phmm_synthesized_path(short):
    """The floor's best phase per frame, cross-checked against the PHMM's own synthesis: the path through the
    state means at the segment's effect, sampled densely, comes as close to each frame within a few mm."""
    import warnings

    from hoap_actions.primitives.discovery.estimator import UNKNOWN
    from hoap_actions.primitives.labels import runs
    from hoap_actions.tracking import pose_floor

    models = load_default_models()
    episode = 3  # the bare approach, cut: its approach and the start of its remove
    floor = pose_floor(models, short, episode)
    fitted = pose_floor(models, short, episode, fit_effect=True)
    H = short[episode].H
    truth = models.discovery_.predict(short[episode].O, [short[episode].T])[0]
    width, hand = 3 * len(models.marker_names_), models.discovery_.hand_marker
    checked = improved = 0
    for cid, start, end in runs(truth):
        if cid == UNKNOWN:
            assert np.all(np.isnan(floor[start:end]))
            continue
        model = models.classes_[cid]
        assert model.kind != "manipulation"  # the bare approach's pieces: the hand's start and end are the effect
        phi = np.r_[H[start, hand], H[end - 1, hand]]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            path = model.phmm.synthesize((phi - model.centre) @ model.basis, n_frames=4000)[:, :width]
        path = path.reshape(len(path), -1, 3)
        d = np.linalg.norm(path[None] - H[start:end, None], axis=3)
        dense = d[np.arange(end - start), np.argmin(np.mean(d**2, axis=2), axis=1)]
        rms = lambda x: np.sqrt(np.mean(x**2, axis=1))  # noqa: E731  (a one-line local function)
        assert np.max(np.abs(rms(floor[start:end]) - rms(dense))) < 0.002  # the same polyline, sampled apart
        assert np.mean(fitted[start:end] ** 2) <= np.mean(floor[start:end] ** 2)  # a fitted effect never does worse
        improved += np.mean(fitted[start:end] ** 2) < np.mean(floor[start:end] ** 2)
        checked += 1
    assert checked >= 1
    assert improved >= 1  # the fit moves the effect: some segment comes closer than at its true effect
    with pytest.raises(InvalidInputError, match="phases"):
        pose_floor(models, small, episode, phases=1)
