"""The action level: whole approach, manipulation and remove movements, pooled across directions.

Discovery's Euclidean quantisation cuts a long push or carry into pieces by distance (P1 P2 P3) and
keeps each direction apart: fine for recognising, but a robot asked to carry a peg from S to E
anywhere on the table needs one *move*, whatever its direction and length. So, without reading any
hidden label:

1. each demonstration becomes its whole actions: the approach, the manipulation pieces joined
   along its segmentation into one run, and the remove (:func:`whole_runs`);
2. each run's object trajectory is put in a direction-normalised frame, the paper's polar
   quantisation: relative to its start, rotated about z so the net displacement points along +x,
   and sampled at :data:`SIGNATURE_POINTS` steps of progress; its signature is the lateral offset,
   the lift and the yaw change (times ``rotation_radius``, as discovery measures rotations);
3. discovery's action groups (:func:`~hoap_actions.primitives.discovery.groups.action_groups`)
   whose mean signatures lie within ``tolerance`` of each other (RMS, m) are one action (connected
   components), so pushes of every direction pool, moves pool, and the two rotations stay apart.

The default tolerance (discovery's rest tolerance) falls in the gap between the signatures of groups
of one action and those of different actions on ``paper`` recordings (``docs/experiments/recognition.md``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION, REMOVE, PrimitiveDiscovery
from hoap_actions.primitives.discovery.groups import action_groups
from hoap_actions.primitives.hmm.hmm_math import validate_sequences

__all__ = ["SIGNATURE_POINTS", "ActionLevel", "ActionRun", "action_level", "run_signature", "whole_runs"]

SIGNATURE_POINTS = 20  # steps of progress a run's direction-normalised trajectory is sampled at
MIN_NET_DISPLACEMENT = 0.01  # m: below it a run has no direction (a rotation in place) and is not turned


@dataclass(frozen=True)
class ActionRun:
    """Frames ``[start, end)`` of demonstration ``demo`` performing one whole action of kind ``kind``
    (approach, manipulation or remove); ``group`` is discovery's action group of its first piece."""

    demo: int
    start: int
    end: int
    kind: str
    group: int


@dataclass(frozen=True)
class ActionLevel:
    """Whole actions: ``runs`` of every training demonstration, each group's action ``action_of_group``
    (group id -> action id), each action's ``kinds``, and each group's mean signature."""

    runs: tuple[ActionRun, ...]
    action_of_group: dict[int, int]
    kinds: tuple[str, ...]
    signatures: dict[int, np.ndarray]

    def action(self, run: ActionRun) -> int:
        return self.action_of_group[run.group]


def whole_runs(discovery: PrimitiveDiscovery) -> list[ActionRun]:
    """Every training demonstration's approach, joined manipulation pieces and remove, in order."""
    check_is_fitted(discovery)
    groups = action_groups(discovery)
    runs = []
    for demo, segments in enumerate(discovery.segmentations_):
        current: list[tuple[int, int, int]] = []
        for pid, start, end in [*segments, (None, None, None)]:
            kind = None if pid is None else discovery.primitive_kinds_[pid]
            if current and (kind != MANIPULATION or discovery.primitive_kinds_[current[0][0]] != MANIPULATION):
                first = current[0][0]
                runs.append(ActionRun(demo, current[0][1], current[-1][2], discovery.primitive_kinds_[first],
                                      groups[first]))
                current = []
            if pid is not None:
                current.append((pid, start, end))
    return runs


def run_signature(poses: np.ndarray, rotation_radius: float) -> np.ndarray:
    """The direction-normalised shape of one run's object poses ``(T, 6)`` (position m, rotation
    vector rad): lateral offset, lift and ``rotation_radius`` x yaw change at :data:`SIGNATURE_POINTS`
    steps of progress, flattened, then 1 if the run has a net displacement (else 0)."""
    poses = np.asarray(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 6 or len(poses) < 2 or not np.all(np.isfinite(poses)):
        raise InvalidInputError(f"poses must be (T >= 2, 6) finite object poses; got shape {poses.shape}")
    relative = poses[:, :3] - poses[0, :3]
    net = relative[-1, :2]
    moves = bool(np.linalg.norm(net) > MIN_NET_DISPLACEMENT)
    heading = float(np.arctan2(net[1], net[0])) if moves else 0.0
    lateral = -np.sin(heading) * relative[:, 0] + np.cos(heading) * relative[:, 1]
    yaw = np.unwrap(Rotation.from_rotvec(poses[:, 3:]).as_euler("xyz")[:, 2])
    progress = np.linspace(0.0, len(poses) - 1.0, SIGNATURE_POINTS)
    frames = np.arange(len(poses))
    shape = [np.interp(progress, frames, v) for v in (lateral, relative[:, 2], rotation_radius * (yaw - yaw[0]))]
    return np.concatenate([np.stack(shape, axis=1).ravel(), [float(moves)]])


def action_level(discovery: PrimitiveDiscovery, X: np.ndarray, lengths: Sequence[int],
                 tolerance: float | None = None) -> ActionLevel:
    """Whole actions of the demonstrations ``discovery`` was fitted on (their object poses ``X``
    ``(N, 6)`` with ``lengths``); groups whose mean signatures are within ``tolerance`` (RMS, m;
    default the discovery's rest tolerance) of each other are one action."""
    check_is_fitted(discovery)
    X, lengths = validate_sequences(X, lengths)
    if len(lengths) != len(discovery.segmentations_):
        raise InvalidInputError(f"discovery was fitted on {len(discovery.segmentations_)} demonstrations; "
                                f"X and lengths hold {len(lengths)}: give the same ones")
    tolerance = discovery.rest_tolerance if tolerance is None else float(tolerance)
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise InvalidInputError(f"tolerance must be a finite distance >= 0 (m); got {tolerance!r}")
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    runs = whole_runs(discovery)
    members: dict[int, list[np.ndarray]] = {}
    for run in runs:
        if run.kind == MANIPULATION:
            poses = X[starts[run.demo] + run.start: starts[run.demo] + run.end]
            members.setdefault(run.group, []).append(run_signature(poses, discovery.rotation_radius))
    signatures = {g: np.mean(s, axis=0) for g, s in sorted(members.items())}
    action_of_group, kinds = {}, []
    for kind in (APPROACH, REMOVE):  # one group each: discovery puts every approach (remove) in one primitive
        for run in runs:
            if run.kind == kind and run.group not in action_of_group:
                action_of_group[run.group] = len(kinds)
                kinds.append(kind)
    for group, signature in signatures.items():  # connected components of "within tolerance"
        near = [g for g in action_of_group if g in signatures and _rms(signatures[g], signature) <= tolerance]
        if not near:
            action_of_group[group] = len(kinds)
            kinds.append(MANIPULATION)
            continue
        keep = min(action_of_group[g] for g in near)
        merged = {action_of_group[g] for g in near}
        for g, a in action_of_group.items():
            if a in merged:
                action_of_group[g] = keep
        action_of_group[group] = keep
    renumber = {a: i for i, a in enumerate(dict.fromkeys(action_of_group[g] for g in sorted(action_of_group)))}
    return ActionLevel(
        runs=tuple(runs),
        action_of_group={g: renumber[a] for g, a in action_of_group.items()},
        kinds=tuple(kinds[old] for old in renumber),
        signatures=signatures,
    )


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))
