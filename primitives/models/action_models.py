"""Learned action models: one parametric HMM per discovered primitive class, and the action grammar.

This is the paper's learning step after discovery ("Recognition with HMMs and PHMMs"): every
equivalence class of arm movements that :class:`~hoap_actions.primitives.discovery.estimator.PrimitiveDiscovery`
finds becomes a left-right :class:`~hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM` whose state
means move with the class's effect phi, and the classes' order in the demonstrations becomes an
:class:`~hoap_actions.primitives.discovery.grammar.ActionGrammar`. Fitted, the models

- **synthesise** a movement of a class for a desired effect (:meth:`ActionModels.synthesize`),
- **recognise** a movement: its class, its effect and every class's log-likelihood
  (:meth:`ActionModels.recognize`),
- **decode** a demonstration cut into pieces: the grammatical class sequence that best explains the
  pieces (:meth:`ActionModels.decode_segments`).

Choices, each measured on a validation split of ``paper`` recordings (training seeds 0 and 2,
held-out seed 3; figures in ``benchmarks/results/NOTES.md``):

- **Observations**: the 6 markers' positions (18-D) and their displacement over 0.1 s (18-D): the
  successive pieces of one push or carry move the hand alike and differ mostly in speed.
- **Effect**: phi = (initial, final) 3-D location, of the object for a manipulation and of the hand
  marker for approach and remove, as in the paper (every primitive biparametric). Each class's PHMM
  sees phi reduced to the principal directions in which its training effects vary by more than
  ``effect_tol`` (at most ``n_segments - 2`` of them): the object stays on the table, so z never
  varies and a 6-D phi would not be identifiable. Every public method speaks the full 6-D phi.
- **States**: as many as the class's shortest training segment has frames times
  ``state_fraction``, at most ``max_states``; diagonal covariances.
- **Variance prior**: a manipulation piece is a class with a handful of segments, whose state
  variances would collapse onto ``reg_covar``; such classes are refitted with a conjugate prior
  (``covars_weight`` frames per state) on the within-state variances pooled over all of them.
- **Recognising a piece** (the cuts known): its class's chain over the training effects must explain
  its displacements best, the evidence connected recognition reads (94.8 % through the grammar,
  against 92.5 % for the PHMMs' likelihoods at each class's estimated phi on all 36 features: those
  are overconfident about the positions); phi is then estimated by the best classes' PHMMs.
- **Decoding pieces** (the cuts known): the strict grammar of the transitions seen in training; a
  piece shorter than a class's chain costs that class ``unexplained_penalty`` nats instead of ruling
  it out; neighbouring manipulation pieces must agree on the object's location at their cut
  (``continuity_weight`` nats per m^2 of gap, :mod:`~hoap_actions.primitives.models.effect_continuity`);
  then the object's trajectory is estimated from the hand between the first and the last piece
  decoded as a manipulation (:mod:`~hoap_actions.primitives.models.object_estimate`), discovery parses it
  as it parses a real one, and each piece's class in that parse gets ``object_vote`` nats before the
  grammar decodes again (after the unexplained penalty, so a piece shorter than the voted class's
  chain, as a brisker demonstrator's are, keeps its vote). Discovery's classes are what the object did, and neighbouring classes
  differ by a centimetre of object motion that the arm's displacements hardly show (the lifts that
  start carries, 18 against 44): 95.7 -> 97.8 % on validation recordings 20 and 21.
- **Decoding a whole movement** (:meth:`ActionModels.decode`, from the markers alone): connected
  recognition over the classes' chains (:mod:`~hoap_actions.primitives.models.connected_recognition`) on
  the displacement features only: over the training effects a state's positions spread across the
  table and cut worse (frame accuracy 89.2 % with them, 94.5 % without), and ``stay_weight`` 2
  (95.2 %, edit score 0.909 against 0.888 at 1); then, as with the cuts given, discovery parses the
  object trajectory estimated from the hand between the first and last frame decoded as a
  manipulation, each frame's class in that parse gets ``object_vote`` nats, and Viterbi runs again:
  the parse cuts the pieces of a push or carry where the object's path does (validation recordings 20
  and 21: segment accuracy 88.4 -> 98.5 %, edit score 0.906 -> 0.986, frame accuracy 95.4 -> 96.1 %).

Files: :meth:`ActionModels.save` writes a models directory (layout in :mod:`~hoap_actions.primitives.models.models_directory`);
:meth:`ActionModels.load` validates every file and names the one that is wrong.
"""

from __future__ import annotations

import json
import logging
import dataclasses
import math
import sys
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hoap_actions.errors import DataFileError, ExtrapolationWarning, InvalidInputError, NotFittedError
from hoap_actions.outputs import claimed_directory
from hoap_actions.primitives.base import Estimator, check_is_fitted
from hoap_actions.primitives.models.whole_actions import action_level
from hoap_actions.primitives.models.connected_recognition import ChainedHMM, chain_classes, exit_probability
from hoap_actions.primitives.discovery.estimator import MANIPULATION, UNKNOWN, PrimitiveDiscovery
from hoap_actions.primitives.discovery.groups import action_groups
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.models_directory import (
    FORMAT_VERSION,
    KIND,
    MANIFEST,
    check_manifest,
    finite_array,
    names,
    positive,
    read_manifest,
)
from hoap_actions.primitives.models.effect_continuity import effect_gap_scores
from hoap_actions.primitives.models.object_estimate import HAND_FRAME_MARKERS, fit_grasp_offset, object_poses
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.parametric_hmm import EXTRAPOLATION_MARGIN, ParametricHMM

logger = logging.getLogger(__name__)

__all__ = ["ActionModels", "ClassModel", "DecodedSegment", "SegmentRecognition", "marker_features"]

DISPLACEMENT_WINDOW_S = 0.1  # s, the marker displacement appended to the positions
EFFECT_DIM = 6  # phi = initial xyz, final xyz (m)
PHI_NAMES = ("initial x", "initial y", "initial z", "final x", "final y", "final z")


def marker_features(H: np.ndarray, fps: float, velocity: bool = True) -> np.ndarray:
    """Model input of one movement: markers ``(T, 18)`` (or ``(T, M, 3)``) in metres, with each
    marker's displacement over :data:`DISPLACEMENT_WINDOW_S` appended when ``velocity``: ``(T, 36)``."""
    X = np.asarray(H, dtype=float).reshape(len(H), -1)
    if not velocity:
        return X
    displacement = np.gradient(X, axis=0) * (fps * DISPLACEMENT_WINDOW_S) if len(X) > 1 else np.zeros_like(X)
    return np.hstack([X, displacement])


@dataclass(frozen=True)
class ClassModel:
    """One class's PHMM and the affine map between its reduced effect and the full phi (6,)."""

    class_id: int
    kind: str
    phmm: ParametricHMM
    centre: np.ndarray  # (6,) mean training effect
    basis: np.ndarray  # (6, r) principal directions the PHMM's reduced phi runs along
    exit_probability: float  # per frame, of leaving the chain's last state (connected recognition)

    def full_phi(self, reduced: np.ndarray) -> np.ndarray:
        return self.centre + self.basis @ reduced

    def reduced_phi(self, phi: np.ndarray) -> np.ndarray:
        return (np.asarray(phi, float) - self.centre) @ self.basis


@dataclass(frozen=True)
class SegmentRecognition:
    """A recognised movement: the best class, its phi (6,), every class's log-likelihood (its chain's
    best path over its training effects, on the displacements) and the candidate classes' phi.

    Classes whose chain is longer than the movement score ``-inf``; classes that are not candidates have no phi.
    """

    class_id: int
    phi: np.ndarray
    log_likelihoods: Mapping[int, float]
    phis: Mapping[int, np.ndarray]


@dataclass(frozen=True)
class DecodedSegment:
    """A piece of a decoded movement: frames ``[start, end)`` perform class ``class_id`` with effect ``phi`` (6,)."""

    class_id: int
    start: int
    end: int
    phi: np.ndarray


class ActionModels(Estimator):
    """Learn, recognise and synthesise with one PHMM per discovered class (module docstring: the choices).

    Args:
        covariance_type, reg_covar: the PHMMs' (see :class:`ParametricHMM`).
        covars_weight: frames per state of the manipulation classes' pooled variance prior (0: none).
        effect_tol: least spread (m) of a phi direction a class's PHMM models.
        max_states, state_fraction: states per class (see the module docstring).
        velocity: append marker displacements to the positions.
        n_restarts: phi estimates started per class and movement (from the mean training effect, then
            from random training effects).
        n_candidates: classes :meth:`recognize` estimates phi for: those whose chains, over their
            training effects, explain the movement best (effect continuity compares their phis).
        unexplained_penalty: nats a class pays for a piece shorter than its chain (``None``: ruled out).
        continuity_weight: nats per m^2 of gap between neighbouring manipulation pieces' effects (0: off).
        stay_weight: power on self-transition probabilities in connected recognition (:meth:`decode`).
        object_vote: nats that each piece (:meth:`decode_segments`) or each frame (:meth:`decode`) gives
            its class in discovery's parse of the object trajectory estimated from the hand
            (:meth:`object_parse`; 0: off; models learned without object poses have no grasp offset and
            cannot vote).
        mean_model, smoothing: how each PHMM's state means depend on phi (see :class:`ParametricHMM`).
        speed_augmentation: time-stretch factors (in [0.5, 2]); every class's training movement is also
            fitted as if performed that many times as long (resampled in time), so that the chains accept a
            demonstrator slower or faster than those seen. ``()`` (default): none.

    Learned attributes: ``classes_`` (dict id -> :class:`ClassModel`), ``grammar_``,
    ``discovery_``, ``fps_``, ``marker_names_``, ``covars_prior_``; the action level ``actions_``
    (dict id -> :class:`ClassModel` of a whole action), ``action_lifts_`` (dict id -> the highest
    lift, m, of the object in its runs) and ``action_of_class_`` (dict class id -> the whole action
    its pieces belong to), all empty without it; ``demonstrators_``, the profiles of who demonstrated
    (empty: not known); ``grasp_offset_`` (3,), the object's centre in the hand's frame while the hand
    moves it (m; ``None`` when learned without object poses).
    """

    _learned = ("classes_", "grammar_", "discovery_", "fps_", "marker_names_", "covars_prior_", "actions_",
                "action_lifts_", "action_of_class_", "demonstrators_", "grasp_offset_")
    _file_kind = KIND
    _format_version = FORMAT_VERSION
    _readable_versions = (1, 2, FORMAT_VERSION)

    def __init__(
        self,
        covariance_type: str = "diag",
        reg_covar: float = 1e-5,
        covars_weight: float = 5.0,
        effect_tol: float = 0.01,
        max_states: int = 40,
        state_fraction: float = 1.0,
        velocity: bool = True,
        n_restarts: int = 1,
        n_candidates: int = 8,
        unexplained_penalty: float | None = 1000.0,
        continuity_weight: float = 1e6,
        stay_weight: float = 2.0,
        mean_model: str = "linear",
        smoothing: float = 1.0,
        speed_augmentation: tuple[float, ...] = (),
        object_vote: float = 1000.0,
    ) -> None:
        self.covariance_type = covariance_type
        self.reg_covar = reg_covar
        self.covars_weight = covars_weight
        self.effect_tol = effect_tol
        self.max_states = max_states
        self.state_fraction = state_fraction
        self.velocity = velocity
        self.n_restarts = n_restarts
        self.n_candidates = n_candidates
        self.unexplained_penalty = unexplained_penalty
        self.continuity_weight = continuity_weight
        self.stay_weight = stay_weight
        self.mean_model = mean_model
        self.smoothing = smoothing
        self.speed_augmentation = speed_augmentation
        self.object_vote = object_vote

    def _check_params(self) -> None:
        def number(name: str, low: float, high: float = math.inf, low_open: bool = False) -> None:
            value = getattr(self, name)
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
            ok = ok and np.isfinite(value) and (value > low if low_open else value >= low) and value <= high
            if not ok:
                bound = f"{'(' if low_open else '['}{low}, {high}{']' if np.isfinite(high) else ')'}"
                raise InvalidInputError(f"{name} must be a number in {bound}; got {value!r}")

        if self.covariance_type not in ("diag", "full"):
            raise InvalidInputError(f"covariance_type must be 'diag' or 'full'; got {self.covariance_type!r}")
        number("reg_covar", 0.0, low_open=True)
        number("covars_weight", 0.0)
        number("effect_tol", 0.0)
        number("state_fraction", 0.0, 1.0, low_open=True)
        number("continuity_weight", 0.0)
        number("stay_weight", 0.0, low_open=True)
        number("smoothing", 0.0)
        number("object_vote", 0.0)
        if self.mean_model not in ("linear", "tps"):
            raise InvalidInputError(f"mean_model must be 'linear' or 'tps'; got {self.mean_model!r}")
        if self.unexplained_penalty is not None:
            number("unexplained_penalty", 0.0)
        for name in ("max_states", "n_restarts", "n_candidates"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise InvalidInputError(f"{name} must be an int >= 1; got {value!r}")
        factors = self.speed_augmentation
        if not isinstance(factors, (tuple, list)) or not all(
                isinstance(f, (int, float)) and not isinstance(f, bool) and 0.5 <= f <= 2.0 and f != 1.0 for f in factors):
            raise InvalidInputError(f"speed_augmentation must be a tuple of time-stretch factors in [0.5, 2], not 1; "
                                    f"got {factors!r}")
        if not isinstance(self.velocity, bool):
            raise InvalidInputError(f"velocity must be True or False; got {self.velocity!r}")

    DECODING_PARAMS = ("n_restarts", "n_candidates", "unexplained_penalty", "continuity_weight", "stay_weight",
                       "object_vote")
    """Hyper-parameters that only recognition reads: fitted models take new values of these without a refit."""

    def set_params(self, **params: object) -> ActionModels:
        """Set :data:`DECODING_PARAMS` (validated; the others need a new fit) and return ``self``."""
        unknown = sorted(set(params) - set(self.DECODING_PARAMS))
        if unknown:
            raise InvalidInputError(f"set_params takes the decoding parameters {list(self.DECODING_PARAMS)}; got "
                                    f"{unknown} (fit new models to change the others)")
        previous = self.get_params()
        self.__dict__.update(params)
        try:
            self._check_params()
        except InvalidInputError:
            self.__dict__.update(previous)
            raise
        if "stay_weight" in params:
            self._chained = None  # the chained HMM is built with it
        return self

    # ------------------------------------------------------------------------------------- fit
    def fit(
        self,
        H: np.ndarray,
        lengths: Sequence[int],
        discovery: PrimitiveDiscovery,
        fps: float,
        marker_names: Sequence[str] | None = None,
        progress: bool = False,
        O: np.ndarray | None = None,
        demonstrators: Sequence[Mapping] = (),
    ) -> ActionModels:
        """Fit one PHMM per class of ``discovery`` and the grammar of its segmentations.

        ``H`` are the demonstrations' arm markers, concatenated ``(N, 18)`` or ``(N, 6, 3)`` (m), with
        ``lengths`` frames each, recorded at ``fps``; ``discovery`` was fitted on the same
        demonstrations in the same order (its segments index them). ``progress`` shows a bar over
        the class fits when stderr is a terminal. With the object poses ``O`` ``(N, 6)`` the action
        level is learned too (:mod:`~hoap_actions.primitives.models.whole_actions`): one PHMM per whole action,
        phi = the object's (or the hand's, for approach and remove) start and end. ``demonstrators``:
        who performed the demonstrations (profiles as :meth:`DemonstratorProfile.to_dict` gives them;
        empty: not known), kept so that recognising someone else can warn.
        """
        self._check_params()
        self._chained = None  # built from the fitted classes on first use
        hands = _split(H, lengths)
        if not hasattr(discovery, "classes_"):
            raise NotFittedError("discovery must be a fitted PrimitiveDiscovery (call its fit first)")
        n_demos = len(discovery.segmentations_)
        if n_demos != len(hands):
            raise InvalidInputError(
                f"discovery was fitted on {n_demos} demonstrations but H holds {len(hands)} (lengths); give the same ones"
            )
        if not (isinstance(fps, (int, float)) and np.isfinite(fps) and fps > 0):
            raise InvalidInputError(f"fps must be a positive number of frames per second; got {fps!r}")
        self.fps_ = float(fps)
        self.marker_names_ = tuple(marker_names) if marker_names is not None else tuple(f"marker_{i}" for i in range(hands[0].shape[1] // 3))
        inputs = [marker_features(h, self.fps_, self.velocity) for h in hands]
        stretched = {f: [marker_features(_stretch(h, f), self.fps_, self.velocity) for h in hands]
                     for f in self.speed_augmentation}
        pieces = [c for c in discovery.classes_ if c.kind == MANIPULATION]
        refit = self.covars_weight > 0 and bool(pieces)
        bar = tqdm(total=len(discovery.classes_) + (len(pieces) if refit else 0), desc="fitting class PHMMs",
                   unit="class", disable=not (progress and sys.stderr.isatty()))
        with bar:
            fitted = {}
            for c in discovery.classes_:
                fitted[c.primitive_id] = self._fit_class(c, inputs, stretched, None)
                bar.update()
            self.covars_prior_ = None
            if refit:  # the first fit's variances make the pooled prior
                frames = [sum(s.end - s.start for s in c.segments) for c in pieces]
                self.covars_prior_ = _pooled_variances([fitted[c.primitive_id].phmm for c in pieces], frames,
                                                       self.reg_covar)
                for c in pieces:
                    fitted[c.primitive_id] = self._fit_class(c, inputs, stretched, self.covars_prior_)
                    bar.update()
        self.classes_ = {int(cid): fitted[cid] for cid in sorted(fitted)}
        self.grammar_ = ActionGrammar(0.0).fit([[int(pid) for pid, *_ in seg] for seg in discovery.segmentations_])
        self.discovery_ = discovery
        self.demonstrators_ = _unique_profiles(demonstrators)
        self.actions_, self.action_lifts_, self.action_of_class_ = (
            ({}, {}, {}) if O is None else self._fit_actions(inputs, O, lengths))
        self.grasp_offset_ = None if O is None else self._fit_grasp_offset(hands, O, lengths)
        return self

    def _fit_grasp_offset(self, hands: list[np.ndarray], O: np.ndarray, lengths: Sequence[int]) -> np.ndarray | None:
        """Where the object sits in the hand's frame over the training manipulations (from the first
        manipulation piece of a demonstration to its last); ``None`` without the hand's markers."""
        if not set(HAND_FRAME_MARKERS) <= set(self.marker_names_):
            return None
        spans: dict[int, tuple[int, int]] = {}
        for c in self.discovery_.classes_:
            if c.kind == MANIPULATION:
                for s in c.segments:
                    first, last = spans.get(s.demo, (s.start, s.end))
                    spans[s.demo] = (min(first, s.start), max(last, s.end))
        if not spans:
            return None
        objects = np.split(np.asarray(O, dtype=float), np.cumsum(lengths)[:-1])
        shape = (-1, len(self.marker_names_), 3)
        return fit_grasp_offset([(hands[d][a:b].reshape(shape), objects[d][a:b]) for d, (a, b) in sorted(spans.items())],
                                self.marker_names_)

    def _fit_actions(self, inputs: list[np.ndarray], O: np.ndarray, lengths: Sequence[int]
                     ) -> tuple[dict[int, ClassModel], dict[int, float], dict[int, int]]:
        """One model per whole action: approach and remove are their classes already; each pooled
        manipulation action gets a PHMM on its whole runs, phi = the object's start and end."""
        level = action_level(self.discovery_, O, lengths)
        groups = action_groups(self.discovery_)
        action_of_class = {cid: level.action_of_group[groups[cid]] for cid in self.classes_}
        objects = np.split(np.asarray(O, dtype=float), np.cumsum(lengths)[:-1])
        actions, lifts = {}, {}
        for action, kind in enumerate(level.kinds):
            runs = [r for r in level.runs if level.action(r) == action]
            if kind != MANIPULATION:
                whole = next(m for m in self.classes_.values() if m.kind == kind)
                actions[action], lifts[action] = dataclasses.replace(whole, class_id=action), 0.0
                continue
            movements = [inputs[r.demo][r.start:r.end] for r in runs]
            phis = np.array([np.r_[objects[r.demo][r.start, :3], objects[r.demo][r.end - 1, :3]] for r in runs])
            actions[action] = self._fit_model(action, kind, movements, phis, None)
            lifts[action] = max(float(level.signatures[g][:-1].reshape(-1, 3)[:, 1].max())
                                for g in {r.group for r in runs})
        return actions, lifts, action_of_class

    def _fit_class(self, cls, inputs: list[np.ndarray], stretched: dict[float, list[np.ndarray]],
                   covars_prior: np.ndarray | None) -> ClassModel:
        """The class's PHMM from its segments of ``inputs`` and of each time-stretched copy in ``stretched``."""
        movements = [inputs[s.demo][s.start:s.end] for s in cls.segments]
        copies = [stretched[f][s.demo][round(s.start * f):round(s.end * f)]
                  for f in self.speed_augmentation for s in cls.segments]
        phis = np.tile(cls.phis, (1 + len(self.speed_augmentation), 1))
        return self._fit_model(int(cls.primitive_id), str(cls.kind), movements + copies, phis, covars_prior,
                               n_original=len(movements))

    def _fit_model(self, model_id: int, kind: str, movements: list[np.ndarray], phis: np.ndarray,
                   covars_prior: np.ndarray | None, n_original: int | None = None) -> ClassModel:
        """A left-right PHMM on ``movements`` with their effects ``phis`` (n, 6), reduced to the
        directions they vary in (module docstring); its states are counted on the first ``n_original``
        movements (the rest are time-stretched copies)."""
        n_original = len(movements) if n_original is None else n_original
        centre = phis.mean(axis=0)
        _, singular, vt = np.linalg.svd(phis - centre, full_matrices=False)
        spread = singular / np.sqrt(len(phis))
        rank = int(min(np.sum(spread > self.effect_tol), max(n_original - 2, 0)))
        basis = vt[:rank].T
        lengths = np.array([len(m) for m in movements])
        shortest = lengths[:n_original].min()
        n_states = max(1, int(min(self.max_states, self.state_fraction * shortest)))
        keep = lengths >= n_states  # a stretched copy too short for the chain is left out
        movements, phis, lengths = [m for m, k in zip(movements, keep) if k], phis[keep], lengths[keep]
        phmm = ParametricHMM(
            n_states=n_states, covariance_type=self.covariance_type, reg_covar=self.reg_covar, n_iter=100,
            tol=1e-3, random_state=0, covars_prior=covars_prior, covars_weight=self.covars_weight,
            mean_model=self.mean_model, smoothing=self.smoothing,
        )
        reduced = (phis - centre) @ basis
        phmm.fit(np.concatenate(movements), lengths, reduced)
        leave = exit_probability(phmm, movements, reduced)
        return ClassModel(model_id, kind, phmm, centre, basis, leave)

    # ----------------------------------------------------------------------------- synthesis
    def synthesize(self, class_id: int, phi: np.ndarray, n_frames: int | None = None) -> np.ndarray:
        """Marker trajectory ``(T, M, 3)`` (m) of class ``class_id`` for the effect ``phi`` (6,): initial
        and final location. Only the part of phi along the directions the class's demonstrations
        varied in is used; a phi far outside them warns (ExtrapolationWarning)."""
        return self._synthesize(_lookup(self.classes_, class_id, "class", "classes"), phi, n_frames)

    def synthesize_action(self, action_id: int, phi: np.ndarray, n_frames: int | None = None) -> np.ndarray:
        """Marker trajectory ``(T, M, 3)`` (m) of a whole action (``actions_``) for ``phi`` (6,): for
        approach and remove the hand's start and end, for a manipulation the object's. Which
        manipulation carries (lifts) the object: :attr:`action_lifts_` (m)."""
        check_is_fitted(self)
        if not self.actions_:
            raise InvalidInputError("these models have no action level: fit them with the object poses O "
                                    "(hoap-actions learn does), or load a models directory of format_version 2")
        return self._synthesize(_lookup(self.actions_, action_id, "action", "actions"), phi, n_frames)

    def _synthesize(self, model: ClassModel, phi: np.ndarray, n_frames: int | None) -> np.ndarray:
        phi = _check_phi(phi)
        self._warn_if_extrapolating(model, phi)
        with warnings.catch_warnings():  # said above, in the full phi's terms
            warnings.simplefilter("ignore", ExtrapolationWarning)
            X = model.phmm.synthesize(model.reduced_phi(phi), n_frames)
        return X[:, : 3 * len(self.marker_names_)].reshape(len(X), -1, 3)

    def _warn_if_extrapolating(self, model: ClassModel, phi: np.ndarray) -> None:
        """Warn if a component of ``phi`` is beyond the class's training effects, widened by
        :data:`~hoap_actions.primitives.hmm.parametric_hmm.EXTRAPOLATION_MARGIN` of their span plus
        ``effect_tol`` (a direction the demonstrations did not vary in is not modelled at all)."""
        trained = model.centre + model.phmm.train_phi_ @ model.basis.T  # (n_segments, 6)
        low, high = trained.min(axis=0), trained.max(axis=0)
        margin = EXTRAPOLATION_MARGIN * (high - low) + self.effect_tol
        far = np.flatnonzero((phi < low - margin) | (phi > high + margin))
        if far.size:
            ranges = "; ".join(f"{PHI_NAMES[i]} {phi[i]:.3f} m, demonstrated {low[i]:.3f}..{high[i]:.3f} m" for i in far)
            warnings.warn(f"phi is far outside what class {model.class_id}'s demonstrations show ({ranges}): the "
                          "movement is an unchecked extrapolation", ExtrapolationWarning, stacklevel=3)

    # ---------------------------------------------------------------------------- recognition
    def features(self, H: np.ndarray) -> np.ndarray:
        """The model input of one movement's markers ``(T, M, 3)`` or ``(T, 3M)``, checked against the models."""
        check_is_fitted(self)
        H = np.asarray(H, dtype=float)
        markers = len(self.marker_names_)
        if H.ndim not in (2, 3) or H.reshape(len(H), -1).shape[1] != 3 * markers or len(H) < 1:
            raise InvalidInputError(
                f"a movement must be (T, {markers}, 3) or (T, {3 * markers}) marker positions "
                f"({', '.join(self.marker_names_)}); got shape {H.shape}"
            )
        if not np.all(np.isfinite(H)):
            raise InvalidInputError("a movement's markers must be finite (no NaN or inf); bridge occlusion gaps first "
                                    "with hoap_actions.primitives.pipelines.mocap_cleaning.fill_gaps (learn and recognize do)")
        return marker_features(H, self.fps_, self.velocity)

    def recognize(self, H: np.ndarray) -> SegmentRecognition:
        """The class of one movement ``H`` (its markers), its phi (6,), and every class's log-likelihood.

        The class is the one whose chain, over its training effects, explains the displacements best:
        the evidence connected recognition (:meth:`decode`) reads, so a piece cut from a demonstration
        is classified as the decoder would classify it between those cuts. Phi is then estimated with
        the PHMMs of the ``n_candidates`` best classes (the others get none).
        """
        return self._recognize_features(self.features(H))

    def _recognize_features(self, X: np.ndarray) -> SegmentRecognition:
        chained = self.chained()
        marginal = chained.class_scores(self.connected_log_emissions(X))
        scores = {int(c): float(v) for c, v in zip(chained.class_ids, marginal)}
        best = [int(chained.class_ids[i]) for i in np.argsort(-marginal, kind="stable")[: self.n_candidates]
                if np.isfinite(marginal[i])]
        if not best:  # shorter than every chain: no class explains it
            return SegmentRecognition(-1, np.full(EFFECT_DIM, np.nan), scores, {})
        phis = {c: self.classes_[c].full_phi(self.classes_[c].phmm.estimate_phi(X, n_restarts=self.n_restarts))
                for c in best}
        return SegmentRecognition(best[0], phis[best[0]], scores, phis)

    def decode_segments(self, segments: Sequence[np.ndarray]) -> list[SegmentRecognition]:
        """Recognise the consecutive pieces of one demonstration together, through the grammar.

        Each piece is recognised on its own, then the grammar picks the class sequence that best
        explains all of them (with the unexplained penalty and effect continuity); then, with
        ``object_vote``, the class discovery gives each piece of the object trajectory estimated from
        the hand adds to that class's score and the grammar decodes again (module docstring). Each
        returned recognition carries the decoded class and that class's phi. A piece no class
        explains, or a demonstration the strict grammar cannot parse, keeps its isolated class.
        """
        if isinstance(segments, np.ndarray) or not len(segments):
            raise InvalidInputError("segments must be a non-empty list of movements, one (T, M, 3) array per piece")
        recognitions = [self.recognize(piece) for piece in segments]
        decoded = self._decode(recognitions)
        votes = self.object_votes(segments, [r.class_id for r in decoded])
        return decoded if votes is None else self._decode(recognitions, votes)

    def object_votes(self, segments: Sequence[np.ndarray], class_ids: Sequence[int]) -> list[int] | None:
        """Each consecutive piece's class (its frames' majority) in :meth:`object_parse` of the pieces'
        markers, the manipulation being the pieces from the first to the last of ``class_ids`` that is a
        manipulation class; -1 where the parse knows no class; ``None`` when :meth:`object_parse` gives none."""
        lengths = [len(piece) for piece in segments]
        H = np.concatenate([np.asarray(piece, dtype=float).reshape(len(piece), -1) for piece in segments])
        labels = self.object_parse(H, np.repeat(np.asarray(class_ids, dtype=int), lengths))
        if labels is None:
            return None
        bounds = np.cumsum([0] + lengths)
        return [int(np.bincount(labels[a:b] - UNKNOWN).argmax()) + UNKNOWN for a, b in zip(bounds[:-1], bounds[1:])]

    def object_parse(self, H: np.ndarray, frame_classes: np.ndarray) -> np.ndarray | None:
        """Discovery's class of every frame (``UNKNOWN`` where it knows none) in its parse of the object
        trajectory estimated from the markers ``H`` ``(T, M, 3)`` or ``(T, 3M)``
        (:mod:`~hoap_actions.primitives.models.object_estimate`), the hand moving the object from the first to
        the last frame that ``frame_classes`` ``(T,)`` gives a manipulation class. ``None`` when the
        models cannot vote (``object_vote`` 0, no grasp offset) or no frame is a manipulation."""
        check_is_fitted(self)
        if self.object_vote == 0 or self.grasp_offset_ is None:
            return None
        manipulations = {c for c, m in self.classes_.items() if m.kind == MANIPULATION}
        moving = np.flatnonzero(np.isin(frame_classes, list(manipulations)))
        if not moving.size:
            return None
        H = np.asarray(H, dtype=float).reshape(len(H), len(self.marker_names_), 3)
        poses = object_poses(H, self.marker_names_, int(moving[0]), int(moving[-1]) + 1, self.grasp_offset_)
        return self.discovery_.predict(poses, [len(poses)])[0]

    def _decode(self, recognitions: list[SegmentRecognition], votes: Sequence[int] | None = None
                ) -> list[SegmentRecognition]:
        scores = [r.log_likelihoods if r.class_id >= 0 else dict.fromkeys(self.classes_, 0.0) for r in recognitions]
        # after the unexplained penalty: a piece shorter than the voted class's chain (a brisker
        # demonstrator than the training ones) still gets the vote
        bonus = None if votes is None else [{vote: self.object_vote} if vote in self.classes_ else {} for vote in votes]
        pairs = None
        if self.continuity_weight > 0 and len(recognitions) > 1:
            pieces = {cid for cid, m in self.classes_.items() if m.kind == MANIPULATION}

            def where(rec: SegmentRecognition, part: slice) -> dict:
                return {c: phi[part] for c, phi in rec.phis.items() if c in pieces}

            pairs = [effect_gap_scores(where(a, slice(3, 6)), where(b, slice(0, 3)), float(self.continuity_weight))
                     for a, b in zip(recognitions, recognitions[1:])]
        try:
            labels, _ = self.grammar_.decode(scores, self.unexplained_penalty, pairs, bonus)
        except InvalidInputError:  # the strict grammar cannot parse these pieces: keep the isolated classes
            return recognitions
        return [
            SegmentRecognition(int(label), rec.phis.get(int(label), np.full(EFFECT_DIM, np.nan)),
                               rec.log_likelihoods, rec.phis)
            for label, rec in zip(labels, recognitions)
        ]

    def decode(self, H: np.ndarray) -> list[DecodedSegment]:
        """Cut a whole movement (its markers alone) into primitives and recognise each, with its phi.

        Connected recognition (:mod:`~hoap_actions.primitives.models.connected_recognition`): the classes'
        chains joined by the grammar, Viterbi over every frame, then again with each frame's class in
        :meth:`object_parse` ``object_vote`` nats the likelier; then each segment's phi estimated with
        its class's PHMM. A movement no grammatical path explains gives an empty list.
        """
        X = self.features(H)
        return self.decode_features(X, self.connected_log_emissions(X))

    def connected_log_emissions(self, X: np.ndarray) -> np.ndarray:
        """Log-density of every frame of the features ``X`` (:meth:`features`) under every state of the
        chained classes, ``(T, S)``: connected recognition's evidence."""
        return self.chained().log_emissions(X[:, self.connected_features()])

    def decode_features(self, X: np.ndarray, log_emissions: np.ndarray) -> list[DecodedSegment]:
        """:meth:`decode` from a movement's features and their :meth:`connected_log_emissions`, for a
        caller that uses the emissions too (the recognition report's baseline)."""
        chained = self.chained()
        labels, score = chained.viterbi(log_emissions)
        if not np.isfinite(score):
            return []
        ids = chained.class_ids
        parse = self.object_parse(X[:, : 3 * len(self.marker_names_)], ids[labels])
        if parse is not None:  # each frame's class in the parse gets object_vote nats, and Viterbi runs again
            parsed = np.searchsorted(ids, parse).clip(0, len(ids) - 1)  # ids are sorted
            voted = (ids[parsed] == parse)[:, None] & (chained.state_class[None, :] == parsed[:, None])
            relabelled, score = chained.viterbi(log_emissions + self.object_vote * voted)
            labels = relabelled if np.isfinite(score) else labels
        decoded = []
        for index, start, end in runs(labels):
            model = self.classes_[int(ids[index])]
            phi = (model.full_phi(model.phmm.estimate_phi(X[start:end], n_restarts=self.n_restarts))
                   if end - start >= model.phmm.min_frames else np.full(EFFECT_DIM, np.nan))
            decoded.append(DecodedSegment(model.class_id, int(start), int(end), phi))
        return decoded

    def chained(self) -> ChainedHMM:
        """The classes' chains joined by the grammar, over the training effects (built once)."""
        check_is_fitted(self)
        if getattr(self, "_chained", None) is None:
            ids = list(self.classes_)
            self._chained = chain_classes([self.classes_[c].phmm for c in ids], ids,
                                          [self.classes_[c].exit_probability for c in ids], self.grammar_,
                                          self.connected_features(), self.stay_weight)
        return self._chained

    def connected_features(self) -> np.ndarray:
        """Indices of the features connected recognition reads: the displacements when the models have
        them (module docstring), else the positions."""
        positions = 3 * len(self.marker_names_)
        return np.arange(positions, 2 * positions) if self.velocity else np.arange(positions)

    # ----------------------------------------------------------------------------------- files
    def _write(self, path: Path, overwrite: bool) -> None:
        """A models directory (:mod:`~hoap_actions.primitives.models.models_directory`) that appears whole once
        complete; an existing one is replaced only with ``overwrite``."""
        with claimed_directory(path, overwrite, what="action models") as staging:
            self.write_files(staging)

    def write_files(self, folder: Path) -> None:
        """Write the models' files into ``folder``, an empty directory the caller has claimed
        (:func:`hoap_actions.outputs.claimed_directory`); use :meth:`save` otherwise."""
        check_is_fitted(self)
        folder = Path(folder)
        manifest = {
            "format_version": FORMAT_VERSION,
            "kind": KIND,
            "params": self.get_params(),
            "fps": self.fps_,
            "marker_names": list(self.marker_names_),
            "covars_prior": None if self.covars_prior_ is None else self.covars_prior_.tolist(),
            **({"demonstrators": list(self.demonstrators_)} if self.demonstrators_ else {}),
            "grasp_offset": None if self.grasp_offset_ is None else self.grasp_offset_.tolist(),
            "classes": [
                {"id": cid, "kind": m.kind, "file": f"class_{cid}.npz", "effect_centre": m.centre.tolist(),
                 "effect_basis": m.basis.tolist(), "exit_probability": m.exit_probability,
                 "action": self.action_of_class_.get(cid)}
                for cid, m in self.classes_.items()
            ],
            "actions": [
                {"id": aid, "kind": m.kind, "file": f"action_{aid}.npz", "effect_centre": m.centre.tolist(),
                 "effect_basis": m.basis.tolist(), "exit_probability": m.exit_probability,
                 "lift_m": self.action_lifts_[aid]}
                for aid, m in self.actions_.items()
            ],
        }
        (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
        self.discovery_.save(folder / "discovery.json")
        self.grammar_.save(folder / "grammar.json")
        for cid, model in self.classes_.items():
            model.phmm.save(folder / f"class_{cid}.npz")
        for aid, model in self.actions_.items():
            model.phmm.save(folder / f"action_{aid}.npz")

    @classmethod
    def _read(cls, path: Path) -> tuple[object, object, dict]:
        if not path.is_dir():
            raise DataFileError(f"no models directory at {path}; make one with `hoap-actions learn`")
        manifest = read_manifest(path / MANIFEST)
        return manifest.get("kind"), manifest.get("format_version"), manifest

    @classmethod
    def _from_file(cls, path: Path, manifest: dict, version: int) -> ActionModels:
        """The models of the directory ``path``: every file validated, each error naming its file and entry."""
        directory = path
        manifest_path = directory / MANIFEST
        check_manifest(manifest_path, manifest)
        try:
            params = dict(manifest["params"])
            if isinstance(params.get("speed_augmentation"), list):  # JSON has no tuples
                params["speed_augmentation"] = tuple(params["speed_augmentation"])
            models = cls(**params)
            models._check_params()
        except (TypeError, InvalidInputError) as exc:
            raise DataFileError(f"{manifest_path}: entry params: {exc}; accepted: {cls._param_names()}") from None
        models.fps_ = positive(manifest_path, "fps", manifest["fps"])
        models.marker_names_ = tuple(names(manifest_path, "marker_names", manifest["marker_names"]))
        width = (2 if models.velocity else 1) * 3 * len(models.marker_names_)
        prior = manifest["covars_prior"]
        models.covars_prior_ = None if prior is None else finite_array(manifest_path, "covars_prior", prior, (width,))
        models.demonstrators_ = _profiles_entry(manifest_path, manifest.get("demonstrators", []))
        offset = manifest.get("grasp_offset") if version >= 3 else None
        models.grasp_offset_ = None if offset is None else finite_array(manifest_path, "grasp_offset", offset, (3,))
        models.discovery_ = PrimitiveDiscovery.load(directory / "discovery.json")
        models.grammar_ = ActionGrammar.load(directory / "grammar.json")
        classes = {e["id"]: _entry_model(directory, e, "classes", "class", width) for e in _entries(manifest_path, manifest, "classes")}
        actions = {e["id"]: _entry_model(directory, e, "actions", "action", width)
                   for e in (_entries(manifest_path, manifest, "actions") if version >= 2 else [])}
        models.actions_ = dict(sorted(actions.items()))
        models.action_lifts_ = {}
        for entry in (manifest["actions"] if version >= 2 else []):
            lift = entry.get("lift_m")
            if isinstance(lift, bool) or not isinstance(lift, (int, float)) or not np.isfinite(lift):
                raise DataFileError(f"{manifest_path}: entry actions[{entry['id']}]: lift_m must be a number (m); got {lift!r}")
            models.action_lifts_[entry["id"]] = float(lift)
        models.action_of_class_ = {}
        for entry in (manifest["classes"] if version >= 2 and actions else []):
            if entry.get("action") not in actions:
                raise DataFileError(f"{manifest_path}: entry classes[{entry['id']}]: action must be one of the "
                                    f"actions {sorted(actions)}; got {entry.get('action')!r}")
            models.action_of_class_[entry["id"]] = entry["action"]
        known = {c.primitive_id for c in models.discovery_.classes_}
        if set(classes) != known or set(models.grammar_.symbols_) - set(classes):
            raise DataFileError(
                f"{manifest_path}: classes {sorted(classes)} do not match the discovery's {sorted(known)} "
                "or the grammar's symbols"
            )
        models.classes_ = dict(sorted(classes.items()))
        return models


# ------------------------------------------------------------------------------------------ helpers
def _lookup(models: Mapping[int, ClassModel], model_id: object, what: str, plural: str) -> ClassModel:
    """``models[model_id]``, or an error listing the ids there are."""
    try:
        return models[int(model_id)]
    except (KeyError, TypeError, ValueError):
        raise InvalidInputError(f"no {what} {model_id!r}; {plural}: {sorted(models)}") from None


def _entries(manifest_path: Path, manifest: dict, key: str) -> list[dict]:
    """The manifest's list ``key`` of models, each an object with an int id and its file ``<prefix>_<id>.npz``."""
    prefix = {"classes": "class", "actions": "action"}[key]
    entries = manifest.get(key)
    if not isinstance(entries, list):
        raise DataFileError(f"{manifest_path}: entry {key} must be a list of models")
    for entry in entries:
        if not isinstance(entry, dict) or not isinstance(entry.get("id"), int) or entry.get("file") != f"{prefix}_{entry.get('id')}.npz":
            raise DataFileError(f"{manifest_path}: entry {key}[{entry.get('id') if isinstance(entry, dict) else entry!r}] "
                                f"must hold an int id and its file {prefix}_<id>.npz")
    return entries


def _entry_model(directory: Path, entry: dict, key: str, prefix: str, width: int) -> ClassModel:
    """One model of the manifest, its numbers checked and its PHMM loaded and matched against them."""
    manifest_path = directory / MANIFEST
    where = f"{manifest_path}: entry {key}[{entry['id']}]"
    centre = finite_array(manifest_path, f"{key}[{entry['id']}].effect_centre", entry.get("effect_centre"), (EFFECT_DIM,))
    basis = np.asarray(entry.get("effect_basis"), dtype=float)
    if basis.ndim != 2 or basis.shape[0] != EFFECT_DIM or not np.all(np.isfinite(basis)):
        raise DataFileError(f"{where}: effect_basis must be a finite (6, r) matrix; got shape {basis.shape}")
    phmm = ParametricHMM.load(directory / entry["file"])
    if phmm.mean_bar_.shape[1] != width or phmm.W_.shape[2] != basis.shape[1]:
        raise DataFileError(
            f"{directory / entry['file']}: the model has {phmm.mean_bar_.shape[1]} features and "
            f"{phmm.W_.shape[2]} effect directions; the manifest says {width} and {basis.shape[1]}"
        )
    leave = entry.get("exit_probability")
    if isinstance(leave, bool) or not isinstance(leave, (int, float)) or not 0.0 < leave <= 1.0:
        raise DataFileError(f"{where}: exit_probability must be a probability in (0, 1]; got {leave!r}")
    return ClassModel(entry["id"], str(entry["kind"]), phmm, centre, basis, float(leave))


def _unique_profiles(profiles: Sequence[Mapping]) -> tuple[dict, ...]:
    """Distinct demonstrator profiles in first-seen order, as JSON-ready dicts."""
    unique: list[dict] = []
    for profile in profiles:
        if not isinstance(profile, Mapping) or "name" not in profile:
            raise InvalidInputError(f"a demonstrator is a profile mapping with a name; got {profile!r}")
        if dict(profile) not in unique:
            unique.append(dict(profile))
    return tuple(unique)


def _profiles_entry(manifest_path: Path, value: object) -> tuple[dict, ...]:
    """The manifest's optional ``demonstrators`` entry (absent in models learned before it existed)."""
    try:
        return _unique_profiles(value) if isinstance(value, list) else _unique_profiles([value])
    except InvalidInputError as exc:
        raise DataFileError(f"{manifest_path}: entry demonstrators: {exc}; accepted: a list of profiles") from None


def _stretch(H: np.ndarray, factor: float) -> np.ndarray:
    """The movement ``H`` (T, D) performed ``factor`` times as long: resampled linearly in time."""
    n = max(2, int(round(len(H) * factor)))
    t = np.linspace(0.0, len(H) - 1.0, n)
    return np.stack([np.interp(t, np.arange(len(H)), column) for column in H.reshape(len(H), -1).T], axis=1)


def _split(H: np.ndarray, lengths: Sequence[int]) -> list[np.ndarray]:
    H = np.asarray(H, dtype=float)
    if H.ndim == 3:
        H = H.reshape(len(H), -1)
    if H.ndim != 2 or H.shape[1] % 3 or not np.all(np.isfinite(H)):
        raise InvalidInputError(f"H must be finite markers (N, 3M) or (N, M, 3); got shape {np.shape(H)}")
    lengths = np.asarray(lengths)
    if lengths.ndim != 1 or not np.issubdtype(lengths.dtype, np.integer) or np.any(lengths < 1) or lengths.sum() != len(H):
        raise InvalidInputError(f"lengths must be positive ints summing to len(H) = {len(H)}; got {lengths!r}")
    return np.split(H, np.cumsum(lengths)[:-1])


def _check_phi(phi: np.ndarray) -> np.ndarray:
    phi = np.asarray(phi, dtype=float)
    if phi.shape != (EFFECT_DIM,) or not np.all(np.isfinite(phi)):
        raise InvalidInputError(f"phi must be 6 finite numbers, initial and final xyz (m); got {phi!r}")
    return phi


def _pooled_variances(models: list[ParametricHMM], frames: list[int], reg_covar: float) -> np.ndarray:
    """Within-state variances (D,) pooled over classes, each weighted by its training frames."""
    def variances(model: ParametricHMM) -> np.ndarray:
        covars = model.covars_ if model.covariance_type == "diag" else np.diagonal(model.covars_, axis1=1, axis2=2)
        return np.maximum((covars - reg_covar).mean(axis=0), 0.0) + reg_covar

    total = float(sum(frames))
    return sum(n / total * variances(m) for m, n in zip(models, frames))
