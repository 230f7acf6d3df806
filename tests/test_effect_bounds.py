"""Where a particle's effect may lie: the hand's end held at its posing model's centre along the directions that
model ignores, without moving any pose."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hoap_actions.primitives.models.hand_modes import HandModes
from hoap_actions.tracking.action_tracker import ActionTracker
from hoap_actions.tracking.effect_bounds import EndHold, end_boxes
from hoap_actions.tracking.poses import mean_poses
from hoap_actions.tracking.tracking_models import TrackingModels
from hoap_actions.vision.body_model import BodyModel


def _without_end_height(model):
    """``model`` with an effect basis of the same width that leaves the end's height out (as a hand mode's
    approaches, all ending at one height, teach it)."""
    basis = model.basis.copy()
    basis[5] = 0.0
    basis, _ = np.linalg.qr(basis)
    return dataclasses.replace(model, basis=basis)


@pytest.fixture(scope="module")
def heightless(posed):
    """The posed small models' tracking models with two hand modes, mode 1's approach posed by a refit whose
    basis ignores the end's height."""
    tracked = TrackingModels.from_action_models(posed)
    approach = next(cid for cid, m in tracked.classes.items() if m.kind == "approach")
    refit = _without_end_height(tracked.classes[approach])
    modes = HandModes(np.eye(2, 6), np.array([0.5, 0.5]), {(approach, 1): refit})
    return dataclasses.replace(tracked, hand_modes=modes), approach, refit


def test_the_hold_moves_the_end_only_along_what_the_pose_ignores(heightless):
    tracked, approach, refit = heightless
    rng = np.random.default_rng(0)
    end = refit.centre[3:] + rng.normal(0.0, 0.05, (50, 3))
    start = np.tile(refit.centre[:3], (50, 1))
    held = end.copy()
    EndHold(tracked.classes, tracked.hand_modes.classes, 2).hold(np.full(50, approach), np.ones(50, int), held)
    np.testing.assert_allclose(held[:, 2], refit.centre[5], atol=1e-12)  # the height: the mode's own
    np.testing.assert_allclose(held[:, :2], end[:, :2], atol=1e-12)  # x and y: as they were
    states = np.linspace(0.0, refit.phmm.n_states - 1, 50)
    before = mean_poses(refit, states, np.hstack([start, end]), len(tracked.marker_names))
    after = mean_poses(refit, states, np.hstack([start, held]), len(tracked.marker_names))
    np.testing.assert_allclose(after, before, atol=1e-12)  # the pose does not move


def test_the_hold_leaves_ends_the_model_poses_and_manipulations_alone(heightless):
    """An approach whose basis varies the end in x, y and z keeps its ends; a manipulation's end (the object's) is
    never held, whatever its basis."""
    tracked, approach, _ = heightless
    manipulation = next(cid for cid, m in tracked.classes.items() if m.kind == "manipulation")
    every_end = np.vstack([np.zeros((3, 3)), np.eye(3)])  # (6, 3): the end in every direction, the start fixed
    classes = {approach: dataclasses.replace(tracked.classes[approach], basis=every_end),
               manipulation: dataclasses.replace(tracked.classes[manipulation], basis=np.zeros((6, 0)))}
    end = np.random.default_rng(1).normal(0.3, 0.1, (4, 3))
    held = end.copy()
    EndHold(classes, {}, 2).hold(np.array([approach, approach, manipulation, manipulation]), np.array([0, 1, 0, 1]),
                                 held)
    np.testing.assert_array_equal(held, end)


def test_the_tracker_holds_mode_particles_ends_without_moving_their_poses(heightless):
    """After a track, every mode-1 approach particle ends at its refit's height; holding ends moved at random moves
    no particle's pose by more than micrometres (the held directions move a pose by less than a tenth of the move)."""
    from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA

    tracked, approach, refit = heightless
    body = BodyModel(tracked.marker_names, np.zeros(3))
    tracker = ActionTracker(tracked, body, DEMONSTRATOR_CAMERA, n_particles=300, random_state=5)
    model = tracked.classes[approach]
    for s in np.linspace(0.0, model.phmm.n_states - 1, 12):
        observed = mean_poses(model, np.array([s]), model.centre[None], len(tracked.marker_names))
        tracker.step_markers(observed.reshape(-1, 3))
    in_mode = (tracker.class_id == approach) & (tracker.mode == 1)
    assert in_mode.sum() > 10
    np.testing.assert_allclose(tracker.end[in_mode, 2], refit.centre[5], atol=1e-12)
    tracker.end += np.random.default_rng(2).normal(0.0, 0.05, tracker.end.shape)
    moved = tracker.markers()
    tracker._end_hold.hold(tracker.class_id, tracker.mode, tracker.end)
    np.testing.assert_allclose(tracker.markers(), moved, atol=1e-4)


def test_end_boxes_span_the_training_ends_widened_by_the_margin(heightless):
    tracked, approach, _ = heightless
    model = tracked.classes[approach]
    ends = (model.centre + model.phmm.train_phi_ @ model.basis.T)[:, 3:]
    low, high = end_boxes(tracked.classes, margin_m=0.02)[approach]
    np.testing.assert_allclose(low, ends.min(axis=0) - 0.02)
    np.testing.assert_allclose(high, ends.max(axis=0) + 0.02)
