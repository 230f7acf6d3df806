"""Unsupervised discovery of action primitives from the effect of demonstrations on an object.

This module holds the estimator, :class:`PrimitiveDiscovery`, and what it learns
(:class:`PrimitiveClass`, :class:`Segment`). It implements the section "Unsupervised Learning of
Action Primitive Classes According to the Effect on Objects" of the 2010 paper (eqs. 1-3, Figs. 4,
5, 7):

1. every object trajectory O_i (relative to its initial pose) is cut into pieces of about equal
   arc length (``spacing``); each piece becomes a Gaussian and the trajectory a left-right HMM;
2. the HMMs are merged into one joint HMM: states whose Kullback-Leibler divergence (eq. 1) is
   below ``threshold`` are merged with eqs. (2)-(3), omega = 0.5
   (:mod:`hoap_actions.primitives.hmm.gaussians`), closest pair first over all demonstrations at once
   (the paper folds them in one after the other: ``merging="fold"``);
3. every trajectory is Viterbi-decoded with the joint HMM (densities from
   :mod:`hoap_actions.primitives.hmm.hmm_math`; :mod:`hoap_actions.primitives.hmm.sparse_viterbi`, as the
   joint HMM's chains allow few transitions per state);
4. repetitions are dropped and the state strings are cut into common and unique substrings by
   longest common substring (Fig. 5, :func:`hoap_actions.primitives.discovery.substrings.find_primitives`);
5. the segmentation is carried over to the arm-marker trajectories H_i: each primitive becomes an
   equivalence class of H segments, each with its effect phi = (initial, final) 3-D location.

The choices the paper leaves open (pose metric, relative pose, rest and motion, symmetric KL,
one-to-one merging, order-free merging, approach and remove) and why: ``docs/discovery.md``.
"""

from __future__ import annotations

import hashlib
import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import Estimator, check_is_fitted
from hoap_actions.primitives.discovery.discovery_file import discovery_from_document, write_discovery
from hoap_actions.primitives.discovery.primitive_classes import (
    APPROACH,
    MANIPULATION,
    N_MARKERS,
    OBJECT_DIM,
    REMOVE,
    UNKNOWN,
    PrimitiveClass,
    Segment,
    effect_track,
    split_demonstrations,
    xyz,
)
from hoap_actions.primitives.discovery.state_clustering import cluster_pieces
from hoap_actions.primitives.discovery.substrings import find_primitives
from hoap_actions.primitives.hmm import hmm_math
from hoap_actions.primitives.hmm.gaussians import merge_gaussians, symmetric_kl_matrix
from hoap_actions.primitives.hmm.sparse_viterbi import sparse_viterbi
from hoap_actions.primitives.json_files import JsonModelFile
from hoap_actions.primitives.labels import runs

__all__ = ["APPROACH", "MANIPULATION", "MERGINGS", "REMOVE", "UNKNOWN", "PrimitiveClass", "PrimitiveDiscovery",
           "Segment", "canonical_order", "effect_track"]

logger = logging.getLogger(__name__)

FORMAT_VERSION = 2  # 2 added the hyper-parameter merging; version 1 files are the paper's fold
DEFAULT_SPACING = 0.03  # m, tuned on the paper preset (benchmarks/discovery_sweep.py)
DEFAULT_THRESHOLD = 3.0  # nats, ditto
REST_FLOOR = 0.1  # fraction of the rest tolerance below which a displacement is creep, not motion
MERGINGS = ("fold", "agglomerative")
HEADING_COS = 0.5  # cosine: motions heading more than 60 degrees apart share no state ("agglomerative")
DECODE_CELLS = 4_000_000  # frames x states decoded per batch: bounds the decoding's memory (~100 MB)

# ---------------------------------------------------------------------------------------- estimator


class PrimitiveDiscovery(JsonModelFile, Estimator):
    """Learn action primitives from object trajectories (and their equivalence classes in arm space).

    Parameters
    ----------
    spacing:
        Arc length (m, with rotations counted as ``rotation_radius * angle``) covered by one Gaussian
        along the moving part of a trajectory: the resolution of the quantisation. It also sets the
        rest tolerance, ``spacing / 4``, and (by default) ``reg_covar``, so the result does not
        change when the data and ``spacing`` are scaled together. Default 3 cm, tuned on the
        ``paper`` preset (5-15 cm pushes and moves, 60 degree turns; benchmarks/discovery_sweep.py).
    threshold:
        Merge two states when their symmetrised eq. (1) divergence (nats) is below this. With the
        default ``reg_covar``, two pieces of a uniform motion offset by ``f * spacing`` along it are
        ``4.8 f^2`` apart and two paths ``d * spacing`` apart across it ``24 d^2``, so the default 3
        merges pieces offset by < 0.8 spacing along and < 0.35 spacing across the motion.
    reg_covar:
        Added to the diagonal of every piece covariance (m^2; ``/ rotation_radius**2`` rad^2 on the
        rotation axes): keeps covariances SPD and is the across-motion uncertainty of the
        quantisation. ``None`` (default): ``spacing**2 / 48``, a standard deviation half the
        along-path one of a piece (``spacing / sqrt(12)``), i.e. 4.3 mm at the default spacing.
    rotation_radius:
        Metres of arc per radian of object rotation (about the object's radius).
    hand_marker:
        Which of the 6 arm markers in H (3 coordinates each) is the hand location used as the effect
        of approach and remove; default 2 (the wrist in the paper's shoulder, elbow, wrist, index
        finger, knuckle, thumb order).
    merging:
        ``"agglomerative"`` (the default: all pieces at once, independent of the order) or ``"fold"``
        (the paper's recursive fold, in the order given); module docstring.
    random_state:
        Accepted for the project's estimator contract; the procedure is deterministic and draws nothing.

    Attributes (after ``fit``)
    --------------------------
    joint_means_, joint_covars_:
        ``(K, 6)`` and ``(K, 6, 6)``: the joint HMM's Gaussians over the relative pose (m, rad).
    joint_at_rest_:
        ``(K,)`` bool: the state models the object at rest.
    transmat_, startprob_:
        ``(K, K)`` and ``(K,)``: the joint HMM's redirected left-right transitions and start states.
    state_sequences_:
        Per trajectory, the Viterbi state string with repetitions removed.
    primitives_, primitive_kinds_:
        Per primitive id: its tuple of joint states, and ``"approach"``, ``"manipulation"`` or
        ``"remove"``. For approach and remove the tuple lists every rest state decoded as that part
        (the object rests in different places), not a substring.
    segmentations_:
        Per trajectory, ``(primitive_id, start_frame, end_frame)`` ints with ``end_frame`` exclusive,
        tiling all frames.
    classes_:
        Per primitive id, a :class:`PrimitiveClass`: the H segments and their effects phi.

    Saved as JSON (:meth:`save`, ``kind`` "PrimitiveDiscovery", ``format_version`` :data:`FORMAT_VERSION`):
    ``params`` (as :meth:`get_params`) and every learned attribute under its name without the ``_``.
    """

    _learned = ("joint_means_", "joint_covars_", "joint_at_rest_", "transmat_", "startprob_", "state_sequences_",
                "primitives_", "primitive_kinds_", "segmentations_", "classes_")
    _file_kind = "PrimitiveDiscovery"
    _format_version = FORMAT_VERSION
    _readable_versions = (1, FORMAT_VERSION)

    def __init__(
        self,
        spacing: float = DEFAULT_SPACING,
        threshold: float = DEFAULT_THRESHOLD,
        reg_covar: float | None = None,
        rotation_radius: float = 0.05,
        hand_marker: int = 2,
        merging: str = "agglomerative",
        random_state: int | np.random.Generator | None = None,
    ) -> None:
        self.spacing = spacing
        self.threshold = threshold
        self.reg_covar = reg_covar
        self.rotation_radius = rotation_radius
        self.hand_marker = hand_marker
        self.merging = merging
        self.random_state = random_state

    # -- parameters

    @property
    def rest_tolerance(self) -> float:
        """Displacement (m) below which the object counts as at rest: ``spacing / 4``."""
        return self.spacing / 4.0

    @property
    def covariance_floor(self) -> float:
        """The ``reg_covar`` in use (m^2): as given, or ``spacing**2 / 48`` when it is ``None``."""
        return self.spacing**2 / 48.0 if self.reg_covar is None else self.reg_covar

    def _check_params(self) -> None:
        for name in ("spacing", "threshold", "reg_covar", "rotation_radius"):
            value = getattr(self, name)
            if name == "reg_covar" and value is None:
                continue
            if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and value > 0):
                raise InvalidInputError(f"{name} must be a finite number > 0, got {value!r}")
        if not (isinstance(self.hand_marker, (int, np.integer)) and 0 <= self.hand_marker < N_MARKERS):
            raise InvalidInputError(f"hand_marker must be an int in [0, {N_MARKERS}), got {self.hand_marker!r}")
        if self.merging not in MERGINGS:
            raise InvalidInputError(f"merging must be one of {MERGINGS}, got {self.merging!r}")

    # -- fit

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None,
            H: np.ndarray | None = None) -> PrimitiveDiscovery:
        """Learn the joint HMM, the primitives and their equivalence classes.

        ``X``: the demonstrations' raw object poses concatenated, ``(N, 6)`` = position (m) + rotation
        vector (rad), world frame, one fixed sampling rate; ``lengths``: the frame count of each
        demonstration (positive ints summing to ``N``), as hmmlearn takes sequences. ``H``: optional
        matching arm markers ``(N, 18)`` (6 markers x xyz, m) for the effects of approach and remove.
        Coordinates beyond :data:`~hoap_actions.demonstration.datasets.MAX_COORDINATE_M` and rotation
        vectors longer than :data:`MAX_ROTATION_ANGLE_RAD` raise InvalidInputError naming the
        demonstration, its frame and the row of ``X`` / ``H``.

        A single demonstration gives approach, one manipulation primitive (nothing to compare it
        with) and remove. A trajectory whose object never moves is one rest: all of it is approach.
        """
        self._check_params()
        objects, arms = split_demonstrations(X, lengths, H)
        prepared = [self._prepare(o) for o in objects]
        order = (canonical_order(objects, [cuts for _, cuts in prepared]) if self.merging == "agglomerative"
                 else list(range(len(objects))))
        objects = [objects[i] for i in order]
        arms = None if arms is None else [arms[i] for i in order]
        relative, pieces = zip(*(prepared[i] for i in order))
        if self.merging == "agglomerative":
            self._cluster_joint_hmm(relative, pieces)
        else:
            self._build_joint_hmm(relative, pieces)
        decoded = self._decode(relative, pieces)
        self.state_sequences_ = [tuple(states) for states, _ in decoded]

        middles, lead, trail = [], [], []
        for states, _ in decoded:
            first, last = self._rest_bounds(states)
            lead.append(first)
            trail.append(last)
            middles.append(states[first:last])
        motion_primitives, motion_labels = find_primitives(middles)
        self._assign_primitives(decoded, lead, trail, motion_primitives, motion_labels)
        self.classes_ = self._make_classes(objects, arms, order)
        given = np.argsort(order)  # from the order worked in back to the caller's
        self.state_sequences_ = [self.state_sequences_[k] for k in given]
        self.segmentations_ = [self.segmentations_[k] for k in given]
        logger.info(
            "discovered %d primitives from %d demonstrations (%d joint states)",
            len(self.primitives_),
            len(objects),
            len(self.joint_means_),
        )
        return self

    def relative_trajectories(self, X: np.ndarray, lengths: Sequence[int]) -> list[np.ndarray]:
        """Raw object poses ``X`` ``(N, 6)`` of demonstrations of ``lengths`` frames as :meth:`fit` models
        them: one ``(T_i, 6)`` array per demonstration, relative to its initial rest pose (m, rad)."""
        self._check_params()
        return [self._prepare(o)[0] for o in split_demonstrations(X, lengths)[0]]

    def motion_spans(self, X: np.ndarray, lengths: Sequence[int]) -> list[tuple[np.ndarray, int, int]]:
        """Per demonstration of raw object poses ``X`` ``(N, 6)`` and ``lengths``: its trajectory relative
        to the initial rest (as :meth:`relative_trajectories`), the first moving frame and the first frame
        of the final rest, as :meth:`fit` cuts them (both the length for an object that never moves)."""
        self._check_params()
        spans = []
        for poses in split_demonstrations(X, lengths)[0]:
            relative, cuts = self._prepare(poses)
            moving, resting = (cuts[0][1], cuts[-1][0]) if len(cuts) > 1 else (len(poses), len(poses))
            spans.append((relative, moving, resting))
        return spans

    def _prepare(self, poses: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int, bool]]]:
        """The trajectory relative to its initial rest pose, and its pieces."""
        cuts = self._cut(self._relative(poses, 1))
        return self._relative(poses, cuts[0][1]), cuts

    def _relative(self, poses: np.ndarray, n_rest: int) -> np.ndarray:
        """Pose relative to the mean of the first ``n_rest`` frames (the initial state, averaged over noise).

        Position difference; rotation ``R_t R_ref^-1`` as a rotation vector.
        """
        rotations = Rotation.from_rotvec(poses[:, 3:])
        reference = rotations[:n_rest].mean()
        relative_rotation = (rotations * reference.inv()).as_rotvec()
        return np.hstack([poses[:, :3] - poses[:n_rest, :3].mean(axis=0), relative_rotation])

    def _distance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The pose metric ``|dp| + rotation_radius |dr|`` (m), broadcast over rows."""
        d = a - b
        return np.linalg.norm(d[..., :3], axis=-1) + self.rotation_radius * np.linalg.norm(d[..., 3:], axis=-1)

    def _cut(self, rel: np.ndarray) -> list[tuple[int, int, bool]]:
        """Pieces ``(start, end, at_rest)`` covering the trajectory: leading rest, motion, trailing rest."""
        n = len(rel)
        lead = self._rest_length(rel)
        if lead == n:
            return [(0, n, True)]
        rest_start = max(n - self._rest_length(rel[::-1]), lead)
        return [(0, lead, True), *self._cut_motion(rel, lead, rest_start), (rest_start, n, True)]

    def _rest_length(self, rel: np.ndarray) -> int:
        """How many leading frames the object rests: up to the first frame farther than ``rest_tolerance``
        from the mean of the frames before it, walked back to where the displacement starts to grow.

        The walk back stops at displacements within ``REST_FLOOR * rest_tolerance`` of the rest: a
        settling object creeps by micrometres, monotonically in noise-free data, and that is rest.
        """
        n = len(rel)
        means = np.cumsum(rel, axis=0)[:-1] / np.arange(1, n)[:, None]  # mean of frames [0, t), t = 1..n-1
        exceed = np.flatnonzero(self._distance(rel[1:], means) > self.rest_tolerance)
        if len(exceed) == 0:
            return n
        first_away = int(exceed[0]) + 1
        displacement = self._distance(rel[:first_away], means[first_away - 1])
        floor = REST_FLOOR * self.rest_tolerance
        last_rest = first_away - 1
        while last_rest > 0 and displacement[last_rest] > max(floor, displacement[last_rest - 1]):
            last_rest -= 1
        return last_rest + 1

    def _cut_motion(self, rel: np.ndarray, start: int, end: int) -> list[tuple[int, int, bool]]:
        """Cut frames ``[start, end)`` every ``spacing`` of dead-banded arc length from frame ``start - 1``.

        The dead band makes the arc length sequential (the anchor moves only when a step exceeds the
        tolerance), so it runs on Python floats: numpy calls on one frame at a time cost far more.
        """
        if end <= start:
            return []
        tol, radius = self.rest_tolerance, self.rotation_radius
        positions, rotations = rel[start - 1 : end, :3].tolist(), rel[start - 1 : end, 3:].tolist()
        progress = np.empty(end - start)
        anchor_p, anchor_r, anchor_progress = positions[0], rotations[0], 0.0
        for k in range(end - start):
            p, r = positions[k + 1], rotations[k + 1]
            step = math.dist(p, anchor_p) + radius * math.dist(r, anchor_r)
            progress[k] = anchor_progress + step
            if step > tol:
                anchor_p, anchor_r, anchor_progress = p, r, progress[k]
        progress = np.maximum.accumulate(progress)
        n_pieces = max(1, int(np.floor(progress[-1] / self.spacing + 0.5)))
        index = np.minimum(np.floor(progress / self.spacing).astype(int), n_pieces - 1)
        return [(start + a, start + b, False) for _, a, b in runs(index)]

    def _build_joint_hmm(self, relative: list[np.ndarray], pieces: list[list[tuple[int, int, bool]]]) -> None:
        """Fold the per-trajectory left-right HMMs into the joint HMM (paper's recursive merge)."""
        reg = self.covariance_floor * np.array([1.0, 1.0, 1.0] + [self.rotation_radius**-2] * 3)
        means = np.empty((0, OBJECT_DIM))
        covs = np.empty((0, OBJECT_DIM, OBJECT_DIM))
        at_rest = np.empty(0, dtype=bool)
        mass = np.zeros((0, 0))
        start_counts = np.zeros(0)
        for rel, cuts in zip(relative, pieces):
            new_means = np.array([rel[a:b].mean(axis=0) for a, b, _ in cuts])
            new_covs = np.array([np.cov(rel[a:b], rowvar=False, bias=True).reshape(6, 6) for a, b, _ in cuts])
            new_covs += np.diag(reg)
            new_rest = np.array([r for _, _, r in cuts], dtype=bool)
            mapping = np.full(len(cuts), -1)
            if len(means):
                rows, cols = self._merge_pairs(means, covs, at_rest, new_means, new_covs, new_rest)
                if len(rows):
                    means[rows], covs[rows] = merge_gaussians(means[rows], covs[rows], new_means[cols], new_covs[cols])
                    mapping[cols] = rows
            fresh = np.flatnonzero(mapping < 0)
            mapping[fresh] = len(means) + np.arange(len(fresh))
            means = np.vstack([means, new_means[fresh]])
            covs = np.concatenate([covs, new_covs[fresh]])
            at_rest = np.concatenate([at_rest, new_rest[fresh]])
            mass = np.pad(mass, ((0, len(fresh)), (0, len(fresh))))
            start_counts = np.pad(start_counts, (0, len(fresh)))
            _add_chain(mass, start_counts, mapping)
        self.joint_means_ = means
        self.joint_covars_ = covs
        self.joint_at_rest_ = at_rest
        self.transmat_ = mass / mass.sum(axis=1, keepdims=True)
        self.startprob_ = start_counts / start_counts.sum()

    def _cluster_joint_hmm(self, relative: Sequence[np.ndarray], pieces: Sequence[list[tuple[int, int, bool]]]) -> None:
        """The joint HMM from all pieces merged at once (``merging="agglomerative"``, module docstring)."""
        reg = self.covariance_floor * np.array([1.0, 1.0, 1.0] + [self.rotation_radius**-2] * 3)
        spans = [(rel, a, b) for rel, cuts in zip(relative, pieces) for a, b, _ in cuts]
        means = np.array([rel[a:b].mean(axis=0) for rel, a, b in spans])
        covs = np.array([np.cov(rel[a:b], rowvar=False, bias=True).reshape(6, 6) for rel, a, b in spans]) + np.diag(reg)
        at_rest = np.array([r for cuts in pieces for _, _, r in cuts], dtype=bool)
        demo = np.repeat(np.arange(len(pieces)), [len(cuts) for cuts in pieces])
        heading = np.zeros((len(pieces), 2))
        for k, (rel, cuts) in enumerate(zip(relative, pieces)):
            step = rel[cuts[-1][0], :2] - rel[max(cuts[0][1] - 1, 0), :2]  # over the motion, horizontally
            if np.linalg.norm(step) > self.spacing:
                heading[k] = step / np.linalg.norm(step)
        cosine = heading[demo] @ heading[demo].T
        turning = ~heading[demo].any(axis=1)  # no clear heading: a turn, or a short motion
        allowed = ((at_rest[:, None] == at_rest[None, :]) & (demo[:, None] != demo[None, :])
                   & ((cosine > HEADING_COS) | turning[:, None] | turning[None, :]))
        label, self.joint_means_, self.joint_covars_ = cluster_pieces(means, covs, allowed, self.threshold)
        n = len(self.joint_means_)
        self.joint_at_rest_ = np.zeros(n, dtype=bool)
        self.joint_at_rest_[label] = at_rest
        mass, start_counts = np.zeros((n, n)), np.zeros(n)
        for mapping in np.split(label, np.cumsum([len(cuts) for cuts in pieces])[:-1]):
            _add_chain(mass, start_counts, mapping)
        self.transmat_ = mass / mass.sum(axis=1, keepdims=True)
        self.startprob_ = start_counts / start_counts.sum()

    def _merge_pairs(
        self,
        means: np.ndarray,
        covs: np.ndarray,
        at_rest: np.ndarray,
        new_means: np.ndarray,
        new_covs: np.ndarray,
        new_rest: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Joint/new state pairs to merge: below threshold, same kind (rest/motion), one-to-one."""
        divergence = symmetric_kl_matrix(means, covs, new_means, new_covs)
        allowed = (divergence < self.threshold) & (at_rest[:, None] == new_rest[None, :])
        if not allowed.any():
            return np.empty(0, int), np.empty(0, int)
        # a forbidden pair costs more than any set of allowed ones: merge as many as possible, then closest
        forbidden_cost = self.threshold * (min(allowed.shape) + 1)
        rows, cols = linear_sum_assignment(np.where(allowed, divergence, forbidden_cost))
        keep = allowed[rows, cols]
        return rows[keep], cols[keep]

    def _decode(
        self, relative: Sequence[np.ndarray], pieces: Sequence[list[tuple[int, int, bool]]]
    ) -> list[tuple[list[int], list[tuple[int, int]]]]:
        """Viterbi paths as run-length encoded ``(states, frame ranges)``, repetitions removed.

        Rest frames (as cut) are decoded by rest states, moving frames by motion states (module
        docstring), in batches of at most :data:`DECODE_CELLS` frame-state cells to bound the memory.
        """
        with np.errstate(divide="ignore"):
            log_start, log_trans = np.log(self.startprob_), np.log(self.transmat_)
        frames_per_batch = max(1, DECODE_CELLS // len(self.joint_means_))
        batch_of = np.cumsum([len(r) for r in relative]) // frames_per_batch  # a long sequence may make its own
        encoded = []
        for _, first, end in runs(batch_of):
            encoded += self._decode_batch(list(relative[first:end]), list(pieces[first:end]), log_start, log_trans)
        return encoded

    def _decode_batch(
        self,
        relative: list[np.ndarray],
        pieces: list[list[tuple[int, int, bool]]],
        log_start: np.ndarray,
        log_trans: np.ndarray,
    ) -> list[tuple[list[int], list[tuple[int, int]]]]:
        """:meth:`_decode` for one batch of sequences."""
        X = np.concatenate(relative)
        lengths = np.array([len(r) for r in relative])
        at_rest = np.concatenate([np.repeat([r for _, _, r in cuts], [b - a for a, b, _ in cuts]) for cuts in pieces])
        log_frameprob = hmm_math.log_gaussian_density(X, self.joint_means_, self.joint_covars_, "full")
        masked = np.where(at_rest[:, None] == self.joint_at_rest_[None, :], log_frameprob, -np.inf)
        best, path = sparse_viterbi(log_start, log_trans, masked, lengths)
        if not np.isfinite(best).all():  # a kind of part the model never saw (e.g. motion, all demos still)
            impossible = np.repeat(~np.isfinite(best), lengths)
            path[impossible] = sparse_viterbi(log_start, log_trans, log_frameprob, lengths)[1][impossible]
        encoded = []
        for seq_path in np.split(path, np.cumsum(lengths)[:-1]):
            states = runs(seq_path)
            encoded.append(([state for state, _, _ in states], [(start, end) for _, start, end in states]))
        return encoded

    def _rest_bounds(self, states: Sequence[int]) -> tuple[int, int]:
        """``(first, last)``: ``states[:first]`` is the leading rest run, ``states[last:]`` the trailing one."""
        rest = self.joint_at_rest_[np.asarray(states, int)]
        first = int(np.argmin(rest)) if not rest.all() else len(states)
        if first == len(states):
            return first, first
        last = len(states) - int(np.argmin(rest[::-1]))
        return first, last

    def _assign_primitives(
        self,
        decoded: list[tuple[list[int], list[tuple[int, int]]]],
        lead: list[int],
        trail: list[int],
        motion_primitives: list[tuple[int, ...]],
        motion_labels: list[list[int]],
    ) -> None:
        """Number approach, manipulation and remove primitives by first appearance; segment every demo."""
        keys: dict[tuple[str, int], int] = {}
        kinds: list[str] = []
        rest_states: dict[str, list[int]] = {APPROACH: [], REMOVE: []}
        segmentations = []

        def primitive_id(kind: str, motion_index: int) -> int:
            key = (kind, motion_index)
            if key not in keys:
                keys[key] = len(kinds)
                kinds.append(kind)
            return keys[key]

        for (states, frames), first, last, labels in zip(decoded, lead, trail, motion_labels):
            segments = []
            if first > 0:
                rest_states[APPROACH].extend(states[:first])
                segments.append((primitive_id(APPROACH, -1), frames[0][0], frames[first - 1][1]))
            position = first
            for label in labels:
                length = len(motion_primitives[label])
                start, end = frames[position][0], frames[position + length - 1][1]
                segments.append((primitive_id(MANIPULATION, label), start, end))
                position += length
            if last < len(states):
                rest_states[REMOVE].extend(states[last:])
                segments.append((primitive_id(REMOVE, -1), frames[last][0], frames[-1][1]))
            segmentations.append(segments)
        primitives: list[tuple[int, ...]] = [()] * len(kinds)
        for (kind, motion_index), pid in keys.items():
            if kind == MANIPULATION:
                primitives[pid] = motion_primitives[motion_index]
            else:  # the rest states of all demos, in order of first appearance
                primitives[pid] = tuple(dict.fromkeys(rest_states[kind]))
        self.primitives_ = primitives
        self.primitive_kinds_ = kinds
        self.segmentations_ = segmentations

    def _make_classes(self, objects: list[np.ndarray], arms: list[np.ndarray] | None,
                      order: Sequence[int]) -> list[PrimitiveClass]:
        """Step 5: the equivalence class of H segments of each primitive, with effects phi; ``order[k]``
        is the caller's index of the k-th demonstration worked in (segments name the caller's)."""
        members: list[list[Segment]] = [[] for _ in self.primitives_]
        marker = slice(3 * self.hand_marker, 3 * self.hand_marker + 3)
        for demo, segments in enumerate(self.segmentations_):
            for pid, start, end in segments:
                track, source = effect_track(self.primitive_kinds_[pid], objects[demo],
                                             None if arms is None else arms[demo][:, marker])
                members[pid].append(Segment(int(order[demo]), start, end, xyz(track[start]), xyz(track[end - 1]),
                                            source))
        return [
            PrimitiveClass(pid, kind, states, tuple(segments))
            for pid, (kind, states, segments) in enumerate(zip(self.primitive_kinds_, self.primitives_, members))
        ]

    # -- use

    def predict(self, X: np.ndarray, lengths: Sequence[int] | None = None) -> list[np.ndarray]:
        """Per-frame primitive ids of new demonstrations: one ``(T_i,)`` int array per demonstration.

        ``X`` and ``lengths`` are raw object poses ``(N, 6)`` and frame counts, as :meth:`fit` takes
        them. The result is split per demonstration because every use of it is (cutting each into
        segments with :func:`hoap_actions.primitives.labels.runs`, comparing with ``segmentations_``);
        ``np.concatenate`` gives hmmlearn's ``(N,)``.

        Frames are Viterbi-decoded with the joint HMM; rest runs at the ends are approach / remove and
        the states between are parsed left to right into the longest known manipulation primitive.
        Frames whose states start no known primitive are labelled ``UNKNOWN`` (-1).
        """
        check_is_fitted(self)
        objects, _ = split_demonstrations(X, lengths)
        relative, pieces = zip(*(self._prepare(o) for o in objects))
        decoded = self._decode(relative, pieces)
        ids = {kind: self.primitive_kinds_.index(kind) for kind in (APPROACH, REMOVE) if kind in self.primitive_kinds_}
        motion = [(p, pid) for pid, p in enumerate(self.primitives_) if self.primitive_kinds_[pid] == MANIPULATION]
        motion.sort(key=lambda item: -len(item[0]))
        labels = []
        for (states, frames), obj in zip(decoded, objects):
            out = np.full(len(obj), UNKNOWN, dtype=int)
            first, last = self._rest_bounds(states)
            for kind, span in ((APPROACH, range(first)), (REMOVE, range(last, len(states)))):
                for k in span:
                    out[frames[k][0] : frames[k][1]] = ids.get(kind, UNKNOWN)
            position = first
            while position < last:
                match = next(
                    ((p, pid) for p, pid in motion if tuple(states[position : position + len(p)]) == p), ((), UNKNOWN)
                )
                length = max(1, len(match[0]))
                out[frames[position][0] : frames[position + length - 1][1]] = match[1]
                position += length
            labels.append(out)
        return labels

    # -- persistence

    def _write(self, path: Path, overwrite: bool) -> None:
        write_discovery(self, path, overwrite)

    @classmethod
    def _from_file(cls, path: Path, document: dict[str, Any], version: int) -> PrimitiveDiscovery:
        return discovery_from_document(cls, path, document, version)



# -------------------------------------------------------------------------------------- validation


def _add_chain(mass: np.ndarray, start_counts: np.ndarray, mapping: np.ndarray) -> None:
    """Count one demonstration's chain of joint states ``mapping``: a uniform left-right chain (stay or
    advance with 1/2 each, the last state only stays) and its start."""
    start_counts[mapping[0]] += 1.0
    np.add.at(mass, (mapping[:-1], mapping[:-1]), 0.5)
    np.add.at(mass, (mapping[:-1], mapping[1:]), 0.5)
    mass[mapping[-1], mapping[-1]] += 1.0


def canonical_order(objects: Sequence[np.ndarray], pieces: Sequence[list[tuple[int, int, bool]]]) -> list[int]:
    """The order in which ``merging="agglomerative"`` numbers states and primitives, whatever order the
    demonstrations come in: most motion pieces first, ties broken by a digest of the raw poses (so only
    identical demonstrations tie, and their order cannot matter)."""
    digests = [hashlib.sha256(np.ascontiguousarray(o, dtype=np.float64).tobytes()).hexdigest() for o in objects]
    motion = [sum(not at_rest for _, _, at_rest in cuts) for cuts in pieces]
    return sorted(range(len(objects)), key=lambda i: (-motion[i], digests[i]))
