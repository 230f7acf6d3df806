"""Comparing movements whose timing differs: DTW alignment, DTW averaging, and the error e of eq. (5).

The paper measures how far a synthesised movement is from the average of four human performances
"after time warping" (eq. 5): an RMS distance over the six 3-D markers in which timing plays no
part.  This module gives the three pieces and the choices made for each:

* :func:`dtw_path`: classic dynamic time warping, steps (1, 0), (0, 1), (1, 1), local cost the
  squared Euclidean distance between whole frames (all markers at once, so one warp serves the arm),
  minimising the summed cost.  Each row of the cost table is one vector operation (a running minimum
  of cumulative sums), so a 300 x 300 alignment of 18-D frames takes about 10-20 ms.
* :func:`warped_rms_error` (eq. 5): the alignment's squared distances are averaged **in the time of
  the reference** -- first over the query frames matched to each reference frame, then over the
  reference frames -- divided by the number of markers, and square-rooted.  Averaging plainly over
  the path's steps would let a query that lingers (repeated frames) weigh more; measured on the
  reference's clock, pauses in the query do not change e, and a smooth re-timing changes it only
  through sampling (its frames fall between the reference's).  :func:`warped_point_errors` splits
  it by marker, along the same alignment.
* :func:`dtw_average`: DTW barycentre averaging (Petitjean et al., 2011) with each repetition
  counting once per average frame.  Start from the medoid (the repetition with the least summed DTW
  cost to the others); bring every repetition onto the average's clock (:func:`warp_to`: the mean of
  its frames aligned to each average frame); replace the average by the mean of these; repeat until
  it stops moving.  For fixed alignments this is the minimiser of the summed eq. (5) errors of the
  repetitions, and a repetition that holds still longer does not pull the average towards itself.
  The result keeps the medoid's number of frames.  A frame-by-frame mean of unaligned repetitions
  would instead blur a movement performed at different speeds.

Trajectories are ``(T, D)`` arrays, or ``(T, M, 3)`` marker arrays that are flattened to ``(T, 3M)``;
distances are in the data's units (metres for the recorded demonstrations).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["dtw_average", "dtw_path", "warp_to", "warped_point_errors", "warped_rms_error"]


def _as_frames(X, name: str) -> np.ndarray:
    """A finite trajectory as float ``(T, D)``; ``(T, M, 3)`` marker arrays are flattened per frame."""
    try:
        arr = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"{name} must be a numeric (T, D) or (T, M, 3) array; got {exc}") from exc
    if arr.ndim == 3:
        arr = arr.reshape(arr.shape[0], -1)
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] < 1:
        raise InvalidInputError(f"{name} must have shape (T, D) or (T, M, 3) with T >= 1; got {np.shape(X)}")
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f"{name} must be finite (no NaN or inf)")
    return arr


def _pair(query, reference) -> tuple[np.ndarray, np.ndarray]:
    a, b = _as_frames(query, "query"), _as_frames(reference, "reference")
    if a.shape[1] != b.shape[1]:
        raise InvalidInputError(f"query and reference need the same frame size; got {a.shape[1]} and {b.shape[1]}")
    return a, b


def _squared_distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(Ta, Tb)`` squared Euclidean distances between frames, summed from per-coordinate differences.

    Differences rather than the expanded ``|a|^2 + |b|^2 - 2ab``: equal frames give exactly 0.
    """
    cost = np.zeros((a.shape[0], b.shape[0]))
    for k in range(a.shape[1]):
        diff = a[:, k, None] - b[None, :, k]
        cost += diff * diff
    return cost


def _accumulate(cost: np.ndarray) -> np.ndarray:
    """DTW table ``D[i, j] = cost[i, j] + min(D[i-1, j-1], D[i-1, j], D[i, j-1])``, one row per vector step.

    Within a row, ``D[i, j] = S[j] + min_{k <= j} (B[k] - S[k])`` with ``B[k]`` the best entry from the
    row above (diagonal or vertical step) plus ``cost[i, k]`` and ``S`` the row's cumulative cost:
    a horizontal run from ``k`` to ``j`` adds ``S[j] - S[k]``, its best start is a running minimum.
    """
    n, m = cost.shape
    acc = np.empty((n, m))
    acc[0] = np.cumsum(cost[0])
    for i in range(1, n):
        above = acc[i - 1]
        from_above = np.minimum(above, np.concatenate([[np.inf], above[:-1]])) + cost[i]
        csum = np.cumsum(cost[i])
        acc[i] = np.minimum.accumulate(from_above - csum) + csum
        # Exact where the best start is j itself (no horizontal run), free of the cumsum's rounding.
        np.minimum(acc[i], from_above, out=acc[i])
    return acc


def dtw_path(query, reference) -> tuple[np.ndarray, float]:
    """Optimal DTW alignment of ``query`` (Ta, D) to ``reference`` (Tb, D).

    Returns ``(path, cost)``: ``path`` is ``(L, 2)`` int pairs ``(i, j)`` from ``(0, 0)`` to
    ``(Ta - 1, Tb - 1)``, each step advancing ``i``, ``j`` or both by one; ``cost`` is the summed
    squared distance along it, the least over all such paths.  Ties prefer the diagonal step.
    """
    a, b = _pair(query, reference)
    cost = _squared_distances(a, b)
    acc = _accumulate(cost)
    i, j = a.shape[0] - 1, b.shape[0] - 1
    path = [(i, j)]
    while i or j:
        if i == 0:
            j -= 1
        elif j == 0:
            i -= 1
        else:
            options = (acc[i - 1, j - 1], acc[i - 1, j], acc[i, j - 1])
            step = int(np.argmin(options))
            i, j = (i - 1, j - 1) if step == 0 else (i - 1, j) if step == 1 else (i, j - 1)
        path.append((i, j))
    path_arr = np.array(path[::-1], dtype=np.int64)
    return path_arr, float(cost[path_arr[:, 0], path_arr[:, 1]].sum())


def warp_to(sequence, reference) -> np.ndarray:
    """``sequence`` on the reference's clock: frame ``j`` is the mean of the frames DTW matches to ``reference[j]``.

    Returns ``(Tb, D)``; this is the per-repetition step of :func:`dtw_average`.
    """
    a, b = _pair(sequence, reference)
    path, _ = dtw_path(a, b)
    return _mean_per_reference(a[path[:, 0]], path[:, 1], b.shape[0])


def _mean_per_reference(values: np.ndarray, ref_index: np.ndarray, n_ref: int) -> np.ndarray:
    """Mean of the rows of ``values`` (L, ...) that share each reference index 0..n_ref-1 (all are present)."""
    counts = np.bincount(ref_index, minlength=n_ref).astype(np.float64)
    sums = np.zeros((n_ref,) + values.shape[1:])
    np.add.at(sums, ref_index, values)
    return sums / counts.reshape((-1,) + (1,) * (values.ndim - 1))


def warped_point_errors(query, reference, point_dim: int = 3) -> np.ndarray:
    """RMS distance of each point (marker) between ``query`` and ``reference`` along one DTW alignment.

    Returns ``(D / point_dim,)`` values in the data's units; the alignment is of whole frames (as in
    eq. 5), so the values show which markers carry :func:`warped_rms_error`, which is the root of their
    mean square.
    """
    a, b = _pair(query, reference)
    if not isinstance(point_dim, (int, np.integer)) or point_dim < 1 or a.shape[1] % point_dim:
        raise InvalidInputError(f"point_dim must be a positive int dividing the frame size {a.shape[1]}; "
                                f"got {point_dim!r}")
    path, _ = dtw_path(a, b)
    diff = (a[path[:, 0]] - b[path[:, 1]]).reshape(len(path), -1, point_dim)
    per_reference = _mean_per_reference((diff * diff).sum(axis=2), path[:, 1], b.shape[0])
    return np.sqrt(per_reference.mean(axis=0))


def warped_rms_error(query, reference, point_dim: int = 3) -> float:
    """Eq. (5): RMS distance per point (marker) between ``query`` and ``reference`` after DTW.

    Squared frame distances along the optimal alignment are averaged over the query frames matched
    to each reference frame, then over the reference frames, and divided by the number of points per
    frame (``D / point_dim``; 6 markers for the arm).  Identical movements give 0; pauses or repeated
    frames in ``query`` leave the value unchanged; a smooth re-timing changes it only through
    sampling (frames of one movement fall between those of the other: at most half a frame's travel,
    added in quadrature).
    """
    return float(np.sqrt(np.mean(warped_point_errors(query, reference, point_dim) ** 2)))


def dtw_average(sequences: Sequence[np.ndarray], n_iter: int = 30, tol: float = 1e-9) -> np.ndarray:
    """DTW barycentre average ``(T, D)`` of repeated performances (see the module docstring).

    Starts at the medoid, so ``T`` is the medoid's frame count; stops after ``n_iter`` rounds or when
    no average frame moves by more than ``tol`` (data units).  One sequence is its own average.
    """
    seqs = [_as_frames(s, f"sequences[{k}]") for k, s in enumerate(sequences)]
    if not seqs:
        raise InvalidInputError("sequences is empty: give at least one (T, D) trajectory to average")
    if len({s.shape[1] for s in seqs}) != 1:
        raise InvalidInputError(f"all sequences need the same frame size; got {sorted({s.shape[1] for s in seqs})}")
    if not isinstance(n_iter, (int, np.integer)) or n_iter < 1:
        raise InvalidInputError(f"n_iter must be an int >= 1; got {n_iter!r}")
    n = len(seqs)
    costs = np.zeros((n, n))
    for p in range(n):
        for q in range(p + 1, n):
            costs[p, q] = costs[q, p] = dtw_path(seqs[p], seqs[q])[1]
    average = seqs[int(np.argmin(costs.sum(axis=1)))].copy()
    for _ in range(int(n_iter)):
        updated = np.mean([warp_to(s, average) for s in seqs], axis=0)
        moved = float(np.abs(updated - average).max())
        average = updated
        if moved <= tol:
            break
    return average
