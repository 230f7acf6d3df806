"""Fixed-lag smoothing by the particles' lineage: known answers, an independent ancestry walk, and the tracker's
smoothed estimates beside its unchanged filter; the pose estimate's sharpened weights."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA as CAMERA
from hoap_actions.errors import InvalidInputError
from hoap_actions.models.shipped import load_default_models
from hoap_actions.tracking.action_tracker import ActionTracker
from hoap_actions.tracking.smoothing import MAX_LAG, ParticleLineage, tilted
from hoap_actions.vision.body_model import BodyModel

TORSO_BASE = np.array([-0.47, 0.25, -0.10])  # about where the demonstration scene's lumbar joint is


def test_a_frame_is_read_with_the_weights_of_the_frame_lag_after_it_through_its_ancestors():
    """Known answer: two particles, lag 1. After frame 1 particle 0 and 1 both descend from particle 1 of
    frame 0, so frame 0's estimate is particle 1's pose whatever frame 1's weights."""
    lineage = ParticleLineage(lag=1)
    poses0 = np.array([[[0.0, 0.0, 0.0]], [[1.0, 2.0, 3.0]]])
    assert lineage.push(0, poses0, np.array([5, 7]), np.array([0.5, 0.5])) == []
    lineage.resampled(np.array([1, 1]))
    (frame0,) = lineage.push(1, poses0 + 10.0, np.array([7, 7]), np.array([0.25, 0.75]))
    assert frame0.frame == 0 and frame0.class_id == 7
    np.testing.assert_allclose(frame0.markers, [[1.0, 2.0, 3.0]])
    assert frame0.class_probabilities == {7: 1.0}
    (frame1,) = lineage.flush(np.array([0.25, 0.75]))
    np.testing.assert_allclose(frame1.markers, 0.25 * poses0[0] + 0.75 * poses0[1] + 10.0)
    assert lineage.flush(np.array([0.5, 0.5])) == []


def test_the_lineage_agrees_with_a_walk_back_through_every_resampling():
    """Cross-check against an independent ancestry walk: random poses, classes, resamplings and weights; each
    frame's estimate is the weighted mean over today's particles of the pose their ancestor had then."""
    rng = np.random.default_rng(4)
    n, frames, lag = 30, 40, 7
    lineage = ParticleLineage(lag)
    poses, classes, weights, ancestry = [], [], [], []  # ancestry[t]: who particle i of frame t+1 copied
    smoothed = []
    for t in range(frames):
        poses.append(rng.normal(size=(n, 2, 3)))
        classes.append(rng.integers(0, 3, n))
        weights.append(rng.dirichlet(np.ones(n)))
        smoothed += lineage.push(t, poses[t], classes[t], weights[t])
        if t < frames - 1:  # the last frame's weights read what is left: no resampling after it
            index = rng.integers(0, n, n) if rng.random() < 0.5 else np.arange(n)
            lineage.resampled(index)
            ancestry.append(index)
    smoothed += lineage.flush(weights[-1])
    assert [s.frame for s in smoothed] == list(range(frames))
    for t, estimate in enumerate(smoothed):
        later = min(t + lag, frames - 1)
        who = np.arange(n)
        for k in range(later - 1, t - 1, -1):  # particle i at `later` descends from who[i] at t
            who = ancestry[k][who]
        np.testing.assert_allclose(estimate.markers, np.einsum("n,nmk->mk", weights[later], poses[t][who]))
        expected = np.bincount(classes[t][who], weights[later], minlength=3)
        for cid, p in estimate.class_probabilities.items():
            assert p == pytest.approx(expected[cid])


@pytest.fixture(scope="module")
def models():
    return load_default_models()


def test_smoothing_leaves_the_filter_as_it_was_and_reads_every_frame_once(models):
    """The same seed with and without a lag: the filter's frames bit for bit equal; the smoothed estimates
    come one per frame, in order; with lag 0 each is the filter's own estimate of its frame."""
    body = BodyModel(models.marker_names_, TORSO_BASE)
    rng = np.random.default_rng(0)
    observed = TORSO_BASE + np.array([0.2, -0.1, 0.1]) + rng.normal(0.0, 0.05, (30, 6, 3))
    runs = {}
    for lag in (0, 5):
        tracker = ActionTracker(models, body, CAMERA, n_particles=60, random_state=2, lag=lag)
        frames = [tracker.step_markers(pose) for pose in observed]
        runs[lag] = (frames, tracker.smoothed_frames(final=True))
    for filtered, plain in zip(runs[5][0], runs[0][0]):
        np.testing.assert_array_equal(filtered.markers, plain.markers)
    for _, smoothed in runs.values():
        assert [s.frame for s in smoothed] == list(range(len(observed)))
    for frame, estimate in zip(runs[0][0], runs[0][1]):
        np.testing.assert_allclose(estimate.markers, frame.markers)
        assert estimate.class_probabilities == pytest.approx(frame.class_probabilities)
    assert any(not np.allclose(a.markers, b.markers) for a, b in zip(runs[5][1], runs[0][1]))


def test_smoothed_frames_are_handed_out_once_and_reset_starts_counting_again(models):
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=20, random_state=0, lag=3)
    pose = np.tile(TORSO_BASE, (6, 1))
    for _ in range(5):
        tracker.step_markers(pose)
    assert [s.frame for s in tracker.smoothed_frames()] == [0, 1]
    assert tracker.smoothed_frames() == []
    assert [s.frame for s in tracker.smoothed_frames(final=True)] == [2, 3, 4]
    tracker.reset()
    tracker.step_markers(pose)
    assert [s.frame for s in tracker.smoothed_frames(final=True)] == [0]


def test_lag_bad_input(models):
    body = BodyModel(models.marker_names_, TORSO_BASE)
    for bad in (-1, MAX_LAG + 1, 2.5, True):
        with pytest.raises(InvalidInputError, match="lag"):
            ActionTracker(models, body, CAMERA, lag=bad)
    plain = ActionTracker(models, body, CAMERA, n_particles=5)  # no lag: no lineage kept, nothing to hand out
    plain.step_markers(np.tile(TORSO_BASE, (6, 1)))
    with pytest.raises(InvalidInputError, match="no lineage"):
        plain.smoothed_frames(final=True)


def test_tilted_weights_are_the_weights_times_the_exponential_tilt_normalised():
    weights = np.array([0.5, 0.5, 0.0])
    np.testing.assert_allclose(tilted(weights, np.array([0.0, np.log(3.0), 5.0])), [0.25, 0.75, 0.0])
    assert tilted(weights, None) is weights
    np.testing.assert_allclose(tilted(weights, np.zeros(3)), weights)
    nothing_left = np.array([-np.inf, -np.inf, 0.0])  # every weighted particle tilted away: the weights as they were
    np.testing.assert_allclose(tilted(weights, nothing_left), weights)


def test_a_tilt_moves_the_smoothed_pose_through_its_ancestors_and_leaves_the_classes():
    """Known answer: lag 1, frame 0's tilt favours particle 1 three to one; after a resampling that swaps the two,
    frame 0's pose is read with the swapped tilt; its class probabilities are the plain weights'."""
    lineage = ParticleLineage(lag=1)
    poses0 = np.array([[[0.0, 0.0, 0.0]], [[4.0, 0.0, 0.0]]])
    lineage.push(0, poses0, np.array([5, 7]), np.array([0.5, 0.5]), np.array([0.0, np.log(3.0)]))
    lineage.resampled(np.array([1, 0]))  # particle 0 now carries frame 0's particle 1, and its tilt
    (frame0,) = lineage.push(1, poses0, np.array([5, 7]), np.array([0.5, 0.5]))
    np.testing.assert_allclose(frame0.markers, [[3.0, 0.0, 0.0]])  # (3 * 4 + 1 * 0) / 4
    assert frame0.class_probabilities == pytest.approx({7: 0.5, 5: 0.5})


def test_pose_sharpening_changes_the_pose_estimate_only(models):
    """The same seed with a sharpening of 1 and without: bit for bit the same; with 16: the same class
    posterior every frame (the filter is untouched), poses nearer the observed markers than the plain ones."""
    body = BodyModel(models.marker_names_, TORSO_BASE)
    rng = np.random.default_rng(5)
    observed = TORSO_BASE + np.array([0.25, -0.1, 0.15]) + rng.normal(0.0, 0.05, (40, 6, 3))
    runs = {}
    for sharpening in (None, 1.0, 16.0):
        extra = {} if sharpening is None else {"pose_sharpening": sharpening}
        tracker = ActionTracker(models, body, CAMERA, n_particles=80, random_state=3, lag=5, **extra)
        frames = [tracker.step_markers(pose) for pose in observed]
        runs[sharpening] = (frames, tracker.smoothed_frames(final=True))
    for a, b in zip(runs[None][0] + runs[None][1], runs[1.0][0] + runs[1.0][1]):
        np.testing.assert_array_equal(a.markers, b.markers)
    error = {}
    for key in (1.0, 16.0):
        frames, smoothed = runs[key]
        for plain, sharp in zip(runs[1.0][0] + runs[1.0][1], frames + smoothed):
            assert sharp.class_probabilities == pytest.approx(plain.class_probabilities, abs=1e-12)
        error[key] = np.mean([np.linalg.norm(f.markers - o) for f, o in zip(smoothed, observed)])
    assert error[16.0] < error[1.0]
    for bad in (0.5, np.inf, np.nan, True, "2"):
        with pytest.raises(InvalidInputError, match="pose_sharpening"):
            ActionTracker(models, body, CAMERA, pose_sharpening=bad)
