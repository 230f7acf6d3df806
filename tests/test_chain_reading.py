"""A demonstration's manipulation read again from where the block went: the training chains, the chain chosen by
the block's seen displacement and the frames' own reading, and the tracker's score of it."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.models.shipped import load_default_models
from hoap_actions.primitives.models.manipulation_chains import ManipulationChain, manipulation_chains
from hoap_actions.tracking import track_markers_episode
from hoap_actions.tracking.chain_reading import read_manipulation_chain


def test_the_chains_are_the_training_runs_of_manipulations_with_their_mean_displacement_and_durations():
    def segment(demo, start, initial, final):
        return SimpleNamespace(demo=demo, start=start, initial=initial, final=final)

    classes = [SimpleNamespace(primitive_id=0, kind="approach", segments=[]),
               SimpleNamespace(primitive_id=7, kind="manipulation", segments=[
                   segment(0, 10, (0.0, 0.0, 0.0), (0.01, 0.0, 0.0)), segment(1, 5, (1.0, 0.0, 0.0), (1.02, 0.0, 0.0)),
                   segment(2, 4, (0.0, 0.0, 0.0), (0.0, 0.05, 0.0))]),
               SimpleNamespace(primitive_id=9, kind="manipulation", segments=[
                   segment(0, 14, (0.01, 0.0, 0.0), (0.10, 0.0, 0.0)),
                   segment(1, 9, (1.02, 0.0, 0.0), (1.12, 0.0, 0.0))]),
               SimpleNamespace(primitive_id=2, kind="remove", segments=[])]
    discovery = SimpleNamespace(classes_=classes, segmentations_=[
        [(0, 0, 10), (7, 10, 14), (9, 14, 30), (2, 30, 40)],
        [(0, 0, 5), (7, 5, 9), (9, 9, 21), (2, 21, 30)],
        [(0, 0, 4), (7, 4, 8), (2, 8, 12)],
        [(0, 0, 6)],
    ])
    first, second = manipulation_chains(discovery)
    assert first.classes == (7, 9) and first.count == 2 and second.classes == (7,) and second.count == 1
    np.testing.assert_allclose(first.displacement, [0.11, 0.0, 0.0])  # (0.10 + 0.12) / 2
    np.testing.assert_allclose(first.durations, [4.0, 14.0])
    np.testing.assert_allclose(second.displacement, [0.0, 0.05, 0.0])


CHAINS = [ManipulationChain((7, 8), np.array([0.05, 0.0, 0.0]), np.array([2.0, 4.0]), 30),
          ManipulationChain((7, 9), np.array([0.10, 0.0, 0.0]), np.array([1.0, 2.0]), 20),
          ManipulationChain((7, 5), np.array([0.10, 0.0, 0.0]), np.array([2.0, 6.0]), 40),
          ManipulationChain((4,), np.array([0.10, 0.0, 0.0]), np.array([1.0]), 90)]
ACTIONS = {7: 1, 8: 1, 9: 1, 5: 1, 4: 3}
KINDS = {0: "approach", 7: "manipulation", 8: "manipulation", 9: "manipulation", 5: "manipulation",
         4: "manipulation", 2: "remove"}
READ = [0, 0, 7, 7, 9, 9, 9, 9, 2, 2]


def seen(moved: float) -> list[np.ndarray]:
    return [np.zeros(3)] * 8 + [np.array([moved, 0.0, 0.0])] * 2


def test_the_chain_the_block_went_by_lasts_its_pieces_training_durations_from_the_manipulations_start():
    # moved 10 cm: (7, 9) and (7, 5) fit; (7, 9) shares more frames with the reading; (4,) is another action. It lasts
    # 1 + 2 frames: the rest of what was read as manipulation goes to the remove read after it
    np.testing.assert_array_equal(read_manipulation_chain(READ, seen(0.10), CHAINS, ACTIONS, KINDS),
                                  [0, 0, 7, 9, 9, 2, 2, 2, 2, 2])
    # moved 5 cm: (7, 8), 2 + 4 frames, as long as the reading
    np.testing.assert_array_equal(read_manipulation_chain(READ, seen(0.049), CHAINS, ACTIONS, KINDS),
                                  [0, 0, 7, 7, 8, 8, 8, 8, 2, 2])
    # no frame shared beyond the lift: the most performed of the fitting chains, (7, 5), 2 + 6 frames, longer than
    # the reading: into the frames read as the remove, up to the end
    np.testing.assert_array_equal(read_manipulation_chain([0, 0, 7, 7, 8, 8, 8, 8, 2, 2], seen(0.10), CHAINS, ACTIONS,
                                                          KINDS), [0, 0, 7, 7, 5, 5, 5, 5, 5, 5])


@pytest.mark.parametrize("classes, blocks", [
    (READ, seen(0.30)),  # no chain moved the block that far
    (READ, [None] * 10),  # the block never seen
    ([0, 0, 0, 2, 2], [np.zeros(3)] * 5),  # no manipulation read
])
def test_the_reading_is_left_as_it_was_where_the_block_cannot_tell(classes, blocks):
    np.testing.assert_array_equal(read_manipulation_chain(classes, blocks, CHAINS, ACTIONS, KINDS), classes)


def test_one_sighting_per_frame_is_asked_for():
    with pytest.raises(InvalidInputError, match="one class and one block sighting"):
        read_manipulation_chain(READ, seen(0.10)[:-1], CHAINS, ACTIONS, KINDS)


def test_a_track_scores_its_classes_read_from_the_block(small_demos):
    models = load_default_models()
    result = track_markers_episode(models, small_demos, 0, particles=100, seed=0)
    summary = result.summary()
    assert len(summary["read_classes"]) == len(summary["recognized"]) == small_demos[0].T
    known = result.truth_classes != -1
    read = np.array(summary["read_classes"])
    assert summary["read_frame_accuracy"] == pytest.approx(np.mean(read[known] == result.truth_classes[known]))
    kinds = {cid: c.kind for cid, c in models.classes_.items()}
    outside = [kinds.get(int(c)) != "manipulation" for c in summary["recognized"]]
    manipulating = np.flatnonzero(~np.array(outside))
    before = np.arange(len(read)) < manipulating[0]
    np.testing.assert_array_equal(read[before], np.array(summary["recognized"])[before])  # the approach is untouched
    assert "read_classes" not in dataclasses.replace(result, chains=[]).summary()
