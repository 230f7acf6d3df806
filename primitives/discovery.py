"""Unsupervised discovery of action primitives from the effect of demonstrations on an object.

This implements the section "Unsupervised Learning of Action Primitive Classes According to the
Effect on Objects" of the 2010 paper (eqs. 1-3, Figs. 4, 5, 7):

1. every object trajectory O_i (relative to its initial pose) is cut into pieces of about equal
   arc length (``spacing``); each piece becomes a Gaussian and the trajectory a left-right HMM;
2. the HMMs are folded, one after the other, into one joint HMM: states whose Kullback-Leibler
   divergence (eq. 1) is below ``threshold`` are merged with eqs. (2)-(3), omega = 0.5;
3. every trajectory is Viterbi-decoded with the joint HMM (densities from
   :mod:`hoap_actions.primitives.hmm_math`; :func:`sparse_viterbi`, as the joint HMM's chains
   allow few transitions per state);
4. repetitions are dropped and the state strings are cut into common and unique substrings by
   longest common substring (Fig. 5), see :func:`find_primitives`;
5. the segmentation is carried over to the arm-marker trajectories H_i: each primitive becomes an
   equivalence class of H segments, each with its effect phi = (initial, final) 3-D location.

Choices the paper leaves open, made here and why:

* **Pose metric.** Arc length and rest detection use ``|dp| + rotation_radius * |dr|`` (metres): a
  rotation counts as the path of a point on the object's rim, so a pure rotation gets Gaussians too.
  ``reg_covar`` is likewise in m^2 and is ``reg_covar / rotation_radius**2`` rad^2 on the rotation
  axes, so position and rotation have the same resolution. By default it follows ``spacing``
  (``spacing**2 / 48``), so ``spacing`` and ``threshold`` are the only scales of the method.
* **Relative pose.** Position minus the initial position; rotation ``R_t R_0^-1`` as a rotation
  vector (the difference in the rotation group, equal to subtraction for rotations about one axis).
  The initial pose is the mean over the leading rest, so noise on frame 0 does not shift everything.
* **Stationary parts.** The object rests before it is touched (approach) and after it is released
  (remove). A piece must not mix rest and motion, or the approach Gaussian of every push direction
  would lean its own way and never merge. So each trajectory is cut into a leading rest, the motion,
  and a trailing rest; the object is at rest while each frame stays within ``spacing / 4`` (the
  resolution, :attr:`PrimitiveDiscovery.rest_tolerance`) of the mean of the frames before it (after
  it, for the trailing rest; a mean, so sensor noise on one reference frame cannot end a rest), and
  the boundary is walked back (forward) to where the displacement starts to grow, but not into
  displacements below ``REST_FLOOR * rest_tolerance``: the micrometre creep of a settling object
  (monotonic in noise-free simulation) is rest, not the start of a motion. Each rest is one
  Gaussian however long it lasts; the motion is cut every ``spacing`` of arc length (the last piece
  is 0.5 to 1.5 spacings), the arc length being measured with a dead band of ``rest_tolerance`` so
  sensor jitter does not add up. Rest and motion states are never merged with each other, and
  Viterbi decodes rest frames with rest states and moving frames with motion states only: left
  free, a broad motion Gaussian can swallow a trailing rest whose merged rest state sits a few mm
  off (the demonstration then has no remove), or a rest state the first frames of a motion.
* **Symmetric KL.** Eq. (1) is D_KL(Q||P); merging is symmetric in the two states, so the merge test
  uses ``(D_KL(Q||P) + D_KL(P||Q)) / 2`` (the log-determinant terms cancel). The result then does not
  depend on which state came from the joint HMM.
* **One-to-one merging.** Among the state pairs below the threshold, each new state merges with at
  most one joint state and vice versa (a linear assignment that merges as many pairs as possible,
  then the closest), so a chain keeps its temporal resolution.
* **Approach and remove.** Leading and trailing runs of rest states in the decoded strings are the
  approach and remove primitives. Their effect in O is nil, so relative to where the object rests
  all of them are the same primitive, whatever the object's location (the paper's Fig. 7 has one
  approach and one remove); their effect phi is the hand marker's initial and final location.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.transform import Rotation

from hoap_actions.errors import DataFileError, InvalidInputError, NotFittedError
from hoap_actions.primitives import hmm_math
from hoap_actions.primitives.datasets import MAX_COORDINATE_M
from hoap_actions.primitives.json_files import read_json_model, write_json_model

logger = logging.getLogger(__name__)

FORMAT_VERSION = 1
OBJECT_DIM = 6
N_MARKERS = 6
HAND_DIM = 3 * N_MARKERS
OMEGA = 0.5
MIN_COMMON_LENGTH = 2
DEFAULT_SPACING = 0.03  # m, tuned on the paper preset (benchmarks/discovery_sweep.py)
DEFAULT_THRESHOLD = 3.0  # nats, ditto
REST_FLOOR = 0.1  # fraction of the rest tolerance below which a displacement is creep, not motion
DECODE_CELLS = 4_000_000  # frames x states decoded per batch: bounds the decoding's memory (~100 MB)
APPROACH, MANIPULATION, REMOVE = "approach", "manipulation", "remove"
UNKNOWN = -1
# Longest object rotation vector accepted (rad): any rotation, from a quaternion of either sign, is
# within 2 pi; far longer ones are corrupt values on which scipy's rotations break down.
MAX_ROTATION_ANGLE_RAD = 2.0 * math.pi


# ----------------------------------------------------------------------------- Gaussians (eqs. 1-3)


def gaussian_kl(mean_q: np.ndarray, cov_q: np.ndarray, mean_p: np.ndarray, cov_p: np.ndarray) -> np.ndarray:
    """Eq. (1): D_KL(Q||P) of Q = N(mean_q, cov_q) from P = N(mean_p, cov_p), in nats.

    Broadcasts over leading axes: means ``(..., n)``, covariances ``(..., n, n)`` SPD.
    """
    mean_q, mean_p = np.asarray(mean_q, float), np.asarray(mean_p, float)
    cov_q, cov_p = np.asarray(cov_q, float), np.asarray(cov_p, float)
    n = mean_q.shape[-1]
    diff = (mean_p - mean_q)[..., None]
    trace = np.trace(np.linalg.solve(cov_p, cov_q), axis1=-2, axis2=-1)
    mahalanobis = (np.swapaxes(diff, -1, -2) @ np.linalg.solve(cov_p, diff))[..., 0, 0]
    logdet_ratio = np.linalg.slogdet(cov_p)[1] - np.linalg.slogdet(cov_q)[1]
    return 0.5 * (logdet_ratio + trace + mahalanobis - n)


def symmetric_kl_matrix(
    means_a: np.ndarray, covs_a: np.ndarray, means_b: np.ndarray, covs_b: np.ndarray
) -> np.ndarray:
    """``(D_KL(a_k||b_m) + D_KL(b_m||a_k)) / 2`` for all pairs, shape ``(K, M)``, vectorised.

    The log-determinants cancel, leaving traces and a Mahalanobis term with the summed precisions.
    """
    prec_a, prec_b = _spd_inverse(covs_a), _spd_inverse(covs_b)
    n = means_a.shape[1]
    traces = np.einsum("mij,kji->km", prec_b, covs_a) + np.einsum("kij,mji->km", prec_a, covs_b)
    diff = means_a[:, None, :] - means_b[None, :, :]
    mahalanobis = np.einsum("kmi,kij,kmj->km", diff, prec_a, diff) + np.einsum("kmi,mij,kmj->km", diff, prec_b, diff)
    return 0.25 * (traces + mahalanobis) - 0.5 * n


def merge_gaussians(
    mean0: np.ndarray, cov0: np.ndarray, mean1: np.ndarray, cov1: np.ndarray, omega: float = OMEGA
) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. (2)-(3): precision-weighted merge of two Gaussians; broadcasts over leading axes.

    ``Sigma^-1 = omega Sigma0^-1 + (1 - omega) Sigma1^-1``,
    ``mu = Sigma (omega Sigma0^-1 mu0 + (1 - omega) Sigma1^-1 mu1)``.
    """
    if not 0.0 <= omega <= 1.0:
        raise InvalidInputError(f"omega must be in [0, 1], got {omega}")
    prec0, prec1 = _spd_inverse(np.asarray(cov0, float)), _spd_inverse(np.asarray(cov1, float))
    prec = omega * prec0 + (1.0 - omega) * prec1
    cov = _spd_inverse(prec)
    weighted = omega * (prec0 @ np.asarray(mean0, float)[..., None]) + (1.0 - omega) * (
        prec1 @ np.asarray(mean1, float)[..., None]
    )
    return (cov @ weighted)[..., 0], cov


def _spd_inverse(cov: np.ndarray) -> np.ndarray:
    """Inverse of SPD matrices via Cholesky, symmetrised (stabler than ``inv`` for small variances)."""
    chol_inv = np.linalg.inv(np.linalg.cholesky(cov))
    return np.swapaxes(chol_inv, -1, -2) @ chol_inv


# ------------------------------------------------------------------ longest common substring (Fig. 5)


def longest_common_substring(a: Sequence[int], b: Sequence[int]) -> tuple[int, int, int]:
    """Longest common substring of two int strings by dynamic programming, one numpy row per symbol of ``a``.

    Returns ``(start_in_a, start_in_b, length)``; the first longest in row-major order; length 0 if none.
    """
    end_a, end_b, length = _longest_match(np.asarray(a, int), np.asarray(b, int))
    return end_a - length + 1, end_b - length + 1, length


def _longest_match(x: np.ndarray, y: np.ndarray) -> tuple[int, int, int]:
    """``(end_x, end_y, length)`` of the longest common substring.

    ``run[j]`` is the length of the common suffix of ``x[:i+1]`` and ``y[:j+1]``; each row is one
    vector operation on the previous row shifted by one.
    """
    run = np.zeros(len(y) + 1, dtype=np.int64)
    best = (0, 0, 0)
    for i, symbol in enumerate(x):
        new = np.zeros_like(run)
        new[1:] = np.where(y == symbol, run[:-1] + 1, 0)
        run = new
        j = int(np.argmax(run[1:])) if len(y) else 0
        if len(y) and run[j + 1] > best[2]:
            best = (i, j, int(run[j + 1]))
    return best


def find_primitives(
    sequences: Sequence[Sequence[int]], min_length: int = MIN_COMMON_LENGTH
) -> tuple[list[tuple[int, ...]], list[list[int]]]:
    """Cut state strings into common and unique substrings (the paper's LCS step, Fig. 5).

    Procedure, generalising the two-string example to many strings: keep every string as a list of
    pieces (initially one piece each). Repeatedly take the distinct pieces, find the longest
    substring of length >= ``min_length`` common to two different ones (the first such in order of
    appearance), and split every piece at every (non-overlapping, left to right) occurrence of it.
    Stop when no two distinct pieces share such a substring; the distinct pieces are then the
    primitives, each either common or unique to one string.

    Pieces found earlier are split again when a later, shorter common substring lies inside them;
    extracting only from the matched pair would make the push of Fig. 7 over the longest distance
    one primitive (P1 P2 P3) instead of reusing the shorter pushes' P1 and P2. Each round splits at
    least one piece, so it ends after at most as many rounds as there are symbols.

    Returns ``(primitives, labels)``: primitives as tuples in order of first appearance, and per
    string the primitive indices of its pieces in order.
    """
    if min_length < 1:
        raise InvalidInputError(f"min_length must be >= 1, got {min_length}")
    pieces = [[tuple(int(s) for s in seq)] if len(seq) else [] for seq in sequences]
    while True:
        distinct = list(dict.fromkeys(p for seq in pieces for p in seq))
        common = _longest_common_piece(distinct)
        if len(common) < min_length:
            break
        pieces = [[part for piece in seq for part in _split_at(piece, common)] for seq in pieces]
    primitives = list(dict.fromkeys(p for seq in pieces for p in seq))
    index = {p: k for k, p in enumerate(primitives)}
    return primitives, [[index[p] for p in seq] for seq in pieces]


def _longest_common_piece(pieces: list[tuple[int, ...]]) -> tuple[int, ...]:
    """Longest substring shared by two different pieces (empty tuple if none); of those, the first in order.

    A binary search on the length: a common substring of length n has common prefixes of every
    shorter length, and each test hashes the O(total length) substrings of one length. The
    pairwise dynamic programme it replaces was quadratic in the total length, every round.
    """
    low, high = 0, max((len(p) for p in pieces), default=0)
    while low < high:
        middle = (low + high + 1) // 2
        if _first_shared(pieces, middle):
            low = middle
        else:
            high = middle - 1
    return _first_shared(pieces, low) if low else ()


def _first_shared(pieces: list[tuple[int, ...]], n: int) -> tuple[int, ...]:
    """The first (in piece order, then position) length-``n`` substring found in two different pieces, or ``()``."""
    owner: dict[tuple[int, ...], int] = {}
    shared = set()
    for k, piece in enumerate(pieces):
        for i in range(len(piece) - n + 1):
            sub = piece[i : i + n]
            if owner.setdefault(sub, k) != k:
                shared.add(sub)
    if shared:
        for piece in pieces:
            for i in range(len(piece) - n + 1):
                if piece[i : i + n] in shared:
                    return piece[i : i + n]
    return ()


def _split_at(piece: tuple[int, ...], sub: tuple[int, ...]) -> list[tuple[int, ...]]:
    """Split ``piece`` around every non-overlapping occurrence of ``sub``, scanning left to right."""
    parts, start, i, n = [], 0, 0, len(sub)
    while i + n <= len(piece):
        if piece[i : i + n] == sub:
            parts.extend(p for p in (piece[start:i], sub) if p)
            i += n
            start = i
        else:
            i += 1
    if start < len(piece):
        parts.append(piece[start:])
    return parts


# ------------------------------------------------------------------------------ sparse Viterbi


def sparse_viterbi(
    log_startprob: np.ndarray, log_transmat: np.ndarray, log_frameprob: np.ndarray, lengths: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hmm_math.viterbi` for a sparse transition matrix: ``(best log-probability (S,), states (N,))``.

    The joint HMM is a few hundred states in merged left-right chains, so each state has a handful
    of predecessors; a dense step costs ``K^2`` per frame, this one the number of allowed
    (finite) transitions. Sequences are sorted by length so the ones still running at time ``t``
    are a prefix, and the frames are never padded. Ties go to the lowest state index, as in
    :func:`hmm_math.viterbi`; an impossible sequence gets ``-inf`` and a meaningless path.
    """
    log_pi = np.asarray(log_startprob, float)
    log_a = np.asarray(log_transmat, float)
    logb = np.asarray(log_frameprob, float)
    lengths = np.asarray(lengths, dtype=np.int64)
    n_states = len(log_pi)
    if log_a.shape != (n_states, n_states) or logb.ndim != 2 or logb.shape[1] != n_states:
        raise InvalidInputError(
            f"shapes disagree: startprob {log_pi.shape}, transmat {log_a.shape}, frameprob {logb.shape}"
        )
    if lengths.ndim != 1 or len(lengths) == 0 or np.any(lengths < 1) or lengths.sum() != len(logb):
        raise InvalidInputError(f"lengths must be positive ints summing to the {len(logb)} frames; got {lengths}")
    # edges sorted by destination, then source: the first best edge of a group is the lowest source
    dst, src = np.nonzero(np.isfinite(log_a).T)
    weight = log_a[src, dst]
    group_start = np.flatnonzero(np.r_[True, dst[1:] != dst[:-1]]) if len(dst) else np.empty(0, int)
    group_dst, group_size = dst[group_start], np.diff(np.r_[group_start, len(dst)])
    edge_index = np.arange(len(dst))

    order = np.argsort(-lengths, kind="stable")
    starts = (np.cumsum(lengths) - lengths)[order]
    sorted_lengths = lengths[order]
    t_max = int(sorted_lengths[0])
    active = np.searchsorted(-sorted_lengths, -np.arange(t_max + 1), side="left")  # sequences with length > t
    back = np.zeros(logb.shape, dtype=np.int32)
    delta = log_pi + logb[starts]
    finals = np.empty((len(lengths), n_states))
    ending = slice(active[1], active[0])
    finals[ending] = delta[ending]
    for t in range(1, t_max):
        n = active[t]
        new = np.full((n, n_states), -np.inf)
        if len(dst):
            cand = delta[:n, src] + weight
            best = np.maximum.reduceat(cand, group_start, axis=1)
            is_best = cand == np.repeat(best, group_size, axis=1)
            first = np.minimum.reduceat(np.where(is_best, edge_index, len(dst)), group_start, axis=1)
            new[:, group_dst] = best
            back[(starts[:n] + t)[:, None], group_dst[None, :]] = src[first]
        delta[:n] = new + logb[starts[:n] + t]
        ending = slice(active[t + 1], n)
        finals[ending] = delta[ending]
    final_state = np.argmax(finals, axis=1)
    best_logprob = finals[np.arange(len(lengths)), final_state]
    path = np.empty(len(logb), dtype=np.intp)
    state = final_state.copy()
    for t in range(t_max - 1, -1, -1):
        n = active[t]
        ending = slice(active[t + 1], n)
        state[ending] = final_state[ending]
        frames = starts[:n] + t
        path[frames] = state[:n]
        if t:
            state[:n] = back[frames, state[:n]]
    result = np.empty(len(lengths))
    result[order] = best_logprob
    return result, path


# ----------------------------------------------------------------------------------- learned values


@dataclass(frozen=True)
class Segment:
    """One demonstration's frames ``[start, end)`` that perform a primitive, with its effect phi.

    ``initial`` and ``final`` are world-frame 3-D locations (m) at the first and last frame: of the
    object for manipulation primitives, of the hand marker for approach and remove (or of the object
    when no hand trajectories were given; ``source`` says which).
    """

    demo: int
    start: int
    end: int
    initial: tuple[float, float, float]
    final: tuple[float, float, float]
    source: str

    @property
    def effect(self) -> np.ndarray:
        """phi = (initial, final), shape ``(6,)``, metres."""
        return np.array(self.initial + self.final)


@dataclass(frozen=True)
class PrimitiveClass:
    """An equivalence class of arm movements that have the same effect on the object (one primitive)."""

    primitive_id: int
    kind: str
    states: tuple[int, ...]
    segments: tuple[Segment, ...]

    @property
    def effects(self) -> np.ndarray:
        """Effects of all segments, shape ``(n_segments, 6)``: initial then final location (m)."""
        return np.array([s.effect for s in self.segments]).reshape(-1, 6)

    def movements(self, hands: Sequence[np.ndarray]) -> list[np.ndarray]:
        """The class's arm-marker trajectories cut from ``hands`` (the ``H_i`` given to ``fit``)."""
        return [np.asarray(hands[s.demo])[s.start : s.end] for s in self.segments]


# ---------------------------------------------------------------------------------------- estimator


class PrimitiveDiscovery:
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
        Per trajectory, ``(primitive_id, start_frame, end_frame)`` with ``end_frame`` exclusive,
        tiling all frames.
    classes_:
        Per primitive id, a :class:`PrimitiveClass`: the H segments and their effects.
    """

    def __init__(
        self,
        spacing: float = DEFAULT_SPACING,
        threshold: float = DEFAULT_THRESHOLD,
        reg_covar: float | None = None,
        rotation_radius: float = 0.05,
        hand_marker: int = 2,
        random_state: int | np.random.Generator | None = None,
    ) -> None:
        self.spacing = spacing
        self.threshold = threshold
        self.reg_covar = reg_covar
        self.rotation_radius = rotation_radius
        self.hand_marker = hand_marker
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

    def get_params(self) -> dict:
        """Hyper-parameters as given to ``__init__``."""
        return {
            "spacing": self.spacing,
            "threshold": self.threshold,
            "reg_covar": self.reg_covar,
            "rotation_radius": self.rotation_radius,
            "hand_marker": self.hand_marker,
            "random_state": self.random_state if isinstance(self.random_state, (int, type(None))) else None,
        }

    def _check_params(self) -> None:
        for name in ("spacing", "threshold", "reg_covar", "rotation_radius"):
            value = getattr(self, name)
            if name == "reg_covar" and value is None:
                continue
            if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and value > 0):
                raise InvalidInputError(f"{name} must be a finite number > 0, got {value!r}")
        if not (isinstance(self.hand_marker, (int, np.integer)) and 0 <= self.hand_marker < N_MARKERS):
            raise InvalidInputError(f"hand_marker must be an int in [0, {N_MARKERS}), got {self.hand_marker!r}")

    # -- fit

    def fit(self, trajectories: Sequence[np.ndarray], hands: Sequence[np.ndarray] | None = None) -> PrimitiveDiscovery:
        """Learn the joint HMM, the primitives and their equivalence classes.

        ``trajectories``: list of raw object poses ``(T_i, 6)`` = position (m) + rotation vector (rad),
        world frame, one fixed sampling rate. ``hands``: optional matching arm markers ``(T_i, 18)``
        (6 markers x xyz, m) for the effects of approach and remove. Coordinates beyond
        :data:`~hoap_actions.primitives.datasets.MAX_COORDINATE_M` and rotation vectors longer than
        :data:`MAX_ROTATION_ANGLE_RAD` raise InvalidInputError naming the trajectory and the frame.

        A single demonstration gives approach, one manipulation primitive (nothing to compare it
        with) and remove. A trajectory whose object never moves is one rest: all of it is approach.
        """
        self._check_params()
        objects = _check_objects(trajectories)
        arms = None if hands is None else _check_hands(hands, objects)
        relative, pieces = zip(*(self._prepare(o) for o in objects))
        self._build_joint_hmm(relative, pieces)
        runs = self._decode(relative, pieces)
        self.state_sequences_ = [tuple(states) for states, _ in runs]

        middles, lead, trail = [], [], []
        for states, _ in runs:
            first, last = self._rest_bounds(states)
            lead.append(first)
            trail.append(last)
            middles.append(states[first:last])
        motion_primitives, motion_labels = find_primitives(middles)
        self._assign_primitives(runs, lead, trail, motion_primitives, motion_labels)
        self.classes_ = self._make_classes(objects, arms)
        logger.info(
            "discovered %d primitives from %d demonstrations (%d joint states)",
            len(self.primitives_),
            len(objects),
            len(self.joint_means_),
        )
        return self

    def relative_trajectories(self, trajectories: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Raw object poses ``(T_i, 6)`` as :meth:`fit` models them: relative to the initial rest pose (m, rad)."""
        self._check_params()
        return [self._prepare(o)[0] for o in _check_objects(trajectories)]

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
        bounds = np.flatnonzero(np.diff(index)) + 1
        edges = [0, *bounds.tolist(), end - start]
        return [(start + a, start + b, False) for a, b in pairwise(edges)]

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
            start_counts[mapping[0]] += 1.0
            # uniform left-right chain: stay or advance with 1/2 each, the last state only stays
            np.add.at(mass, (mapping[:-1], mapping[:-1]), 0.5)
            np.add.at(mass, (mapping[:-1], mapping[1:]), 0.5)
            mass[mapping[-1], mapping[-1]] += 1.0
        self.joint_means_ = means
        self.joint_covars_ = covs
        self.joint_at_rest_ = at_rest
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
        runs = []
        for batch in np.split(np.arange(len(relative)), np.flatnonzero(np.diff(batch_of)) + 1):
            runs += self._decode_batch([relative[i] for i in batch], [pieces[i] for i in batch], log_start, log_trans)
        return runs

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
        runs = []
        for seq_path in np.split(path, np.cumsum(lengths)[:-1]):
            change = np.flatnonzero(np.diff(seq_path)) + 1
            starts = np.concatenate([[0], change])
            ends = np.concatenate([change, [len(seq_path)]])
            runs.append(([int(seq_path[s]) for s in starts], list(zip(starts.tolist(), ends.tolist()))))
        return runs

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
        runs: list[tuple[list[int], list[tuple[int, int]]]],
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

        for (states, frames), first, last, labels in zip(runs, lead, trail, motion_labels):
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

    def _make_classes(self, objects: list[np.ndarray], arms: list[np.ndarray] | None) -> list[PrimitiveClass]:
        """Step 5: the equivalence class of H segments of each primitive, with effects phi."""
        members: list[list[Segment]] = [[] for _ in self.primitives_]
        marker = slice(3 * self.hand_marker, 3 * self.hand_marker + 3)
        for demo, segments in enumerate(self.segmentations_):
            for pid, start, end in segments:
                if self.primitive_kinds_[pid] != MANIPULATION and arms is not None:
                    track, source = arms[demo][:, marker], "hand"
                else:
                    track, source = objects[demo][:, :3], "object"
                members[pid].append(Segment(demo, start, end, _xyz(track[start]), _xyz(track[end - 1]), source))
        return [
            PrimitiveClass(pid, kind, states, tuple(segments))
            for pid, (kind, states, segments) in enumerate(zip(self.primitive_kinds_, self.primitives_, members))
        ]

    # -- use

    def _check_fitted(self) -> None:
        if not hasattr(self, "primitives_"):
            raise NotFittedError("this PrimitiveDiscovery is not fitted yet: call fit() or load() first")

    def predict(self, trajectories: Sequence[np.ndarray]) -> list[np.ndarray]:
        """Per-frame primitive ids ``(T_i,)`` for raw object trajectories ``(T_i, 6)``.

        Frames are Viterbi-decoded with the joint HMM; rest runs at the ends are approach / remove and
        the states between are parsed left to right into the longest known manipulation primitive.
        Frames whose states start no known primitive are labelled ``UNKNOWN`` (-1).
        """
        self._check_fitted()
        objects = _check_objects(trajectories)
        relative, pieces = zip(*(self._prepare(o) for o in objects))
        runs = self._decode(relative, pieces)
        ids = {kind: self.primitive_kinds_.index(kind) for kind in (APPROACH, REMOVE) if kind in self.primitive_kinds_}
        motion = [(p, pid) for pid, p in enumerate(self.primitives_) if self.primitive_kinds_[pid] == MANIPULATION]
        motion.sort(key=lambda item: -len(item[0]))
        labels = []
        for (states, frames), obj in zip(runs, objects):
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

    def save(self, path: str | os.PathLike, overwrite: bool = False) -> None:
        """Write the fitted model as JSON (``format_version`` = :data:`FORMAT_VERSION`)."""
        self._check_fitted()
        body = {
            "params": {k: v.item() if isinstance(v, np.generic) else v for k, v in self.get_params().items()},
            "joint_means": self.joint_means_.tolist(),
            "joint_covars": self.joint_covars_.tolist(),
            "joint_at_rest": self.joint_at_rest_.tolist(),
            "transmat": self.transmat_.tolist(),
            "startprob": self.startprob_.tolist(),
            "state_sequences": [list(s) for s in self.state_sequences_],
            "primitives": [list(p) for p in self.primitives_],
            "primitive_kinds": self.primitive_kinds_,
            "segmentations": [[list(s) for s in seg] for seg in self.segmentations_],
            "classes": [
                {
                    "primitive_id": c.primitive_id,
                    "kind": c.kind,
                    "states": list(c.states),
                    "segments": [
                        [s.demo, s.start, s.end, list(s.initial), list(s.final), s.source] for s in c.segments
                    ],
                }
                for c in self.classes_
            ],
        }
        write_json_model(path, "PrimitiveDiscovery", FORMAT_VERSION, body, overwrite)

    @classmethod
    def load(cls, path: str | os.PathLike) -> PrimitiveDiscovery:
        """Read a model written by :meth:`save`."""
        document = read_json_model(path, "PrimitiveDiscovery", FORMAT_VERSION)
        try:
            model = cls(**document["params"])
            model.joint_means_ = np.array(document["joint_means"], float).reshape(-1, OBJECT_DIM)
            model.joint_covars_ = np.array(document["joint_covars"], float).reshape(-1, OBJECT_DIM, OBJECT_DIM)
            model.joint_at_rest_ = np.array(document["joint_at_rest"], bool)
            model.transmat_ = np.array(document["transmat"], float)
            model.startprob_ = np.array(document["startprob"], float)
            model.state_sequences_ = [tuple(s) for s in document["state_sequences"]]
            model.primitives_ = [tuple(p) for p in document["primitives"]]
            model.primitive_kinds_ = list(document["primitive_kinds"])
            model.segmentations_ = [[tuple(s) for s in seg] for seg in document["segmentations"]]
            model.classes_ = [
                PrimitiveClass(
                    c["primitive_id"],
                    c["kind"],
                    tuple(c["states"]),
                    tuple(Segment(d, a, b, _xyz(i), _xyz(f), src) for d, a, b, i, f, src in c["segments"]),
                )
                for c in document["classes"]
            ]
        except (KeyError, IndexError, TypeError, ValueError) as exc:
            raise DataFileError(f"{path} is a corrupt PrimitiveDiscovery model file: {exc}") from exc
        return model


# -------------------------------------------------------------------------------------- validation


def _xyz(point: np.ndarray) -> tuple[float, float, float]:
    """A 3-D location as a tuple of Python floats (hashable, JSON-ready)."""
    return float(point[0]), float(point[1]), float(point[2])


def _check_trajectories(trajectories: Sequence[np.ndarray], dim: int, name: str) -> list[np.ndarray]:
    """Validate a non-empty list of finite ``(T_i, dim)`` arrays with ``T_i >= 1``; return float copies."""
    if isinstance(trajectories, np.ndarray) and trajectories.ndim == 2:
        raise InvalidInputError(f"{name} must be a list of (T_i, {dim}) arrays, got one 2-D array; wrap it in a list")
    try:
        items = list(trajectories)
    except TypeError as exc:
        kind = type(trajectories).__name__
        raise InvalidInputError(f"{name} must be a list of (T_i, {dim}) arrays, got {kind}") from exc
    if not items:
        raise InvalidInputError(f"{name} is empty: at least one demonstration is needed")
    checked = []
    for i, item in enumerate(items):
        try:
            array = np.array(item, dtype=float)
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"{name}[{i}] is not numeric: {exc}") from exc
        if array.ndim != 2 or array.shape[1] != dim or array.shape[0] < 1:
            raise InvalidInputError(f"{name}[{i}] must have shape (T, {dim}) with T >= 1, got {array.shape}")
        if not np.isfinite(array).all():
            raise InvalidInputError(f"{name}[{i}] contains NaN or inf; only finite values are accepted")
        checked.append(array)
    return checked


def _check_objects(trajectories: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Validate object poses ``(T_i, 6)``: finite, positions within :data:`MAX_COORDINATE_M`, rotation
    vectors within :data:`MAX_ROTATION_ANGLE_RAD`, so a corrupt frame is named here, not in scipy."""
    objects = _check_trajectories(trajectories, OBJECT_DIM, "trajectories")
    for i, poses in enumerate(objects):
        _check_bound(f"trajectories[{i}]", np.abs(poses[:, :3]).max(axis=1), MAX_COORDINATE_M,
                     "an object coordinate of", "m", "positions within +-{limit:g} m of the scene origin")
        with np.errstate(over="ignore"):
            angle = np.linalg.norm(poses[:, 3:], axis=1)
        _check_bound(f"trajectories[{i}]", angle, MAX_ROTATION_ANGLE_RAD, "a rotation vector of angle", "rad",
                     "rotation vectors of angle <= {limit:.4g} rad (2 pi)")
    return objects


def _check_bound(where: str, size: np.ndarray, limit: float, what: str, unit: str, accepted: str) -> None:
    """Raise InvalidInputError naming the first frame whose ``size`` (T,) exceeds ``limit``.

    ``accepted`` says what is accepted, with ``{limit}`` standing for the limit.
    """
    frames = np.flatnonzero(size > limit)
    if len(frames):
        raise InvalidInputError(f"{where} frame {frames[0]} has {what} {size[frames[0]]:.3g} {unit} "
                                f"({len(frames)} such frame(s)); accepted: {accepted.format(limit=limit)}")


def _check_hands(hands: Sequence[np.ndarray], objects: list[np.ndarray]) -> list[np.ndarray]:
    """Validate arm-marker trajectories: one ``(T_i, 18)`` array per object trajectory, same lengths,
    coordinates within :data:`MAX_COORDINATE_M`."""
    arms = _check_trajectories(hands, HAND_DIM, "hands")
    if len(arms) != len(objects):
        raise InvalidInputError(f"got {len(arms)} hand trajectories for {len(objects)} object trajectories")
    for i, (arm, obj) in enumerate(zip(arms, objects)):
        if len(arm) != len(obj):
            raise InvalidInputError(f"hands[{i}] has {len(arm)} frames but trajectories[{i}] has {len(obj)}")
        _check_bound(f"hands[{i}]", np.abs(arm).max(axis=1), MAX_COORDINATE_M, "a marker coordinate of", "m",
                     "marker positions within +-{limit:g} m of the scene origin")
    return arms
