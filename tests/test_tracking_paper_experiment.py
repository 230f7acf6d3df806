"""The paper's tracking experiment (Figs. 10-12) and poses generated from the hand: known answers on
synthetic reaches, the pointed position's settling frame, the proposals' geometry."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.posture import PostureModel
from hoap_actions.primitives.models.class_models import ClassModel
from hoap_actions.tracking.action_tracker import ActionTracker
from hoap_actions.tracking.grid_experiment import approach_tracking_models, grid_reaches, settling_frame
from hoap_actions.tracking.poses import (
    HAND_TURN_MEMORY,
    HandPoses,
    OffsetPoses,
    TurnedHandOffsets,
    _arm_gain,
    _swivel,
    pose_proposal,
    turn_hand,
)
from hoap_actions.tracking.tracking_models import TrackingModels
from hoap_actions.vision.body_model import BodyModel

SHOULDER = np.array([-0.45, 0.15, 0.30])
REST_WRIST = np.array([-0.40, 0.22, -0.25])
TORSO_BASE = np.array([-0.47, 0.25, -0.10])


def synthetic_reach(target: np.ndarray, frames: int = 100) -> np.ndarray:
    """Markers ``(frames, 6, 3)`` of a minimum-jerk reach from rest to just before the block at ``target``
    (u, v): the hand points from the shoulder through the wrist, the elbow hangs below the shoulder-wrist
    line by an amount that depends on the reach's length (a smooth function of the hand)."""
    s = np.linspace(0.0, 1.0, frames)
    s = 10 * s**3 - 15 * s**4 + 6 * s**5
    end = np.array([target[0] - 0.08, target[1], 0.06])
    wrist = REST_WRIST + s[:, None] * (end - REST_WRIST)
    wrist[:, 2] += 0.12 * np.sin(np.pi * s)
    axis = wrist - SHOULDER
    length = np.linalg.norm(axis, axis=1, keepdims=True)
    direction = axis / length
    down = np.cross(direction, np.cross([0.0, 0.0, -1.0], direction))
    down /= np.linalg.norm(down, axis=1, keepdims=True)
    elbow = SHOULDER + 0.5 * axis + down * np.sqrt(np.maximum(0.30**2 - (0.5 * length) ** 2, 0.0004))
    side = np.cross(direction, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    markers = np.stack([np.tile(SHOULDER, (frames, 1)), elbow, wrist, wrist + 0.17 * direction,
                        wrist + 0.09 * direction, wrist + 0.05 * direction + 0.03 * side], axis=1)
    return markers


GRID = [np.array([u, v]) for u in (-0.15, 0.0, 0.15) for v in (-0.3, 0.0, 0.3)]


@pytest.fixture(scope="module")
def grid_models():
    """An approach PHMM (linear, full covariances) and a posture model, trained on 3 x 3 synthetic reaches
    with a few millimetres of jitter, as the paper's experiment trains them on the 3 x 3 grid."""
    rng = np.random.default_rng(0)
    movements = []
    for target in GRID:
        for _ in range(2):
            X = synthetic_reach(target).reshape(100, 18)
            movements.append((X + rng.normal(0.0, 0.002, X.shape), target))
    X = np.concatenate([x for x, _ in movements])
    phmm = ParametricHMM(n_states=20, covariance_type="full", reg_covar=1e-5, n_iter=20, random_state=0)
    phmm.fit(X, [100] * len(movements), np.array([p for _, p in movements]))
    posture = PostureModel(degree=3, alpha=0.1).fit(X)
    return approach_tracking_models(phmm, movements), approach_tracking_models(phmm, movements, posture)


# -------------------------------------------------------------------------------- the settling frame
def test_settling_frame_is_the_first_frame_from_which_the_error_stays_within():
    cm = 0.01
    assert settling_frame(np.array([5, 3, 1, 1, 3, 1, 1.5]) * cm) == 5  # left once at frame 4: from 5 on
    assert settling_frame(np.array([1, 1, 0.5]) * cm) == 0  # within from the first frame
    assert settling_frame(np.array([5, 1, 1, 2.5]) * cm) is None  # out again at the end: never settled
    assert settling_frame(np.array([5, 2.0, 1.99]) * cm) == 2  # 2 cm itself is not within
    assert settling_frame(np.array([1, np.nan, 1]) * cm) == 2  # an unknown estimate counts as outside
    assert settling_frame(np.array([3, 1]) * cm, within_m=0.05) == 0
    with pytest.raises(InvalidInputError, match="non-empty"):
        settling_frame(np.array([]))


# ---------------------------------------------------------------------------- poses from the hand
def test_a_posture_completed_particle_at_the_true_hand_has_the_posture_model_s_elbow():
    """Known answer: a particle whose hand is a held-out reach's true hand gets the shoulder and elbow the
    posture model predicts from that hand, so its elbow is off by the posture model's own error (small
    here: the synthetic elbow is a smooth function of the hand)."""
    train = np.concatenate([synthetic_reach(t, 40).reshape(40, 18) for t in GRID])
    posture = PostureModel(degree=3, alpha=1e-3).fit(train)
    truth = synthetic_reach(np.array([0.07, -0.12]), 40).reshape(40, 18)  # a location the model never saw
    phmm = ParametricHMM(n_states=40, covariance_type="diag")  # a chain whose state means are the true frames
    phmm.mean_bar_, phmm.W_, phmm.V_ = truth.copy(), np.zeros((40, 18, 2)), np.zeros((40, 18, 0))
    phmm.covars_ = np.full((40, 18), 1e-4)
    model = ClassModel(0, "approach", phmm, np.zeros(6), np.eye(6)[:, 3:5], 0.1)
    models = TrackingModels({0: model}, ActionGrammar(0.0).fit([[0]]),
                            ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip"), 3, posture)
    proposal = HandPoses(models)
    poses = proposal.pose(0, np.arange(40.0), np.zeros((40, 6)), np.zeros((40, proposal.dim))).reshape(40, 6, 3)
    true = truth.reshape(40, 6, 3)
    np.testing.assert_allclose(poses[:, 2:], true[:, 2:], atol=1e-12)  # the hand is the true hand
    elbow_error = np.linalg.norm(poses[:, 1] - true[:, 1], axis=1)
    posture_error = np.linalg.norm(posture.predict(truth)[:, 3:] - truth[:, 3:6], axis=1)
    np.testing.assert_allclose(elbow_error, posture_error, atol=1e-12)
    assert np.sqrt(np.mean(elbow_error**2)) < 0.01


def test_the_swivel_turns_the_elbow_about_the_shoulder_wrist_line():
    rng = np.random.default_rng(1)
    shoulder, elbow, wrist = rng.normal(size=(3, 50, 3))
    angle = rng.uniform(-np.pi, np.pi, 50)
    turned = _swivel(shoulder, elbow, wrist, angle)
    for a, b in ((shoulder, elbow), (wrist, elbow)):  # both segments keep their lengths
        np.testing.assert_allclose(np.linalg.norm(turned - a, axis=1), np.linalg.norm(b - a, axis=1), rtol=1e-9)
    np.testing.assert_allclose(_swivel(shoulder, elbow, wrist, np.zeros(50)), elbow, atol=1e-12)
    quarter = _swivel(np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]), np.array([[0.0, 0.0, 2.0]]), np.array([np.pi / 2]))
    np.testing.assert_allclose(quarter, [[-1.0, 0.0, 0.0]], atol=1e-12)  # right-handed about +z


def test_a_turned_hand_is_the_same_hand_turned_rigidly_about_the_wrist():
    rng = np.random.default_rng(3)
    hand = rng.normal(0.0, 0.05, (40, 12))
    turn, roll = rng.uniform(-np.pi, np.pi, (2, 40))
    turned = np.hstack([hand[:, :3], turn_hand(hand, turn, roll)]).reshape(40, 4, 3)
    before = hand.reshape(40, 4, 3)
    for a in range(4):  # every distance between the wrist, index tip, knuckle and thumb is kept
        for b in range(a + 1, 4):
            np.testing.assert_allclose(np.linalg.norm(turned[:, a] - turned[:, b], axis=1),
                                       np.linalg.norm(before[:, a] - before[:, b], axis=1), rtol=1e-9)
    np.testing.assert_allclose(turn_hand(hand, np.zeros(40), np.zeros(40)), hand[:, 3:], atol=1e-12)
    # known answers: a quarter turn about the vertical (right-handed) takes +x to +y; a roll leaves the knuckle
    # on its line and turns the thumb about it
    square = np.array([[0, 0, 0, 0.1, 0, 0, 0.05, 0, 0, 0.05, -0.03, 0.0]])
    np.testing.assert_allclose(turn_hand(square, np.array([np.pi / 2]), np.zeros(1)),
                               [[0, 0.1, 0, 0, 0.05, 0, 0.03, 0.05, 0]], atol=1e-12)
    np.testing.assert_allclose(turn_hand(square, np.zeros(1), np.array([np.pi / 2])),
                               [[0.1, 0, 0, 0.05, 0, 0, 0.05, 0, -0.03]], atol=1e-12)


def test_the_turned_hand_proposal_adds_two_persistent_angles_to_the_offsets(grid_models):
    models, _ = grid_models
    turned, offsets = pose_proposal("turned", models), OffsetPoses(models)
    assert isinstance(turned, TurnedHandOffsets) and turned.dim == offsets.dim + 2
    rng = np.random.default_rng(4)
    states, phi = np.full(5, 7.0), np.tile([*models.classes[0].centre[:3], 0.05, 0.1, 0.025], (5, 1))
    state = np.hstack([rng.normal(0.0, 0.01, (5, offsets.dim)), np.zeros((5, 2))])
    np.testing.assert_allclose(turned.pose(0, states, phi, state), offsets.pose(0, states, phi, state[:, :-2]),
                               atol=1e-12)  # no turn: the offsets' pose
    state[:, -2] = 0.5
    moved = turned.pose(0, states, phi, state) - offsets.pose(0, states, phi, state[:, :-2])
    np.testing.assert_allclose(moved[:, :9], 0.0, atol=1e-12)  # shoulder, elbow and wrist stay
    assert np.all(np.linalg.norm(moved[:, 9:], axis=1) > 0.0)
    # the angles drift as an AR(1) process whose stationary spread is turn_sd
    walk = np.zeros((20000, turned.dim))
    for _ in range(150):
        walk = turned.drift(0, np.full(20000, 3.0), walk, rng)
    expected = np.asarray(turned.turn_sd) * np.sqrt(1.0 - HAND_TURN_MEMORY ** (2 * 150))
    np.testing.assert_allclose(walk[:, -2:].std(axis=0), expected, rtol=0.03)
    for bad in ((0.1,), (0.1, -0.2), (np.nan, 0.1)):
        with pytest.raises(InvalidInputError, match="turn_sd takes two"):
            TurnedHandOffsets(models, bad)


def test_the_arm_follows_a_hand_shift_as_the_state_s_full_gaussian_says(grid_models):
    """Without a posture model the shoulder and elbow move by the conditional Gaussian's mean: for a shift d
    of all four hand markers, Sigma_ah Sigma_hh^-1 (d, d, d, d); a diagonal covariance moves nothing."""
    models, _ = grid_models
    model = models.classes[0]
    gain = _arm_gain(model)
    rng = np.random.default_rng(2)
    d = rng.normal(0.0, 0.01, 3)
    for k in (0, 10, 19):
        covars = model.phmm.covars_[k]
        direct = covars[:6, 6:] @ np.linalg.solve(covars[6:, 6:], np.tile(d, 4))
        np.testing.assert_allclose(gain[k] @ d, direct, rtol=1e-8, atol=1e-12)
    poses = HandPoses(models)
    state, rest = np.zeros((1, poses.dim)), np.zeros((1, poses.dim))
    state[0, :3] = d
    phi = np.array([[*model.centre[:3], 0.05, 0.1, 0.025]])
    moved = poses.pose(0, np.array([5.0]), phi, state) - poses.pose(0, np.array([5.0]), phi, rest)
    np.testing.assert_allclose(moved[0, 6:], np.tile(d, 4), atol=1e-12)
    np.testing.assert_allclose(moved[0, :6], gain[5] @ d, atol=1e-12)
    if poses.trunk:  # a trunk shift moves the shoulder and elbow together and leaves the hand
        state[0, :3], state[0, 4:7] = 0.0, d
        leaned = poses.pose(0, np.array([5.0]), phi, state) - poses.pose(0, np.array([5.0]), phi, rest)
        np.testing.assert_allclose(leaned[0], np.r_[d, d, np.zeros(12)], atol=1e-12)
    assert pose_proposal("offsets", models).dim == 18 and isinstance(pose_proposal("hand", models), HandPoses)
    assert isinstance(pose_proposal("offsets", models), OffsetPoses)
    with pytest.raises(InvalidInputError, match="pose_proposal must be one of"):
        pose_proposal("joints", models)


def test_tracking_a_synthetic_reach_from_markers_converges(grid_models):
    """From a reach's own markers (to a location between the training ones), poses generated from the hand
    follow it within 2 cm RMS and the pointed position ends at least twice as near the truth as it started,
    for each of three seeds, with the state's conditional Gaussian and with the posture model; with the
    posture model it ends within 3 cm in the median run."""
    target = np.array([0.07, -0.12])
    reach = synthetic_reach(target)
    body = BodyModel(("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip"), TORSO_BASE)
    for models in grid_models:
        ends = []
        for seed in range(3):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the first models carry no posture model, and say so
                tracker = ActionTracker(models, body, _camera(), n_particles=200, pose_proposal="hand",
                                        random_state=seed)
            frames = [tracker.step_markers(pose, sigma_m=0.02) for pose in reach]
            estimate = np.array([f.markers for f in frames])
            assert np.sqrt(np.mean(np.sum((estimate - reach) ** 2, axis=2))) < 0.02
            first, last = (np.linalg.norm(frames[k].end_mean[:2] - target) for k in (0, -1))
            assert last < 0.5 * first
            ends.append(last)
        assert models.posture is None or np.median(ends) < 0.03


def test_models_without_a_posture_model_still_track_with_a_warning(grid_models):
    models, _ = grid_models
    body = BodyModel(models.marker_names, TORSO_BASE)
    with pytest.warns(UserWarning, match="no posture model"):
        ActionTracker(models, body, _camera(), n_particles=5, pose_proposal="hand")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the first design needs no posture model: no warning
        ActionTracker(models, body, _camera(), n_particles=5)


def test_tracking_models_bad_input(grid_models):
    models, with_posture = grid_models
    grammar = ActionGrammar(0.0).fit([[7]])
    with pytest.raises(InvalidInputError, match="no model"):
        TrackingModels(models.classes, grammar, models.marker_names, 3)
    with pytest.raises(InvalidInputError, match="hand_marker"):
        TrackingModels(models.classes, models.grammar, models.marker_names, 6)
    with pytest.raises(InvalidInputError, match="posture model poses the markers"):
        TrackingModels(models.classes, models.grammar, ("a", "b", "c", "d", "e", "f"), 3, with_posture.posture)
    with pytest.raises(InvalidInputError, match="object_end"):
        TrackingModels(models.classes, models.grammar, models.marker_names, 3, object_end=(np.zeros(2), 0.01))


def test_grid_reaches_cut_the_approach_of_each_grid_episode(small_demos):
    """The small preset's bare approach is a 5 x 7 test-grid episode: its reach is its approach phase, the
    target the block's place at its end; a grid the recording lacks is refused."""
    (reach,) = grid_reaches(small_demos, "5x7")
    episode = small_demos[reach.episode]
    labels = episode.ground_truth.labels
    assert reach.end == int(np.sum(labels == small_demos.phase_names.index("approach"))) < episode.T
    np.testing.assert_allclose(reach.target, episode.O[reach.end - 1, :2])
    assert reach.location == (2, 3) and reach.grid == "5x7"
    with pytest.raises(InvalidInputError, match="no reaches of grid '3x3'"):
        grid_reaches(small_demos, "3x3")


def _camera():
    from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA

    return DEMONSTRATOR_CAMERA


def test_track_command_poses_from_the_hand_and_runs_the_paper_experiment_only_on_grids(small_demos, tmp_path, capsys):
    """``track --pose-proposal hand --posture FILE`` tracks (here from markers) and says so in its report; the
    paper's experiment (``--grid-model``) needs a recording with a 3 x 3 training grid and its own models."""
    import json

    from hoap_actions.apps.cli import main
    from hoap_actions.demonstration.datasets import write_demonstrations

    path = tmp_path / "small.h5"
    write_demonstrations(path, small_demos)
    frames = np.concatenate([e.H.reshape(e.T, -1) for e in small_demos])
    PostureModel(alpha=1.0).fit(frames).save(tmp_path / "posture.json")
    out = tmp_path / "hand.json"
    assert main(["track", "--demos", str(path), "--episode", "3", "--particles", "50", "--from-markers",
                 "--pose-proposal", "hand", "--posture", str(tmp_path / "posture.json"), "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["pose_proposal"] == "hand" and report["posture"].endswith("posture.json")
    assert report["rms_m_pooled"] > 0 and report["frames"] == small_demos[3].T
    assert main(["track", "--demos", str(path), "--episode", "3", "--grid-model", "linear", "--models",
                 str(tmp_path)]) == 2
    assert main(["track", "--demos", str(path), "--episode", "3", "--grid-model", "linear"]) == 2
    errors = capsys.readouterr().err.strip().splitlines()
    assert "leave out --models" in errors[-2] and "no reaches of grid '3x3'" in errors[-1]
