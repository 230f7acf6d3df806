"""How a particle's (class, effect, state) becomes a body pose: the PHMM's mean markers, and how a particle's
pose strays from them.

Two proposals, each a small state per particle that drifts as an AR(1) process (coefficient
:data:`POSE_MEMORY` per frame, so a stray persists over a few tenths of a second) within the state's
learned spread:

* ``"offsets"`` (the first design): the mean markers plus an offset of every coordinate (18 numbers), each
  drifting within its own standard deviation (the diagonal of the state's covariance). The shoulder, elbow
  and hand stray independently, so most particles pose an arm no person holds.
* ``"turned"``: the offsets, and the hand turned as a whole about the wrist by two persistent angles (a
  turn about the vertical, a roll about the wrist-knuckle line): a person pushes or carries with the hand
  turned as the task asks, which no class's mean says and independent offsets reach only by chance. Used
  from motion capture, where the hand's markers show its turn; from one camera it loosens the class
  posterior more than it poses the hand (validation).
* ``"hand"`` (poses generated from the hand): the hand (wrist, index tip, knuckle, thumb) is the state's
  mean moved by a persistent 3-D shift; the shoulder and elbow follow from the hand, by the
  :class:`~hoap_actions.primitives.hmm.posture.PostureModel` when the models carry one, otherwise by the
  state's Gaussian conditioned on the hand (its full covariance's regression of shoulder and elbow on a
  shift of the hand; with diagonal covariances, the state's mean); then the elbow turns about the
  shoulder-wrist line by a persistent swivel angle, and the shoulder and elbow shift together by a
  persistent trunk shift: seven numbers a particle. How a person holds the elbow and leans for a given
  hand varies; where the hand goes is what the image and the effect say.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from hoap_actions.demonstration.tasks import MARKER_NAMES
from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.hmm.posture import MIN_POINTING_M
from hoap_actions.primitives.models.class_models import ClassModel
from hoap_actions.tracking.tracking_models import TrackingModels

__all__ = ["POSE_PROPOSALS", "HandPoses", "OffsetPoses", "PoseProposal", "TurnedHandOffsets", "mean_poses",
           "pose_proposal", "turn_about_vertical"]

POSE_MEMORY = 0.9  # per-frame AR(1) coefficient of a particle's pose state
SWIVEL_SD_RAD = 0.1  # rad, stationary sd of the elbow's turn about the shoulder-wrist line (validation)
TRUNK = True  # shoulder and elbow shift together as well (validation)
HAND_TURN_SD_RAD = (0.3, 0.4)  # rad, stationary sd of the hand's turn about the vertical and its roll (validation)
HAND_TURN_MEMORY = 0.97  # per-frame AR(1) coefficient of the hand's turn: a hand held turned for seconds
ARM = slice(0, 6)  # shoulder and elbow, xyz each, in the recordings' marker order
HAND = slice(6, 18)  # wrist, index tip, index knuckle, thumb tip
HAND_MARKERS = 4


def mean_poses(model: ClassModel, states: np.ndarray, phi: np.ndarray, n_markers: int) -> np.ndarray:
    """The markers ``(n, 3 * n_markers)`` a class's PHMM means at continuous states ``states`` (n,) and full
    effects ``phi`` (n, 6): the means of states ``floor(s)`` and ``ceil(s)`` at phi, interpolated, as
    :meth:`ParametricHMM.synthesize` moves between them."""
    states, phi = np.asarray(states, dtype=float), np.asarray(phi, dtype=float)
    features, chain = model.phmm.mean_bar_.shape[1], model.phmm.n_states
    if states.ndim != 1 or phi.shape != (states.size, 6) or not 0 < 3 * n_markers <= features:
        raise InvalidInputError(f"mean_poses takes states (n,), phi (n, 6) and 1-{features // 3} markers; "
                                f"got {states.shape}, {phi.shape} and {n_markers}")
    if states.size and not (states.min() >= 0 and states.max() <= chain - 1):
        raise InvalidInputError(f"states must lie in [0, {chain - 1}], the class's chain")
    return _mean_poses(model, states, phi, n_markers)


def _mean_poses(model: ClassModel, states: np.ndarray, phi: np.ndarray, n_markers: int) -> np.ndarray:
    """:func:`mean_poses` without its checks: the filter's particles always lie on their chain."""
    phmm = model.phmm
    width = 3 * n_markers
    reduced = np.einsum("nk,kp->np", phi - model.centre, model.basis)
    low = np.floor(states).astype(int)
    high = np.minimum(low + 1, phmm.n_states - 1)
    share = (states - low)[:, None]
    bend = phmm.effect_features_.transform(reduced) if phmm.V_.shape[2] else None

    def mean_at(s: np.ndarray) -> np.ndarray:
        means = phmm.mean_bar_[s, :width] + np.einsum("ndp,np->nd", phmm.W_[s, :width], reduced)
        return means if bend is None else means + np.einsum("ndm,nm->nd", phmm.V_[s, :width], bend)

    return (1.0 - share) * mean_at(low) + share * mean_at(high)


def _position_variances(model: ClassModel, width: int) -> np.ndarray:
    """``(K, width)``: each state's variances of the first ``width`` features (the marker positions)."""
    covars = model.phmm.covars_
    return covars[:, np.arange(width), np.arange(width)] if model.phmm.covariance_type == "full" else covars[:, :width]


class PoseProposal(Protocol):
    """A particle's pose state (``dim`` numbers), how it drifts each frame, and the pose it gives."""

    name: str
    dim: int

    def drift(self, class_id: int, states: np.ndarray, pose_state: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """The pose states ``(n, dim)`` one frame on, for particles of class ``class_id`` at ``states`` (n,)."""
        ...

    def pose(self, class_id: int, states: np.ndarray, phi: np.ndarray, pose_state: np.ndarray,
             mode: int = 0) -> np.ndarray:
        """Markers ``(n, 3 M)`` of particles of class ``class_id`` holding the hand in ``mode`` (the models' hand
        modes; any with none) at continuous ``states``, effects ``phi`` (n, 6)."""
        ...


def _mode_classes(models: TrackingModels) -> dict[tuple[int, int], ClassModel]:
    return {} if models.hand_modes is None else dict(models.hand_modes.classes)


class OffsetPoses:
    """The state's mean markers plus an 18-D offset, each coordinate within its own learned spread."""

    name = "offsets"

    def __init__(self, models: TrackingModels) -> None:
        self._classes = models.classes
        self._by_mode = _mode_classes(models)
        self._n_markers = len(models.marker_names)
        self.dim = 3 * self._n_markers
        self._sd = {cid: np.sqrt(_position_variances(model, self.dim)) for cid, model in models.classes.items()}

    def drift(self, class_id: int, states: np.ndarray, pose_state: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        spread = self._sd[class_id][states.astype(int)]
        noise = rng.normal(0.0, 1.0, spread.shape) * spread
        return POSE_MEMORY * pose_state + np.sqrt(1.0 - POSE_MEMORY**2) * noise

    def pose(self, class_id: int, states: np.ndarray, phi: np.ndarray, pose_state: np.ndarray,
             mode: int = 0) -> np.ndarray:
        model = self._by_mode.get((class_id, mode), self._classes[class_id])
        return _mean_poses(model, states, phi, self._n_markers) + pose_state


class TurnedHandOffsets(OffsetPoses):
    """The offsets, then the hand (index tip, knuckle, thumb) turned rigidly about the wrist: by a persistent
    angle about the vertical, then by a roll about the wrist-knuckle line. The pose state is the 18 offsets
    and the two angles (rad), each angle drifting within ``turn_sd`` (:data:`HAND_TURN_SD_RAD`)."""

    name = "turned"

    def __init__(self, models: TrackingModels, turn_sd: tuple[float, float] = HAND_TURN_SD_RAD) -> None:
        if tuple(models.marker_names) != MARKER_NAMES:
            raise InvalidInputError(f"a turned hand needs the markers {list(MARKER_NAMES)}; these models have "
                                    f"{list(models.marker_names)}")
        if len(turn_sd) != 2 or not all(np.isfinite(sd) and sd >= 0 for sd in turn_sd):
            raise InvalidInputError(f"turn_sd takes two standard deviations >= 0 (rad); got {turn_sd!r}")
        super().__init__(models)
        self._offsets = self.dim
        self.dim = self._offsets + 2
        self.turn_sd = np.asarray(turn_sd, dtype=float)

    def drift(self, class_id: int, states: np.ndarray, pose_state: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        offsets = super().drift(class_id, states, pose_state[:, :self._offsets], rng)
        noise = rng.normal(0.0, 1.0, (len(pose_state), 2)) * self.turn_sd
        turn = HAND_TURN_MEMORY * pose_state[:, self._offsets:] + np.sqrt(1.0 - HAND_TURN_MEMORY**2) * noise
        return np.hstack([offsets, turn])

    def pose(self, class_id: int, states: np.ndarray, phi: np.ndarray, pose_state: np.ndarray,
             mode: int = 0) -> np.ndarray:
        pose = super().pose(class_id, states, phi, pose_state[:, :self._offsets], mode)
        pose[:, HAND.start + 3:] = turn_hand(pose[:, HAND], *pose_state[:, self._offsets:].T)
        return pose


def turn_hand(hand: np.ndarray, turn: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """The index tip, knuckle and thumb ``(n, 9)`` of hands ``(n, 12)`` (wrist first) turned rigidly about the
    wrist: by ``turn`` (n,) rad about the vertical, then by ``roll`` (n,) rad about the turned wrist-knuckle
    line (right-handed)."""
    wrist = hand[:, :3]
    points = turn_about_vertical(wrist, [hand[:, k:k + 3] for k in (3, 6, 9)], turn)
    knuckle = points[1]
    return np.hstack([_swivel(wrist, point, knuckle, roll) for point in points])


def turn_about_vertical(wrist: np.ndarray, points: list[np.ndarray], turn: np.ndarray) -> list[np.ndarray]:
    """``points`` (each (n, 3)) turned by ``turn`` (n,) rad about the vertical through ``wrist`` (n, 3)."""
    above = wrist + np.array([0.0, 0.0, 1.0])
    return [_swivel(wrist, point, above, turn) for point in points]


class HandPoses:
    """The hand from the PHMM and a persistent shift; shoulder and elbow from the hand; a swivel of the elbow;
    with ``trunk``, a shift of the shoulder and elbow together (the trunk leaning).

    The pose state is ``(hand shift x, y, z (m), swivel (rad)[, trunk shift x, y, z (m)])``. The hand shift
    drifts within the state's learned spread of the wrist, the swivel within ``swivel_sd`` (rad), the trunk
    shift within the state's spread of the shoulder given the hand (full covariances; else the shoulder's).
    """

    name = "hand"

    def __init__(self, models: TrackingModels, swivel_sd: float = SWIVEL_SD_RAD, trunk: bool = TRUNK) -> None:
        if tuple(models.marker_names) != MARKER_NAMES:
            raise InvalidInputError(f"poses generated from the hand need the markers {list(MARKER_NAMES)}; these "
                                    f"models have {list(models.marker_names)}")
        if not (np.isfinite(swivel_sd) and swivel_sd >= 0):
            raise InvalidInputError(f"swivel_sd must be >= 0 (rad); got {swivel_sd!r}")
        self._classes = models.classes
        self._by_mode = _mode_classes(models)
        self.posture = models.posture
        self.swivel_sd, self.trunk = float(swivel_sd), bool(trunk)
        self.dim = 7 if self.trunk else 4
        width = 3 * len(MARKER_NAMES)
        self._sd = {cid: np.hstack([np.sqrt(_position_variances(model, width)[:, HAND.start:HAND.start + 3]),
                                    np.full((model.phmm.n_states, 1), self.swivel_sd),
                                    *([_shoulder_given_hand_sd(model)] if self.trunk else [])])
                    for cid, model in models.classes.items()}
        self._gain = {cid: _arm_gain(model) for cid, model in models.classes.items()}

    def drift(self, class_id: int, states: np.ndarray, pose_state: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        spread = self._sd[class_id][states.astype(int)]
        noise = rng.normal(0.0, 1.0, spread.shape) * spread
        return POSE_MEMORY * pose_state + np.sqrt(1.0 - POSE_MEMORY**2) * noise

    def pose(self, class_id: int, states: np.ndarray, phi: np.ndarray, pose_state: np.ndarray,
             mode: int = 0) -> np.ndarray:
        pose = _mean_poses(self._by_mode.get((class_id, mode), self._classes[class_id]), states, phi, len(MARKER_NAMES))
        shift = pose_state[:, :3]
        pose[:, HAND] += np.tile(shift, HAND_MARKERS)
        if self.posture is not None:
            wrist = pose[:, 6:9]
            pointing = [np.linalg.norm(pose[:, k:k + 3] - wrist, axis=1) for k in (12, 15)]  # knuckle, thumb
            posed = np.minimum(*pointing) >= MIN_POINTING_M  # a hand with no pointing direction keeps the mean arm
            pose[posed, ARM] = self.posture.predict(pose[posed]) if posed.any() else pose[posed, ARM]
        else:
            pose[:, ARM] += np.einsum("nij,nj->ni", self._gain[class_id][states.astype(int)], shift)
        if self.trunk:
            pose[:, ARM] += np.tile(pose_state[:, 4:7], 2)
        pose[:, 3:6] = _swivel(pose[:, 0:3], pose[:, 3:6], pose[:, 6:9], pose_state[:, 3])
        return pose


def _arm_gain(model: ClassModel) -> np.ndarray:
    """``(K, 6, 3)``: per state, how the shoulder and elbow's conditional mean moves when the whole hand moves
    by a shift (the full covariance's regression of the arm on the hand, summed over the four hand markers);
    zeros for diagonal covariances, whose arm does not depend on the hand."""
    k = model.phmm.n_states
    if model.phmm.covariance_type != "full":
        return np.zeros((k, 6, 3))
    covars = model.phmm.covars_
    hand_hand = covars[:, HAND, HAND]
    hand_arm = covars[:, HAND, ARM]
    regression = np.linalg.solve(hand_hand, hand_arm).transpose(0, 2, 1)  # (K, 6, 12): arm on hand
    return regression.reshape(k, 6, HAND_MARKERS, 3).sum(axis=2)


def _shoulder_given_hand_sd(model: ClassModel) -> np.ndarray:
    """``(K, 3)``: per state, the shoulder's standard deviation given the hand (the full covariance's Schur
    complement; with diagonal covariances, the shoulder's own)."""
    covars = model.phmm.covars_
    if model.phmm.covariance_type != "full":
        return np.sqrt(covars[:, 0:3])
    hand_hand, hand_shoulder = covars[:, HAND, HAND], covars[:, HAND, 0:3]
    given = covars[:, 0:3, 0:3] - np.einsum("kha,khb->kab", hand_shoulder, np.linalg.solve(hand_hand, hand_shoulder))
    return np.sqrt(np.maximum(np.diagonal(given, axis1=1, axis2=2), 0.0))


def _swivel(shoulder: np.ndarray, elbow: np.ndarray, wrist: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """The elbows ``(n, 3)`` turned by ``angle`` (n,) rad about the shoulder-wrist line (Rodrigues' formula):
    the upper arm and forearm keep their lengths and the hand stays where it is."""
    axis = wrist - shoulder
    axis = axis / np.maximum(np.linalg.norm(axis, axis=1, keepdims=True), 1e-9)
    v = elbow - shoulder
    cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
    along = np.sum(axis * v, axis=1, keepdims=True) * axis
    return shoulder + v * cos + np.cross(axis, v) * sin + along * (1.0 - cos)


POSE_PROPOSALS = {"offsets": OffsetPoses, "turned": TurnedHandOffsets, "hand": HandPoses}


def pose_proposal(name: str, models: TrackingModels) -> PoseProposal:
    """The proposal called ``name`` (:data:`POSE_PROPOSALS`) for ``models``."""
    if name not in POSE_PROPOSALS:
        raise InvalidInputError(f"pose_proposal must be one of {sorted(POSE_PROPOSALS)}; got {name!r}")
    return POSE_PROPOSALS[name](models)
