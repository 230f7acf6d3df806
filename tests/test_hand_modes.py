"""Hand modes: the ways a demonstrator holds the hand, the classes refitted per mode, their file round trip, and
the tracker posing each particle with its mode's class."""

from __future__ import annotations

import copy
import dataclasses
import json
import shutil

import numpy as np
import pytest

from hoap_actions.demonstration.tasks import MARKER_NAMES
from hoap_actions.errors import DataFileError, InvalidInputError, MissingModelPartWarning
from hoap_actions.primitives.discovery.primitive_classes import PrimitiveClass, Segment
from hoap_actions.primitives.hmm.posture import hand_inputs
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.models.hand_modes import HandModes, fit_hand_modes
from hoap_actions.primitives.models.models_directory import MANIFEST


def frame(knuckle_dir: np.ndarray, thumb_dir: np.ndarray, wrist=(0.3, -0.1, 0.1)) -> np.ndarray:
    """One marker frame (18,) in the recordings' order with the hand pointing as asked."""
    markers = np.zeros((len(MARKER_NAMES), 3))
    markers[MARKER_NAMES.index("wrist")] = wrist
    markers[MARKER_NAMES.index("index_knuckle")] = np.asarray(wrist) + 0.08 * np.asarray(knuckle_dir)
    markers[MARKER_NAMES.index("thumb_tip")] = np.asarray(wrist) + 0.05 * np.asarray(thumb_dir)
    return markers.ravel()


def test_the_modes_pointing_is_the_unit_vectors_from_the_wrist():
    pointing = hand_inputs(frame(np.array([0.0, 1.0, 0.0]), np.array([0.6, 0.0, 0.8]))[None])[:, 3:]
    np.testing.assert_allclose(pointing, [[0.0, 1.0, 0.0, 0.6, 0.0, 0.8]], atol=1e-12)


def test_fit_hand_modes_groups_demonstrations_by_how_the_hand_is_held_and_refits_classes_per_mode():
    # ten demonstrations: approach (class 0, frames 0-10) then a push (class 1, 10-20); six with the fingers to the
    # left, four with the fingers to the right; the hand is held so from the push's first frame
    left, right = np.array([0.0, 1.0, 0.0]), np.array([0.0, -1.0, 0.0])
    hands, segments = [], {0: [], 1: []}
    for d in range(10):
        pointing = left if d < 6 else right
        hands.append(np.tile(frame(pointing, np.array([1.0, 0.0, 0.0])), (20, 1)))
        segments[0].append(Segment(d, 0, 10, (0.0, 0.0, 0.0), (0.3, 0.0, 0.1), "hand"))
        segments[1].append(Segment(d, 10, 20, (0.3, 0.0, 0.0), (0.4, 0.0, 0.0), "object"))
    classes = [PrimitiveClass(0, "approach", (0,), tuple(segments[0])),
               PrimitiveClass(1, "manipulation", (1,), tuple(segments[1]))]
    segmentations = [[(0, 0, 10), (1, 10, 20)] for _ in range(10)]
    fitted = []
    modes = fit_hand_modes(classes, segmentations, hands, lambda c: fitted.append(c) or f"model of {len(c.segments)}",
                           n_modes=2, min_segments=3)
    left_mode = int(np.argmax(modes.centres[:, 1]))
    np.testing.assert_allclose(modes.prior[left_mode], 0.6)
    np.testing.assert_allclose(modes.centres[left_mode], [0.0, 1.0, 0.0, 1.0, 0.0, 0.0], atol=1e-12)
    assert sorted(modes.classes) == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert modes.classes[(1, left_mode)] == "model of 6" and modes.classes[(1, 1 - left_mode)] == "model of 4"
    assert all({s.demo < 6 for s in c.segments} in ({True}, {False}) for c in fitted)  # never a mixed refit
    few = fit_hand_modes(classes, segmentations, hands, lambda c: "model", n_modes=2, min_segments=5)
    assert sorted(few.classes) == [(0, left_mode), (1, left_mode)]  # the four fingers-right segments are too few
    assert fit_hand_modes(classes, segmentations[:1], hands[:1], lambda c: "model", n_modes=2) is None


def test_hand_modes_check_their_numbers():
    with pytest.raises(InvalidInputError, match="prior must be shares summing to 1"):
        HandModes(np.zeros((2, 6)), np.array([0.7, 0.7]), {})
    with pytest.raises(InvalidInputError, match="centres"):
        HandModes(np.zeros((3, 6)), np.array([0.5, 0.5]), {})
    with pytest.raises(InvalidInputError, match=r"modes \[2\] outside 0..1"):
        HandModes(np.zeros((2, 6)), np.array([0.5, 0.5]), {(0, 2): None})
    with pytest.raises(InvalidInputError, match="pose_hand_modes must be an int >= 0"):
        ActionModels(pose_hand_modes=-1)._check_params()


@pytest.fixture(scope="module")
def moded(posed):
    """The posed small models with two hand modes: the approach refitted for mode 1 (its pose class, moved
    10 cm up, stands in for the refit)."""
    approach = next(cid for cid, m in posed.pose_classes_.items() if m.kind == "approach")
    model = posed.pose_classes_[approach]
    lifted = dataclasses.replace(model, phmm=_lifted(model.phmm, 0.1))
    copy = ActionModels(**posed.get_params())
    for name in ActionModels._learned:
        setattr(copy, name, getattr(posed, name, None))
    copy.hand_modes_ = HandModes(np.eye(2, 6), np.array([0.5, 0.5]), {(approach, 1): lifted})
    return copy, approach


def _lifted(phmm, dz: float):
    """A copy of ``phmm`` whose every marker's mean height is ``dz`` higher."""
    lifted = copy.deepcopy(phmm)
    lifted.mean_bar_[:, 2:3 * len(MARKER_NAMES):3] += dz
    return lifted


def _edit(path, change) -> None:
    manifest = json.loads((path / MANIFEST).read_text())
    change(manifest)
    (path / MANIFEST).write_text(json.dumps(manifest))


def test_hand_modes_survive_a_round_trip_and_older_directories_load_without_them(moded, tmp_path):
    models, approach = moded
    path = tmp_path / "models"
    models.save(path)
    again = ActionModels.load(path)
    np.testing.assert_array_equal(again.hand_modes_.prior, models.hand_modes_.prior)
    np.testing.assert_array_equal(again.hand_modes_.centres, models.hand_modes_.centres)
    np.testing.assert_array_equal(again.hand_modes_.classes[(approach, 1)].phmm.mean_bar_,
                                  models.hand_modes_.classes[(approach, 1)].phmm.mean_bar_)
    remove = next(c for c, m in models.classes_.items() if m.kind == "remove")
    _edit(path, lambda m: m["hand_modes"]["classes"][0].update(id=remove, file=f"mode_{remove}_1.npz"))
    shutil.copy(path / f"mode_{approach}_1.npz", path / f"mode_{remove}_1.npz")
    with pytest.raises(DataFileError, match="must refit a class of the same kind and states"):
        ActionModels.load(path)
    _edit(path, lambda m: (m.update(format_version=5), m.pop("hand_modes")))
    for name in path.glob("mode_*.npz"):
        name.unlink()
    with pytest.warns(MissingModelPartWarning, match=r"written before hand modes \(format 5\).*pose_hand_modes=4"):
        assert ActionModels.load(path).hand_modes_ is None
    assert (path / MANIFEST).is_file()


def test_the_tracker_poses_each_particle_with_its_modes_class_and_keeps_modes_through_resampling(moded):
    from hoap_actions.tracking.action_tracker import ActionTracker
    from hoap_actions.tracking.tracking_models import TrackingModels
    from hoap_actions.vision.body_model import BodyModel

    models, approach = moded
    tracked = TrackingModels.from_action_models(models)
    other = copy.deepcopy(tracked.classes[approach])
    other.phmm.n_states += 1
    with pytest.raises(InvalidInputError, match="must have their class's number of states"):
        dataclasses.replace(tracked, hand_modes=HandModes(np.eye(2, 6), np.array([0.5, 0.5]), {(approach, 1): other}))
    body = BodyModel(tracked.marker_names, np.zeros(3))
    tracker = ActionTracker(tracked, body, _camera(), n_particles=2000, random_state=3)
    assert abs(np.mean(tracker.mode == 1) - 0.5) < 0.05  # drawn from the prior
    tracker.class_id[:] = approach
    tracker.state[:] = 1.0
    tracker.offset[:] = 0.0
    tracker.mode[:2] = (0, 1)
    tracker.start[1], tracker.end[1] = tracker.start[0], tracker.end[0]
    poses = tracker.markers(np.arange(2))
    np.testing.assert_allclose(poses[1, :, 2] - poses[0, :, 2], 0.1, atol=1e-9)  # mode 1's class is 10 cm higher
    np.testing.assert_allclose(poses[1, :, :2], poses[0, :, :2], atol=1e-9)
    weights = np.zeros(tracker.n_particles)
    weights[1] = 1.0
    tracker._resample(weights)
    assert np.all(tracker.mode == 1)


def _camera():
    from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA

    return DEMONSTRATOR_CAMERA


def test_models_learn_hand_modes_with_their_classes_count_of_states(small_demos, small):
    demos, discovery = small_demos, small[1]
    lengths = [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    models = ActionModels(pose_mean_model="tps", smoothing=0.5, pose_hand_modes=2).fit(
        H, lengths, discovery, demos.fps, demos.marker_names)
    assert models.hand_modes_.n_modes == 2 and np.isclose(models.hand_modes_.prior.sum(), 1.0)
    assert models.hand_modes_.classes == {}  # three demonstrations with a manipulation: no mode holds six segments
    cls = discovery.classes_[0]
    refit = models._fit_class(cls, [np.hstack([e.H.reshape(e.T, -1), np.zeros((e.T, 18))]) for e in demos], {}, None,
                              n_states=3)
    assert refit.phmm.n_states == 3
    assert ActionModels(pose_hand_modes=0).fit(H, lengths, discovery, demos.fps, demos.marker_names).hand_modes_ is None
