"""effect_gap_scores: known answers, the pieces of one push decoded by their joined-up effects, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.models.effect_continuity import effect_gap_scores


def test_known_gaps():
    final = {"push-1": np.array([0.10, 0.0, 0.0]), "push-2": np.array([0.13, 0.0, 0.0])}
    initial = {"push-2": np.array([0.10, 0.0, 0.0]), "push-3": np.array([0.13, 0.02, 0.0])}
    scores = effect_gap_scores(final, initial, weight=1e6)
    assert scores[("push-1", "push-2")] == 0.0
    assert scores[("push-1", "push-3")] == pytest.approx(-1e6 * (0.03 ** 2 + 0.02 ** 2))
    assert scores[("push-2", "push-2")] == pytest.approx(-1e6 * 0.03 ** 2)
    assert scores[("push-2", "push-3")] == pytest.approx(-1e6 * 0.02 ** 2)
    assert len(scores) == 4


def test_classes_without_an_estimate_are_left_out():
    scores = effect_gap_scores({"a": [0.0, 0.0], "b": [np.nan, np.nan]}, {"c": [0.01, 0.0]}, weight=2.0)
    assert scores == {("a", "c"): pytest.approx(-2e-4)}
    assert effect_gap_scores({}, {"c": [0.0, 0.0]}, weight=1.0) == {}


def test_gaps_pick_the_pieces_whose_effects_join_up():
    """Two pieces that look alike to their models: the grammar allows 1 -> 2 and 1 -> 3, the segment
    scores prefer 3 slightly, but only piece 2's initial location continues where piece 1 ended."""
    grammar = ActionGrammar().fit([["approach", "push-1", "push-2", "remove"],
                                   ["approach", "push-1", "push-3", "remove"]])
    scores = [{"approach": 0.0}, {"push-1": 0.0}, {"push-2": -2.0, "push-3": 0.0}, {"remove": 0.0}]
    assert grammar.decode(scores)[0][2] == "push-3"
    ends = {"push-1": np.array([0.20, 0.05, 0.02])}
    starts = {"push-2": np.array([0.201, 0.05, 0.02]), "push-3": np.array([0.23, 0.05, 0.02])}
    pairs = [{}, effect_gap_scores(ends, starts, weight=1e6), {}]
    assert grammar.decode(scores, pair_scores=pairs)[0] == ["approach", "push-1", "push-2", "remove"]


def test_bad_input():
    with pytest.raises(InvalidInputError, match="weight"):
        effect_gap_scores({"a": [0.0]}, {"b": [0.0]}, weight=-1.0)
    with pytest.raises(InvalidInputError, match="weight"):
        effect_gap_scores({"a": [0.0]}, {"b": [0.0]}, weight=float("nan"))
    with pytest.raises(InvalidInputError, match="must map"):
        effect_gap_scores([[0.0]], {"b": [0.0]}, weight=1.0)
    with pytest.raises(InvalidInputError, match="1-D"):
        effect_gap_scores({"a": [[0.0]]}, {"b": [0.0]}, weight=1.0)
    with pytest.raises(InvalidInputError, match="same kind"):
        effect_gap_scores({"a": [0.0, 0.0]}, {"b": [0.0, 0.0, 0.0]}, weight=1.0)
    with pytest.raises(InvalidInputError, match="differ in length"):
        effect_gap_scores({"a": [0.0, 0.0], "b": [0.0]}, {"c": [0.0]}, weight=1.0)
