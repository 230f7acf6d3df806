"""An approach's goal read from the manipulation that followed it: the training ends grouped by what came next,
the place chosen at the seen block, and the tracker's score of it."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.models.shipped import load_default_models
from hoap_actions.primitives.models.approach_ends import approach_ends_by_following_class
from hoap_actions.tracking import track_markers_episode
from hoap_actions.tracking.approach_goal import read_approach_end

Segment = SimpleNamespace


def fake_discovery():
    """Approaches in demos 0, 1 and 2, then what discovery cut after them: demo 1 performs two pieces and then
    approaches again; demo 2's approach ends it."""
    segments = [Segment(demo=0, end=10), Segment(demo=1, end=8), Segment(demo=2, end=5), Segment(demo=1, end=25)]
    approach = SimpleNamespace(primitive_id=0, kind="approach", segments=segments)
    pieces = [SimpleNamespace(primitive_id=pid, kind=kind, segments=[])
              for pid, kind in ((7, "manipulation"), (9, "manipulation"), (2, "remove"))]
    return SimpleNamespace(classes_=[approach, *pieces], segmentations_=[
        [(0, 0, 10), (7, 10, 20), (2, 20, 30)],
        [(0, 0, 8), (9, 8, 12), (7, 12, 15), (2, 15, 20), (0, 20, 25), (9, 25, 30)],
        [(0, 0, 5)],
    ])


def test_the_training_ends_are_grouped_by_the_pieces_that_followed_each_approach():
    ends = np.arange(12.0).reshape(4, 3)
    grouped = approach_ends_by_following_class(fake_discovery(), ends)
    assert sorted(grouped) == [7, 9]  # the remove is no manipulation; demo 2's approach is followed by nothing
    np.testing.assert_array_equal(grouped[7], ends[:2])  # demo 1's first approach: 9, then 7, up to its next approach
    np.testing.assert_array_equal(grouped[9], ends[[1, 3]])
    with pytest.raises(InvalidInputError, match=r"ends must be \(4, 3\)"):
        approach_ends_by_following_class(fake_discovery(), ends[:2])


def test_every_shipped_approach_led_into_a_manipulation():
    models = load_default_models()
    grouped = approach_ends_by_following_class(models.discovery_, models.approach_ends_)
    assert sum(len(ends) for ends in grouped.values()) >= len(models.approach_ends_)
    assert all(models.classes_[cid].kind == "manipulation" for cid in grouped)
    rows = {tuple(end) for ends in grouped.values() for end in ends}
    assert rows == {tuple(end) for end in models.approach_ends_}  # every approach led into a manipulation


def test_the_place_nearest_the_estimate_is_read_at_the_seen_block():
    places = {5: np.array([[-0.08, 0.04, 0.06], [-0.08, -0.04, 0.06]])}
    block = np.array([0.10, 0.20, 0.025])
    np.testing.assert_allclose(read_approach_end(np.array([0.0, 0.17, 0.10]), 5, block, places), [0.02, 0.16, 0.06])
    np.testing.assert_allclose(read_approach_end(np.array([0.0, 0.23, 0.10]), 5, block, places), [0.02, 0.24, 0.06])
    estimate = np.array([0.3, 0.3, 0.3])
    for following, seen in ((None, block), (6, block), (5, None)):  # nothing followed, no places, no block: as is
        np.testing.assert_array_equal(read_approach_end(estimate, following, seen, places), estimate)


def test_a_track_scores_the_goal_read_from_the_task(small_demos):
    """With the true end as the only place of every manipulation, the read goal is exact; without places or
    sightings there is no such figure."""
    models = load_default_models()
    result = track_markers_episode(models, small_demos, 0, particles=100, seed=0)
    summary = result.summary()
    assert summary["approaches"] == 1 and 0 <= summary["approaches_read_from_task"] <= 1
    assert summary["read_from_task_error_m"] >= 0.0
    (_, end, target), = result.approach_ends
    block = result.objects_seen[end - 1]
    exact = {cid: np.array([[target[0] - block[0], target[1] - block[1], target[2]]])
             for cid, c in models.classes_.items() if c.kind == "manipulation"}
    told = dataclasses.replace(result, approach_places=exact).summary()
    assert told["approaches_read_from_task"] == 1 and told["read_from_task_error_m"] == pytest.approx(0.0, abs=1e-12)
    for missing in ({"approach_places": {}}, {"objects_seen": []}):
        assert "approaches_read_from_task" not in dataclasses.replace(result, **missing).summary()
