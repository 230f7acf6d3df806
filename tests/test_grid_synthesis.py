"""The Fig. 8 protocol (grid_synthesis): references, the demonstrator's errors, error maps, known answers."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.evaluation.grid_synthesis import GridData, fit_grid_model, repetition_spread, synthesis_map

MARKERS = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")
OFFSETS = np.array([-0.003, 0.0, 0.001, 0.006])  # m, each repetition's shift across its path


def across(phi: np.ndarray) -> np.ndarray:
    """Unit vector across every marker's path to ``phi`` (horizontal, normal to the reach): a shift along
    it cannot be undone by re-timing, so DTW keeps the identity alignment and errors are exact."""
    return np.array([-phi[1], phi[0], 0.0]) / np.hypot(*phi)


def reach(phi: np.ndarray, n: int = 30) -> np.ndarray:
    """(n, 18): six markers moving in straight lines from rest towards phi (the elbow rises more at the
    region's sides), all in the vertical plane through the reach."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    s = 3 * t**2 - 2 * t**3
    end = np.array([phi[0], phi[1], 0.02])
    lift = np.array([0.0, 0.0, 0.1 * phi[1] ** 2 / 0.16])
    markers = [np.array([-0.4, 0.0, 0.3]) + 0.05 * s * end]
    markers += [np.array([-0.3, 0.1, 0.1]) + s * (end * (0.5 + 0.1 * k) + lift * (k == 0)) for k in range(5)]
    return np.hstack(markers)


def cells(grid_points: dict[str, np.ndarray]) -> dict:
    out = {}
    for grid, (xs, ys) in grid_points.items():
        out[grid] = {(r, c): [(reach(np.array([x, y])) + np.tile(o * across(np.array([x, y])), 6), np.array([x, y]))
                              for o in OFFSETS]
                     for r, x in enumerate(xs) for c, y in enumerate(ys)}
    return out


@pytest.fixture(scope="module")
def data() -> GridData:
    axes = {"2x2": (np.linspace(0.1, 0.3, 2), np.linspace(-0.4, 0.4, 2)),
            "3x3": (np.linspace(0.1, 0.3, 3), np.linspace(-0.4, 0.4, 3)),
            "5x7": (np.linspace(0.1, 0.3, 5), np.linspace(-0.4, 0.4, 7))}
    return GridData.from_cells(cells(axes), MARKERS)


def test_demonstrator_errors_have_known_values(data):
    """Repetitions shifted by OFFSETS: in-sample each is |c_k - mean(c)| from the average; left out,
    |c_k - mean of the others|."""
    in_sample = np.sqrt(np.mean((OFFSETS - OFFSETS.mean()) ** 2))
    others = np.array([np.delete(OFFSETS, k).mean() for k in range(OFFSETS.size)])
    left_out = np.sqrt(np.mean((OFFSETS - others) ** 2))
    assert left_out > in_sample
    for key in data.test:
        assert data.human[key] == pytest.approx(in_sample, abs=1e-9)
        assert data.human_loo[key] == pytest.approx(left_out, abs=1e-9)
    assert data.shape == (5, 7)


def test_repetition_spread_per_marker_is_the_left_out_shift(data):
    """Every marker of a repetition is shifted by the same OFFSETS across the path: each marker's spread
    is the leave-one-out figure of the whole frame."""
    others = np.array([np.delete(OFFSETS, k).mean() for k in range(OFFSETS.size)])
    np.testing.assert_allclose(repetition_spread(data), np.sqrt(np.mean((OFFSETS - others) ** 2)), atol=1e-9)


class _Replay:
    """A stand-in model that synthesises the reference at each location, shifted by ``shift`` (m)."""

    def __init__(self, data: GridData, shift: float) -> None:
        self.data, self.shift = data, shift

    def synthesize(self, phi):
        key = min(self.data.test, key=lambda k: np.linalg.norm(self.data.location(k) - phi))
        return self.data.references[key] + np.tile(self.shift * across(self.data.location(key)), 6)


def test_synthesis_map_known_answers(data):
    exact = synthesis_map(_Replay(data, 0.0), data)
    assert np.all(exact.errors == 0.0)
    summary = exact.summary(data)
    assert summary["locations_within_human_loo"] == 35 and summary["mean_cm"] == 0.0
    shifted = synthesis_map(_Replay(data, 0.01), data).summary(data)
    assert shifted["mean_cm"] == pytest.approx(1.0, abs=1e-9)
    assert shifted["per_marker_cm"] == {name: pytest.approx(1.0) for name in MARKERS}
    assert shifted["locations_within_human_loo"] == 0


class _UndoArmShift:
    """A stand-in posture model that puts the shoulder and elbow of a ``_Replay(data, shift)`` back."""

    def __init__(self, data: GridData, shift: float) -> None:
        self.data, self.shift = data, shift

    def complete(self, X):
        for key in self.data.test:
            shift = np.tile(self.shift * across(self.data.location(key)), 6)
            if X.shape == self.data.references[key].shape and np.allclose(X, self.data.references[key] + shift):
                out = X.copy()
                out[:, :6] -= shift[:6]
                return out
        raise AssertionError("not a replayed reference")


def test_a_posture_model_replaces_the_synthesised_shoulder_and_elbow(data):
    scored = synthesis_map(_Replay(data, 0.01), data, posture=_UndoArmShift(data, 0.01)).summary(data)
    assert scored["per_marker_cm"]["shoulder"] == pytest.approx(0.0, abs=1e-9)
    assert scored["per_marker_cm"]["elbow"] == pytest.approx(0.0, abs=1e-9)
    assert scored["per_marker_cm"]["wrist"] == pytest.approx(1.0)
    assert scored["mean_cm"] == pytest.approx(np.sqrt(4 / 6), abs=1e-9)


def test_a_bending_mean_interpolates_a_bending_reach_better(data):
    linear, _ = fit_grid_model(data, "3x3", n_states=8, reg_covar=1e-6)
    bent, _ = fit_grid_model(data, "3x3", n_states=8, reg_covar=1e-6, mean_model="tps", smoothing=1e-3)
    linear_error = synthesis_map(linear, data).errors.mean()
    bent_error = synthesis_map(bent, data).errors.mean()
    assert bent_error < 0.7 * linear_error


def test_needs_a_test_grid_with_repetitions():
    axes = {"3x3": (np.linspace(0.1, 0.3, 3), np.linspace(-0.4, 0.4, 3))}
    with pytest.raises(InvalidInputError, match="no 5x7 test grid"):
        GridData.from_cells(cells(axes), MARKERS)
    single = cells({"5x7": (np.linspace(0.1, 0.3, 5), np.linspace(-0.4, 0.4, 7))})
    single["5x7"][(0, 0)] = single["5x7"][(0, 0)][:1]
    with pytest.raises(InvalidInputError, match="1 repetition"):
        GridData.from_cells(single, MARKERS)
