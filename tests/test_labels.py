"""Runs of equal labels: the one helper every segmentation is cut with."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.labels import runs


def test_runs_known_answer():
    assert runs(np.array([3, 3, 1, 1, 1, -1, 3])) == [(3, 0, 2), (1, 2, 5), (-1, 5, 6), (3, 6, 7)]
    assert runs([7]) == [(7, 0, 1)]
    assert runs(np.array([], dtype=int)) == []
    assert runs(["a", "a", "b"]) == [("a", 0, 2), ("b", 2, 3)]


def test_runs_give_python_ints():
    (value, start, end), = runs(np.full(4, 2, dtype=np.int16))
    assert type(value) is int and type(start) is int and type(end) is int


def test_runs_tile_the_array_and_rebuild_it():
    rng = np.random.default_rng(0)
    for _ in range(50):
        labels = rng.integers(0, 3, size=rng.integers(1, 40))
        cut = runs(labels)
        assert cut[0][1] == 0 and cut[-1][2] == len(labels)
        assert all(a[2] == b[1] and a[0] != b[0] for a, b in zip(cut, cut[1:]))
        np.testing.assert_array_equal(np.concatenate([np.full(e - s, v) for v, s, e in cut]), labels)


def test_runs_refuse_more_than_one_axis():
    with pytest.raises(InvalidInputError, match="1-D"):
        runs(np.zeros((2, 3)))
