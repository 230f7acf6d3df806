"""Segmentation metrics on cases with known answers."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.evaluation.segmentation import (
    boundary_f1,
    edit_score,
    hungarian_frame_accuracy,
    hungarian_mapping,
    levenshtein,
    many_to_one_frame_accuracy,
    many_to_one_mapping,
    relabel,
)

TRUE = [np.array([0, 0, 0, 1, 1, 2, 2, 2]), np.array([0, 0, 1, 1, 1, 1, 2, 2])]


def test_relabelled_truth_is_perfect():
    pred = [np.array([7, 7, 7, 3, 3, 9, 9, 9]), np.array([7, 7, 3, 3, 3, 3, 9, 9])]
    assert hungarian_mapping(pred, TRUE) == {3: 1, 7: 0, 9: 2}
    assert hungarian_frame_accuracy(pred, TRUE) == 1.0
    assert edit_score(pred, TRUE, hungarian_mapping(pred, TRUE)) == 1.0
    assert boundary_f1(pred, TRUE, tolerance_frames=0) == 1.0


def test_hungarian_accuracy_known_answer():
    # contingency (pred rows a, b; true cols 0, 1): [[3, 1], [1, 3]] -> a:0, b:1, 6 of 8 frames
    pred = ["a", "a", "a", "b", "a", "b", "b", "b"]
    true = [0, 0, 0, 0, 1, 1, 1, 1]
    assert hungarian_frame_accuracy(pred, true) == pytest.approx(6 / 8)
    assert hungarian_mapping(pred, true) == {"a": 0, "b": 1}


def test_hungarian_mapping_is_global_across_demos():
    # label 5 is "0" in the first demo and "1" in the second: one label, one meaning
    pred = [np.array([5, 5, 5, 6]), np.array([5, 5])]
    true = [np.array([0, 0, 0, 1]), np.array([1, 1])]
    assert hungarian_frame_accuracy(pred, true) == pytest.approx(4 / 6)


def test_more_predicted_than_true_labels_leaves_some_unmatched():
    pred = np.array([0, 0, 1, 1, 2, 2])  # over-segmented: true has one label for the second half
    true = np.array([0, 0, 1, 1, 1, 1])
    assert len(hungarian_mapping(pred, true)) == 2
    assert hungarian_frame_accuracy(pred, true) == pytest.approx(4 / 6)
    assert edit_score(pred, true, hungarian_mapping(pred, true)) == pytest.approx(1 - 1 / 3)


def test_many_to_one_maps_consecutive_primitives_of_one_action_to_it():
    # the Fig. 7 case: one push cut into P1 P2 P3 (ids 1, 2, 3); id 4 straddles push and remove
    pred = [np.array([0, 0, 1, 2, 3, 4, 4, 4]), np.array([0, 1, 2, 4, 4])]
    true = [np.array([0, 0, 7, 7, 7, 7, 9, 9]), np.array([0, 7, 7, 9, 9])]
    assert many_to_one_mapping(pred, true) == {0: 0, 1: 7, 2: 7, 3: 7, 4: 9}
    assert many_to_one_frame_accuracy(pred, true) == pytest.approx(12 / 13)
    assert hungarian_frame_accuracy(pred, true) == pytest.approx(9 / 13)  # one of P1 P2 P3 only
    mapped = relabel(pred, many_to_one_mapping(pred, true))
    np.testing.assert_array_equal(mapped[0], [0, 0, 7, 7, 7, 9, 9, 9])
    assert edit_score(mapped, true) == 1.0  # P1 P2 P3 became one push segment
    assert boundary_f1(mapped, true, tolerance_frames=1) == 1.0


def test_many_to_one_is_never_below_one_to_one():
    rng = np.random.default_rng(3)
    for _ in range(50):
        true = [rng.integers(0, 4, size=rng.integers(1, 30)) for _ in range(3)]
        pred = [rng.integers(0, 6, size=len(t)) for t in true]
        assert many_to_one_frame_accuracy(pred, true) >= hungarian_frame_accuracy(pred, true) - 1e-12


def test_relabel_marks_unmapped_labels():
    np.testing.assert_array_equal(relabel(np.array([1, 2, 3]), {1: 5, 3: 6})[0], [5, -1, 6])


def test_edit_score_known_answers():
    # segments (a b c) vs (a c): one deletion over max length 3
    assert edit_score(list("aabbbcc"), list("aaacccc")) == pytest.approx(2 / 3)
    # boundary shifts are not penalised, order is
    assert edit_score(list("aaaab"), list("abbbb")) == 1.0
    assert edit_score(list("ab"), list("ba")) == 0.0
    # mean over demos
    assert edit_score([np.array([1, 2]), np.array([1])], [np.array([1, 2]), np.array([2])]) == pytest.approx(0.5)


@cache
def reference_levenshtein(a: tuple, b: tuple) -> int:
    if not a or not b:
        return len(a) + len(b)
    return min(
        reference_levenshtein(a[1:], b) + 1,
        reference_levenshtein(a, b[1:]) + 1,
        reference_levenshtein(a[1:], b[1:]) + (a[0] != b[0]),
    )


def test_levenshtein_matches_recursive_definition():
    assert levenshtein("kitten", "sitting") == 3
    rng = np.random.default_rng(0)
    for _ in range(100):
        a = tuple(rng.integers(0, 3, size=rng.integers(0, 8)).tolist())
        b = tuple(rng.integers(0, 3, size=rng.integers(0, 8)).tolist())
        assert levenshtein(a, b) == reference_levenshtein(a, b)


def test_boundary_f1_known_answers():
    true = np.array([0] * 10 + [1] * 10 + [2] * 10)  # boundaries at 10 and 20
    pred = np.array([0] * 12 + [1] * 5 + [3] * 3 + [2] * 10)  # boundaries at 12, 17, 20
    assert boundary_f1(pred, true, tolerance_frames=2) == pytest.approx(2 * (2 / 3) * 1 / (2 / 3 + 1))
    assert boundary_f1(pred, true, tolerance_frames=1) == pytest.approx(2 * (1 / 3) * (1 / 2) / (1 / 3 + 1 / 2))
    # one-to-one: two predicted boundaries near one true boundary count once
    assert boundary_f1(np.array([0, 1, 2, 2]), np.array([0, 0, 1, 1]), tolerance_frames=1) == pytest.approx(2 / 3)


def test_boundary_f1_without_boundaries():
    assert boundary_f1(np.zeros(5), np.ones(5), tolerance_frames=0) == 1.0
    assert boundary_f1(np.array([0, 0, 1]), np.zeros(3), tolerance_frames=3) == 0.0
    assert boundary_f1(np.zeros(3), np.array([0, 0, 1]), tolerance_frames=3) == 0.0


@pytest.mark.parametrize(
    "pred, true, message",
    [
        ([], [], "empty"),
        ([np.zeros(3)], [np.zeros(3), np.zeros(3)], "1 predicted and 2 true"),
        (np.zeros(3), np.zeros(4), "3 predicted labels for 4 frames"),
        (np.zeros((2, 3)), np.zeros((2, 3)), "1-D"),
        ([np.zeros((2, 2))], [np.zeros((2, 2))], "1-D"),
        ([np.zeros(0)], [np.zeros(0)], "no frames"),
    ],
)
def test_bad_input(pred, true, message):
    for metric in (hungarian_frame_accuracy, many_to_one_frame_accuracy, edit_score, lambda p, t: boundary_f1(p, t, 1)):
        with pytest.raises(InvalidInputError, match=message):
            metric(pred, true)


def test_bad_tolerance():
    for tolerance in (-1, 1.5, True):
        with pytest.raises(InvalidInputError, match="tolerance_frames"):
            boundary_f1(np.zeros(3), np.zeros(3), tolerance)
