"""Scores of recognition: the edit score against known answers."""

from __future__ import annotations

import pytest

from hoap_actions.primitives.pipelines.recognize import edit_score


@pytest.mark.parametrize(
    "predicted, truth, expected",
    [
        ([0, 1, 2], [0, 1, 2], 1.0),
        ([0, 2], [0, 1, 2], 1 - 1 / 3),  # one deletion
        ([0, 1, 3, 2], [0, 1, 2], 1 - 1 / 4),  # one insertion, over the longer sequence
        ([0, 5, 2], [0, 1, 2], 1 - 1 / 3),  # one substitution
        ([], [0, 1], 0.0),
        ([], [], 1.0),
        ([1, 0], [0, 1], 0.0),  # two substitutions
    ],
)
def test_edit_score_is_one_minus_levenshtein_over_the_longer_sequence(predicted, truth, expected):
    assert edit_score(predicted, truth) == pytest.approx(expected)
