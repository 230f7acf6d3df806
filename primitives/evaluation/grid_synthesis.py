"""Fig. 8 of the paper: how precisely an approach PHMM synthesises reaches to locations it never saw.

Protocol (section "Precision of Synthesized Actions from PHMMs"), on an ``approach-grid`` recording (4
repetitions at every location of a 2x2, a 3x3 and the 5x7 test grid over the 80 x 30 cm region):

* a movement is an episode's frames labelled ``approach`` (the labels pick the segment and the grid;
  models see only ``H``, 6 markers x 3-D, and the effect phi);
* phi = the object's (x, y) at the end of the approach: the place the hand reaches. The hand starts from
  the same rest pose every time, so the paper's second parameter (the hand's start) is constant here;
* the error e of eq. (5) (:func:`~hoap_actions.primitives.trajectory_metrics.warped_rms_error`) of a
  synthesis against the DTW-barycentre average of the 4 real performances at its location;
* the demonstrator's own error, leave-one-out: each repetition against the average of the other
  three, RMS over the four (the in-sample figure, each repetition inside its own average, is lower).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from hoap_actions.demonstration.datasets import N_MARKERS, Demonstrations
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.posture import PostureModel, choose_alpha
from hoap_actions.primitives.trajectory_metrics import dtw_average, warped_point_errors, warped_rms_error

__all__ = ["GridData", "SynthesisMap", "fit_grid_model", "fit_grid_posture", "grid_data", "repetition_spread",
           "synthesis_map"]

TEST_GRID = "5x7"
TIE_M = 1e-4  # errors are compared at 0.1 mm: closer than that counts as a tie


@dataclass
class GridData:
    """Approach movements by grid and location, and the test grid's references and human errors (m).

    ``cells[grid][(row, col)]`` is a list of ``(X (T, 18), phi (2,))``; ``references``, ``human`` and
    ``human_loo`` are indexed by the test grid's ``(row, col)``.
    """

    cells: dict[str, dict[tuple[int, int], list[tuple[np.ndarray, np.ndarray]]]]
    references: dict[tuple[int, int], np.ndarray]
    human: dict[tuple[int, int], float]
    human_loo: dict[tuple[int, int], float]
    marker_names: tuple[str, ...]

    @property
    def test(self) -> dict[tuple[int, int], list[tuple[np.ndarray, np.ndarray]]]:
        return self.cells[TEST_GRID]

    @property
    def shape(self) -> tuple[int, int]:
        rows, cols = zip(*self.test)
        return max(rows) + 1, max(cols) + 1

    def location(self, key: tuple[int, int], grid: str = TEST_GRID) -> np.ndarray:
        """The mean effect (object x, y) of the repetitions at ``key``."""
        return np.mean([phi for _, phi in self.cells[grid][key]], axis=0)

    @classmethod
    def from_cells(cls, cells: dict, marker_names: tuple[str, ...]) -> GridData:
        """The test grid's references (DTW averages) and the demonstrator's errors, from the movements."""
        if TEST_GRID not in cells:
            raise InvalidInputError(f"this recording has no {TEST_GRID} test grid (grids {sorted(cells)})")
        references, human, human_loo = {}, {}, {}
        for key, reps in cells[TEST_GRID].items():
            movements = [x for x, _ in reps]
            if len(movements) < 2:
                raise InvalidInputError(f"test location {key} has {len(movements)} repetition(s); the "
                                        "demonstrator's leave-one-out error needs >= 2")
            references[key] = dtw_average(movements)
            human[key] = _rms([warped_rms_error(x, references[key]) for x in movements])
            others = [dtw_average(movements[:k] + movements[k + 1:]) for k in range(len(movements))]
            human_loo[key] = _rms([warped_rms_error(x, o) for x, o in zip(movements, others)])
        return cls(cells, references, human, human_loo, marker_names)

    def as_map(self, values: dict[tuple[int, int], float]) -> np.ndarray:
        out = np.full(self.shape, np.nan)
        for key, value in values.items():
            out[key] = value
        return out


def grid_data(demos: Demonstrations) -> GridData:
    """Cut the approach movements of an ``approach-grid`` recording and build the test references."""
    if "approach" not in demos.phase_names:
        raise InvalidInputError(f"this recording has no 'approach' phase (phases {demos.phase_names}); "
                                "record one with: hoap-actions record --preset approach-grid")
    code = demos.phase_names.index("approach")
    cells: dict = {}
    for episode in demos:
        truth = episode.ground_truth
        if not truth.grid:
            raise InvalidInputError("this recording's episodes carry no grid locations; record one with: "
                                    "hoap-actions record --preset approach-grid")
        frames = np.flatnonzero(truth.labels == code)
        start, end = int(frames[0]), int(frames[-1]) + 1
        X = episode.H[start:end].reshape(end - start, -1)
        cells.setdefault(truth.grid, {}).setdefault(tuple(int(i) for i in truth.grid_index), []).append(
            (X, episode.O[end - 1, :2]))
    return GridData.from_cells(cells, tuple(demos.marker_names))


def repetition_spread(data: GridData) -> np.ndarray:
    """Per marker ``(M,)`` (m), how far a repetition strays from the others: at every test location each
    repetition against the DTW average of the other repetitions, RMS over the frames, repetitions and
    locations. People vary more in the trunk and elbow than a tightly scripted arm does."""
    squares = []
    for reps in data.test.values():
        movements = [x for x, _ in reps]
        for k, movement in enumerate(movements):
            others = dtw_average(movements[:k] + movements[k + 1:])
            squares.append(warped_point_errors(movement, others) ** 2)
    return np.sqrt(np.mean(squares, axis=0))


def _rms(values: list[float]) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def fit_grid_model(data: GridData, grid: str, **params) -> tuple[ParametricHMM, float]:
    """One PHMM (``params`` for :class:`ParametricHMM`) on every movement of ``grid``; and its fit time (s)."""
    movements = [m for reps in data.cells[grid].values() for m in reps]
    X = np.concatenate([x for x, _ in movements])
    started = time.perf_counter()
    model = ParametricHMM(**params).fit(X, [len(x) for x, _ in movements], np.array([p for _, p in movements]))
    return model, time.perf_counter() - started


def fit_grid_posture(data: GridData, grid: str) -> tuple[PostureModel, dict[float, float], float]:
    """A :class:`~hoap_actions.primitives.hmm.posture.PostureModel` on every frame of ``grid``'s movements, its
    penalty chosen by leaving out one location at a time; the errors (m) of the penalties tried; the fit
    time (s), choice included."""
    groups = [[x for x, _ in reps] for reps in data.cells[grid].values()]
    started = time.perf_counter()
    alpha, errors = choose_alpha(groups)
    model = PostureModel(alpha=alpha).fit(np.concatenate([x for group in groups for x in group]))
    return model, errors, time.perf_counter() - started


@dataclass
class SynthesisMap:
    """A model's synthesis error e (m) at every test location, per marker, and the synthesis time."""

    errors: np.ndarray          # (rows, cols)
    marker_errors: np.ndarray   # (rows, cols, markers)
    synthesis_s: float          # total wall time of the 35 syntheses

    def summary(self, data: GridData) -> dict:
        """Mean / max (cm), the map, per-marker RMS (cm), and the locations within the demonstrator's
        own error (in-sample and leave-one-out)."""
        human, loo = data.as_map(data.human), data.as_map(data.human_loo)
        markers = np.sqrt(np.mean(self.marker_errors**2, axis=(0, 1))) * 100
        return {
            "mean_cm": float(np.mean(self.errors) * 100), "max_cm": float(np.max(self.errors) * 100),
            "map_cm": np.round(self.errors * 100, 3).tolist(),
            "per_marker_cm": {n: round(float(v), 3) for n, v in zip(data.marker_names, markers, strict=True)},
            "locations_within_human": int(np.sum(self.errors <= human + TIE_M)),
            "locations_within_human_loo": int(np.sum(self.errors <= loo + TIE_M)),
            "synthesis_ms_per_movement": 1000 * self.synthesis_s / self.errors.size,
        }


def synthesis_map(model: ParametricHMM, data: GridData, posture: PostureModel | None = None) -> SynthesisMap:
    """Synthesise at every test location (its repetitions' mean effect) and score it against the reference;
    with ``posture``, the shoulder and elbow of each synthesis are the posture model's, from its hand."""
    errors = np.full(data.shape, np.nan)
    points = np.full(data.shape + (N_MARKERS,), np.nan)
    elapsed = 0.0
    for key in data.test:
        started = time.perf_counter()
        movement = model.synthesize(data.location(key))
        if posture is not None:
            movement = posture.complete(movement)
        elapsed += time.perf_counter() - started
        points[key] = warped_point_errors(movement, data.references[key])
        errors[key] = np.sqrt(np.mean(points[key] ** 2))
    return SynthesisMap(errors, points, elapsed)
