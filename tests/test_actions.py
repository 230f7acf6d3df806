"""The action level: whole runs joined along each segmentation, direction-normalised signatures, pooling."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import MANIPULATION, PrimitiveDiscovery
from hoap_actions.primitives.models.whole_actions import SIGNATURE_POINTS, action_level, run_signature, whole_runs


def straight_run(heading: float, length: float = 0.1, lift: float = 0.0, frames: int = 60) -> np.ndarray:
    """Object poses of a straight slide (or a carry lifted by ``lift`` m at mid-way) along ``heading``."""
    s = np.linspace(0.0, 1.0, frames)
    xy = np.outer(s * length, [np.cos(heading), np.sin(heading)]) + [0.2, -0.1]
    z = 0.02 + lift * np.sin(np.pi * s)
    return np.column_stack([xy, z, np.zeros((frames, 3))])


@pytest.mark.parametrize("heading", [0.3, 1.9, -2.5, np.pi])
def test_signature_does_not_depend_on_the_direction(heading):
    np.testing.assert_allclose(run_signature(straight_run(heading), 0.05), run_signature(straight_run(0.0), 0.05),
                               atol=1e-12)


def test_signature_tells_a_carry_from_a_slide_and_a_turn_in_place():
    slide, carry = run_signature(straight_run(0.0), 0.05), run_signature(straight_run(0.0, lift=0.05), 0.05)
    lift = 0.05 * np.sin(np.pi * np.linspace(0.0, 1.0, SIGNATURE_POINTS))  # the carry's lift at each step
    expected = np.sqrt(np.sum(lift**2) / slide.size)  # only the lift entries differ
    assert np.sqrt(np.mean((slide - carry) ** 2)) == pytest.approx(expected, rel=0.02)
    turn = straight_run(0.0, length=0.0)
    turn[:, 5] = np.linspace(0.0, 1.0, len(turn))  # 1 rad about z, no displacement
    signature = run_signature(turn, 0.05)
    assert signature[-1] == 0.0 and slide[-1] == 1.0  # no net displacement: no direction
    np.testing.assert_allclose(signature[:-1].reshape(SIGNATURE_POINTS, 3)[-1], [0.0, 0.0, 0.05])


def test_signature_refuses_bad_poses():
    with pytest.raises(InvalidInputError, match=r"\(T >= 2, 6\)"):
        run_signature(np.zeros((1, 6)), 0.05)
    with pytest.raises(InvalidInputError, match="finite"):
        run_signature(np.full((5, 6), np.nan), 0.05)


@pytest.fixture(scope="module")
def small(small_demos):
    demos = small_demos
    X, lengths = np.concatenate([e.O for e in demos]), [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    return demos, PrimitiveDiscovery().fit(X, lengths, H), X, lengths


def test_whole_runs_join_each_segmentations_manipulation_pieces(small):
    demos, discovery, _, _ = small
    runs = whole_runs(discovery)
    for demo, segments in enumerate(discovery.segmentations_):
        mine = [r for r in runs if r.demo == demo]
        assert mine[0].start == 0 and mine[-1].end == demos[demo].T  # the runs tile the demonstration
        assert all(a.end == b.start for a, b in zip(mine, mine[1:]))
        kinds = [discovery.primitive_kinds_[pid] for pid, *_ in segments]
        assert [r.kind for r in mine] == [k for i, k in enumerate(kinds) if i == 0 or k != kinds[i - 1]]


def test_action_level_of_the_small_preset(small):
    """One push, one move, one rotation: three manipulation actions besides approach and remove."""
    demos, discovery, X, lengths = small
    level = action_level(discovery, X, lengths)
    assert sorted(level.kinds) == ["approach", "manipulation", "manipulation", "manipulation", "remove"]
    actions = {demos[r.demo].ground_truth.action: level.action(r) for r in level.runs if r.kind == MANIPULATION}
    assert len(set(actions.values())) == 3  # push, move and rotate apart
    everything = action_level(discovery, X, lengths, tolerance=1.0)  # a tolerance beyond every distance
    assert sorted(everything.kinds) == ["approach", "manipulation", "remove"]
    with pytest.raises(InvalidInputError, match="fitted on 4 demonstrations"):
        action_level(discovery, X[: lengths[0]], lengths[:1])
    with pytest.raises(InvalidInputError, match="tolerance"):
        action_level(discovery, X, lengths, tolerance=-1.0)
