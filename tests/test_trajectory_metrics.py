"""trajectory_metrics: DTW against brute force and hand-worked cases, eq. (5) invariances, DTW averaging."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.trajectory_metrics import (
    dtw_average,
    dtw_path,
    warp_to,
    warped_point_errors,
    warped_rms_error,
)


def all_paths(n: int, m: int):
    """Every monotone path from (0, 0) to (n-1, m-1) with steps (1, 0), (0, 1), (1, 1)."""
    if (n, m) == (1, 1):
        yield [(0, 0)]
        return
    for di, dj in ((1, 1), (1, 0), (0, 1)):
        if n - di >= 1 and m - dj >= 1:
            for path in all_paths(n - di, m - dj):
                yield path + [(n - 1, m - 1)]


def arm_curve(n: int = 80, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Six markers (n, 6, 3) on curved paths in the x-z plane (y = 0), plus ``offset``.

    Minimum-jerk progress along paths of 16-38 cm: at most 8 mm per frame at n = 80, like a reach at 100 Hz.
    """
    t = np.linspace(0.0, 1.0, n)[:, None]
    s = t**3 * (10.0 - 15.0 * t + 6.0 * t**2)
    markers = [np.hstack([0.04 * (k + 3) * s, 0.0 * s, 0.05 * np.sin(2.0 * np.pi * s + k)]) for k in range(6)]
    return np.stack(markers, axis=1) + np.asarray(offset)


# ------------------------------------------------------------------------------------------------ DTW
def test_dtw_hand_worked_path():
    a = np.array([[0.0], [1.0], [2.0]])
    b = np.array([[0.0], [0.0], [1.0], [2.0], [2.0]])
    path, cost = dtw_path(a, b)
    assert cost == 0.0
    assert path.tolist() == [[0, 0], [0, 1], [1, 2], [2, 3], [2, 4]]


def test_dtw_hand_worked_cost():
    # [0, 3] against [1, 2]: the diagonal costs 1 + 1 = 2; any path with a horizontal or vertical step costs more.
    path, cost = dtw_path([[0.0], [3.0]], [[1.0], [2.0]])
    assert cost == pytest.approx(2.0)
    assert path.tolist() == [[0, 0], [1, 1]]


@pytest.mark.parametrize("seed", range(6))
def test_dtw_matches_brute_force(seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=(rng.integers(1, 6), 2)), rng.normal(size=(rng.integers(1, 6), 2))
    best = min(sum(float(((a[i] - b[j]) ** 2).sum()) for i, j in p) for p in all_paths(len(a), len(b)))
    path, cost = dtw_path(a, b)
    assert cost == pytest.approx(best, rel=1e-12, abs=1e-12)
    steps = np.diff(path, axis=0)
    assert path[0].tolist() == [0, 0] and path[-1].tolist() == [len(a) - 1, len(b) - 1]
    assert {tuple(s) for s in steps} <= {(1, 0), (0, 1), (1, 1)}
    assert cost == pytest.approx(float(((a[path[:, 0]] - b[path[:, 1]]) ** 2).sum()))


def test_dtw_identical_is_diagonal():
    a = arm_curve()
    path, cost = dtw_path(a, a)
    assert cost == 0.0
    assert np.array_equal(path[:, 0], np.arange(len(a))) and np.array_equal(path[:, 1], np.arange(len(a)))


def test_warp_to_undoes_repeated_frames():
    b = arm_curve().reshape(80, -1)
    a = np.repeat(b, np.random.default_rng(0).integers(1, 4, size=80), axis=0)
    np.testing.assert_allclose(warp_to(a, b), b, atol=1e-12)


# ------------------------------------------------------------------------------------------ eq. (5)
def test_error_zero_for_identical():
    a = arm_curve()
    assert warped_rms_error(a, a) == 0.0


def test_error_of_constant_offset_is_the_offset():
    # Offset across the x-z plane the markers move in: DTW keeps the diagonal, every marker is 1 cm off.
    a, b = arm_curve(), arm_curve(offset=(0.0, 0.01, 0.0))
    assert warped_rms_error(a, b) == pytest.approx(0.01, rel=1e-9)
    # (T, 6, 3) and flattened (T, 18) are the same thing
    assert warped_rms_error(a.reshape(80, -1), b.reshape(80, -1)) == pytest.approx(0.01, rel=1e-9)


def test_error_is_rms_over_markers():
    a = arm_curve()
    b = a.copy()
    b[:, 2, 1] += 0.03  # only the wrist is 3 cm off
    assert warped_rms_error(a, b) == pytest.approx(0.03 / np.sqrt(6), rel=1e-9)
    # split by marker: all of it is the wrist's
    np.testing.assert_allclose(warped_point_errors(a, b), [0, 0, 0.03, 0, 0, 0], atol=1e-12)


def test_point_errors_are_the_rms_error_split_by_marker():
    # known answer: offsets across the x-z plane the markers move in keep DTW on the diagonal
    a = arm_curve()
    c = a.copy()
    c[:, 0, 1] += 0.01
    c[:, 3, 1] -= 0.02
    np.testing.assert_allclose(warped_point_errors(a, c), [0.01, 0, 0, 0.02, 0, 0], rtol=1e-9, atol=1e-12)
    assert warped_rms_error(a, c) == pytest.approx(np.sqrt((0.01**2 + 0.02**2) / 6), rel=1e-9)
    with pytest.raises(InvalidInputError):
        warped_point_errors(np.zeros((5, 4)), np.zeros((5, 4)), point_dim=3)


def test_error_invariant_to_time_warping_the_query():
    b = arm_curve(offset=(0.0, 0.01, 0.0))
    a = arm_curve()
    reference = warped_rms_error(a, b)
    assert reference == pytest.approx(0.01, rel=1e-9)
    rng = np.random.default_rng(1)
    paused = np.repeat(a, rng.integers(1, 5, size=len(a)), axis=0)          # exact re-timing: pauses
    assert warped_rms_error(paused, b) == pytest.approx(reference, rel=1e-9)
    # A smooth non-uniform re-timing, interpolated at 1.5-4x the frame rate: the query frames matched to
    # one reference frame spread over its sampling interval (up to 8 mm of travel here), which adds
    # about 1 % to a 1 cm error.
    for n_frames in (120, 160, 320):
        u = np.linspace(0.0, 1.0, n_frames) ** 1.7 * (len(a) - 1)
        flat = a.reshape(len(a), -1)
        warped = np.column_stack([np.interp(u, np.arange(len(a)), flat[:, d]) for d in range(flat.shape[1])])
        assert warped_rms_error(warped, b) == pytest.approx(reference, rel=1e-2)


def test_error_bad_input():
    with pytest.raises(InvalidInputError):
        warped_rms_error(np.zeros((5, 18)), np.zeros((5, 12)))
    with pytest.raises(InvalidInputError):
        warped_rms_error(np.full((5, 3), np.nan), np.zeros((5, 3)))
    with pytest.raises(InvalidInputError):
        warped_rms_error(np.zeros((5, 4)), np.zeros((5, 4)), point_dim=3)
    with pytest.raises(InvalidInputError):
        warped_rms_error(np.zeros((0, 3)), np.zeros((5, 3)))


# ------------------------------------------------------------------------------------------ averaging
DELAYS = (0, 4, 9, 12)
OFFSETS = (-0.01, 0.0, 0.005, 0.013)


def shifted_copies(delays=DELAYS, offsets=OFFSETS):
    """The base movement started ``delays`` frames late (held still before, and after to equal length),
    each copy moved by its ``offsets`` (m) in y, across the x-z plane the markers move in."""
    base = arm_curve(100)
    copies = []
    for delay, dy in zip(delays, offsets):
        held = [np.repeat(base[:1], delay, axis=0), base, np.repeat(base[-1:], max(delays) - delay, axis=0)]
        copies.append(np.concatenate(held) + [0.0, dy, 0.0])
    return base, copies


def test_average_of_time_shifted_copies_is_the_movement():
    base, copies = shifted_copies(offsets=(0.0,) * 4)
    average = dtw_average(copies)
    assert warped_rms_error(average, base) < 1e-12 and warped_rms_error(base, average) < 1e-12
    # the frame-by-frame mean of the unaligned copies blurs the movement
    assert warped_rms_error(np.mean(copies, axis=0), base) > 2e-3


def test_average_of_offset_copies_is_the_mean_offset():
    base, copies = shifted_copies(delays=(0,) * 4)
    target = base + [0.0, np.mean(OFFSETS), 0.0]
    assert warped_rms_error(dtw_average(copies), target) < 1e-12


def test_average_of_shifted_and_offset_copies():
    # Each copy counts once per average frame, however long it holds still: the average is exactly the
    # movement at the mean offset (a frame-pooled DBA would lean towards the copies that hold longest).
    base, copies = shifted_copies()
    target = base + [0.0, np.mean(OFFSETS), 0.0]
    average = dtw_average(copies)
    assert warped_rms_error(average, target) < 1e-12 and warped_rms_error(target, average) < 1e-12


def test_average_keeps_medoid_length_and_single_sequence():
    rng = np.random.default_rng(2)
    seqs = [rng.normal(size=(n, 3)) for n in (20, 25, 30)]
    assert dtw_average(seqs).shape[1] == 3 and dtw_average(seqs).shape[0] in (20, 25, 30)
    np.testing.assert_array_equal(dtw_average(seqs[:1]), seqs[0])


def test_average_bad_input():
    with pytest.raises(InvalidInputError):
        dtw_average([])
    with pytest.raises(InvalidInputError):
        dtw_average([np.zeros((4, 3)), np.zeros((4, 2))])
    with pytest.raises(InvalidInputError):
        dtw_average([np.zeros((4, 3))], n_iter=0)
