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

Choices (each measured on a validation split of ``paper`` recordings; figures and history in
``docs/experiments/recognition.md``):

- **Observations**: the 6 markers' positions (18-D) and their displacement over 0.1 s (18-D): the
  successive pieces of one push or carry move the hand alike and differ mostly in speed.
- **Effect**: phi = (initial, final) 3-D location, of the object for a manipulation and of the hand
  marker for approach and remove, as in the paper. Each class's PHMM sees phi reduced to the principal
  directions in which its training effects vary by more than ``effect_tol`` (at most ``n_segments - 2``
  of them): the object stays on the table, so z never varies and a 6-D phi would not be identifiable.
  Every public method speaks the full 6-D phi.
- **States**: the class's shortest training segment's frames times ``state_fraction``, at most
  ``max_states``; diagonal covariances.
- **Variance prior**: manipulation classes have a handful of segments, whose state variances would
  collapse onto ``reg_covar``; they are refitted with a conjugate prior (``covars_weight`` frames per
  state) on the within-state variances pooled over all of them.
- **Recognising a piece** (cuts known): the class whose chain, over its training effects, explains
  the displacements best (the evidence connected recognition reads); phi is then estimated by the best
  classes' PHMMs.
- **Decoding pieces** (cuts known): the strict grammar of the transitions seen in training; a piece
  shorter than a class's chain costs that class ``unexplained_penalty`` nats instead of ruling it out;
  neighbouring manipulation pieces must agree on the object's location at their cut
  (``continuity_weight``, :mod:`~hoap_actions.primitives.models.effect_continuity`); then discovery
  parses the object trajectory estimated from the hand
  (:mod:`~hoap_actions.primitives.models.object_estimate`) and each piece's class in that parse gets
  ``object_vote`` nats before the grammar decodes again: discovery's classes are what the object did,
  and neighbouring classes differ by a centimetre of object motion that the arm hardly shows.
- **Decoding a whole movement** (:meth:`ActionModels.decode`, markers alone): connected recognition
  over the classes' chains (:mod:`~hoap_actions.primitives.models.connected_recognition`) on the
  displacement features only (over the training effects a state's positions spread across the table),
  ``stay_weight`` 2, then the same object vote per frame and Viterbi again.

Files: :meth:`ActionModels.save` writes a models directory (layout in
:mod:`~hoap_actions.primitives.models.models_directory`); :meth:`ActionModels.load` validates every file
and names the one that is wrong.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import sys
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from tqdm import tqdm

from hoap_actions.demonstration.tasks import MARKER_NAMES
from hoap_actions.errors import ExtrapolationWarning, InvalidInputError, NotFittedError
from hoap_actions.outputs import claimed_directory
from hoap_actions.primitives.base import Estimator, check_is_fitted
from hoap_actions.primitives.discovery.estimator import MANIPULATION, PrimitiveDiscovery
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.discovery.groups import action_groups
from hoap_actions.primitives.discovery.primitive_classes import PrimitiveClass
from hoap_actions.primitives.hmm.parametric_hmm import EXTRAPOLATION_MARGIN, ParametricHMM
from hoap_actions.primitives.models.approach_ends import fit_approach_ends
from hoap_actions.primitives.models.class_models import (
    EFFECT_DIM,
    PHI_NAMES,
    ClassModel,
    DecodedSegment,
    SegmentRecognition,
    lookup_model,
    marker_features,
)
from hoap_actions.primitives.models.connected_recognition import exit_probability
from hoap_actions.primitives.models.decoding import ActionDecoding
from hoap_actions.primitives.models.hand_modes import HandModes, fit_hand_modes
from hoap_actions.primitives.models.models_directory import (
    FORMAT_VERSION,
    KIND,
    foreign_entries,
    models_from_directory,
    read_models_directory,
    unique_profiles,
    write_models_directory,
)
from hoap_actions.primitives.models.object_estimate import HAND_FRAME_MARKERS, fit_grasp_offset
from hoap_actions.primitives.models.whole_actions import action_level

logger = logging.getLogger(__name__)

__all__ = ["ActionModels", "ClassModel", "DecodedSegment", "SegmentRecognition", "marker_features"]

class ActionModels(ActionDecoding, Estimator):
    """Learn, recognise and synthesise with one PHMM per discovered class (module docstring: the choices).

    Parameters
    ----------
    covariance_type, reg_covar
        the PHMMs' (see :class:`ParametricHMM`).
    covars_weight
        frames per state of the manipulation classes' pooled variance prior (0: none).
    effect_tol
        least spread (m) of a phi direction a class's PHMM models.
    max_states, state_fraction
        states per class (see the module docstring).
    velocity
        append marker displacements to the positions.
    n_restarts
        phi estimates started per class and movement (from the mean training effect, then
        from random training effects).
    n_candidates
        classes :meth:`recognize` estimates phi for: those whose chains, over their
        training effects, explain the movement best (effect continuity compares their phis).
    unexplained_penalty
        nats a class pays for a piece shorter than its chain (``None``: ruled out).
    continuity_weight
        nats per m^2 of gap between neighbouring manipulation pieces' effects (0: off).
    stay_weight
        power on self-transition probabilities in connected recognition (:meth:`decode`).
    object_vote
        nats that each piece (:meth:`decode_segments`) or each frame (:meth:`decode`) gives
        its class in discovery's parse of the object trajectory estimated from the hand
        (:meth:`object_parse`; 0: off; models learned without object poses have no grasp offset and
        cannot vote).
    mean_model, smoothing
        how each PHMM's state means depend on phi (see :class:`ParametricHMM`).
    speed_augmentation
        time-stretch factors (in [0.5, 2]); every class's training movement is also
        fitted as if performed that many times as long (resampled in time), so that the chains accept a
        demonstrator slower or faster than those seen. ``()`` (default): none.
    pose_mean_model
        ``"tps"`` or ``"linear"``: also fit every class again with that mean model, the classes the tracker
        poses the arm with (``pose_classes_``); recognition and synthesis keep ``classes_``. ``None``
        (default): none.
    pose_hand_modes
        how many ways of holding the hand (:mod:`~hoap_actions.primitives.models.hand_modes`) the pose classes
        are also refitted for (``hand_modes_``); 0 (default): none.
    progress
        show a bar over the class fits when stderr is a terminal (not saved with the models).

    Attributes
    ----------
    classes_
        dict class id -> :class:`ClassModel`.
    grammar_, discovery_
        the :class:`ActionGrammar` of the classes and the :class:`PrimitiveDiscovery` they came from.
    fps_, marker_names_, covars_prior_
        the recordings' frame rate and markers, and the manipulation classes' variance prior.
    actions_, action_lifts_, action_of_class_
        the action level: dict id -> :class:`ClassModel` of a whole action, dict id -> the highest lift
        (m) of the object in its runs, dict class id -> the whole action its pieces belong to; all
        empty without object poses.
    demonstrators_
        the profiles of who demonstrated (empty: not known).
    grasp_offset_
        (3,) the object's centre in the hand's frame while the hand moves it (m; ``None`` when learned
        without object poses).
    approach_ends_
        (n, 3) where each training approach ended: the hand's x and y from the object's, and its height (m)
        (:mod:`~hoap_actions.primitives.models.approach_ends`; ``None`` when learned without object poses,
        or before models kept it); the tracker draws approach goals around a seen block from them.
    pose_classes_
        dict class id -> :class:`ClassModel` of every class refitted with ``pose_mean_model`` (the same
        segments, states and effects; empty without it; models learned before 2026-12-06's third session
        hold approach and remove only, and the tracker poses the others with ``classes_``).
    hand_modes_
        the :class:`~hoap_actions.primitives.models.hand_modes.HandModes` the tracker poses the arm with per way
        of holding the hand (``None`` without ``pose_hand_modes``, or in models learned before them).
    """

    _learned = ("classes_", "grammar_", "discovery_", "fps_", "marker_names_", "covars_prior_", "actions_",
                "action_lifts_", "action_of_class_", "demonstrators_", "grasp_offset_", "approach_ends_",
                "pose_classes_", "hand_modes_")
    _file_kind = KIND
    _format_version = FORMAT_VERSION
    _readable_versions = (1, 2, 3, 4, 5, FORMAT_VERSION)

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
        pose_mean_model: str | None = None,
        pose_hand_modes: int = 0,
        progress: bool = False,
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
        self.pose_mean_model = pose_mean_model
        self.pose_hand_modes = pose_hand_modes
        self.progress = progress

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
        if self.pose_mean_model not in (None, "linear", "tps"):
            raise InvalidInputError(f"pose_mean_model must be None, 'linear' or 'tps'; got {self.pose_mean_model!r}")
        if self.unexplained_penalty is not None:
            number("unexplained_penalty", 0.0)
        if isinstance(self.pose_hand_modes, bool) or not isinstance(self.pose_hand_modes, (int, np.integer)) \
                or self.pose_hand_modes < 0:
            raise InvalidInputError(f"pose_hand_modes must be an int >= 0; got {self.pose_hand_modes!r}")
        for name in ("max_states", "n_restarts", "n_candidates"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise InvalidInputError(f"{name} must be an int >= 1; got {value!r}")
        factors = self.speed_augmentation
        if not isinstance(factors, (tuple, list)) or not all(
                isinstance(f, (int, float)) and not isinstance(f, bool) and 0.5 <= f <= 2.0 and f != 1.0
                for f in factors):
            raise InvalidInputError(f"speed_augmentation must be a tuple of time-stretch factors in [0.5, 2], not 1; "
                                    f"got {factors!r}")
        for name in ("velocity", "progress"):
            if not isinstance(getattr(self, name), bool):
                raise InvalidInputError(f"{name} must be True or False; got {getattr(self, name)!r}")

    DECODING_PARAMS = ("n_restarts", "n_candidates", "unexplained_penalty", "continuity_weight", "stay_weight",
                       "object_vote")
    """Hyper-parameters that only recognition reads: fitted models take new values of these without a refit."""

    _refit_free_params = (*DECODING_PARAMS, "progress")
    _unsaved_params = ("progress",)

    def _params_changed(self, names: set[str]) -> None:
        if "stay_weight" in names:
            self._chained = None  # the chained HMM is built with it

    # ------------------------------------------------------------------------------------- fit
    def fit(
        self,
        X: np.ndarray,
        lengths: Sequence[int] | None = None,
        discovery: PrimitiveDiscovery | None = None,
        fps: float | None = None,
        marker_names: Sequence[str] | None = None,
        O: np.ndarray | None = None,
        demonstrators: Sequence[Mapping] = (),
    ) -> ActionModels:
        """Fit one PHMM per class of ``discovery`` and the grammar of its segmentations.

        ``X`` are the demonstrations' arm markers, concatenated ``(N, 18)`` or ``(N, 6, 3)`` (m), with
        ``lengths`` frames each (``None``: one demonstration), recorded at ``fps``; ``discovery`` was
        fitted on the same demonstrations in the same order (its segments index them). With the object
        poses ``O`` ``(N, 6)`` the action level is learned too
        (:mod:`~hoap_actions.primitives.models.whole_actions`): one PHMM per whole action, phi = the
        object's (or the hand's, for approach and remove) start and end. ``demonstrators``: who performed
        the demonstrations (profiles as :meth:`DemonstratorProfile.to_dict` gives them; empty: not
        known), kept so that recognising someone else can warn.
        """
        if discovery is None or fps is None:
            raise InvalidInputError("fit needs the discovery fitted on these demonstrations and their fps: "
                                    "fit(X, lengths, discovery, fps)")
        H = X
        lengths = [len(H)] if lengths is None else lengths
        self._check_params()
        self._chained = None  # built from the fitted classes on first use
        hands = _split(H, lengths)
        if not hasattr(discovery, "classes_"):
            raise NotFittedError("discovery must be a fitted PrimitiveDiscovery (call its fit first)")
        n_demos = len(discovery.segmentations_)
        if n_demos != len(hands):
            raise InvalidInputError(
                f"discovery was fitted on {n_demos} demonstrations but H holds {len(hands)} (lengths); give the same "
                "ones"
            )
        if not (isinstance(fps, (int, float)) and np.isfinite(fps) and fps > 0):
            raise InvalidInputError(f"fps must be a positive number of frames per second; got {fps!r}")
        self.fps_ = float(fps)
        self.marker_names_ = (tuple(marker_names) if marker_names is not None
                              else tuple(f"marker_{i}" for i in range(hands[0].shape[1] // 3)))
        inputs = [marker_features(h, self.fps_, self.velocity) for h in hands]
        stretched = {f: [marker_features(_stretch(h, f), self.fps_, self.velocity) for h in hands]
                     for f in self.speed_augmentation}
        pieces = [c for c in discovery.classes_ if c.kind == MANIPULATION]
        refit = self.covars_weight > 0 and bool(pieces)
        bar = tqdm(total=len(discovery.classes_) + (len(pieces) if refit else 0), desc="fitting class PHMMs",
                   unit="class", disable=not (self.progress and sys.stderr.isatty()))
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
        self.demonstrators_ = unique_profiles(demonstrators)
        self.actions_, self.action_lifts_, self.action_of_class_ = (
            ({}, {}, {}) if O is None else self._fit_actions(inputs, O, lengths))
        self.grasp_offset_ = None if O is None else self._fit_grasp_offset(hands, O, lengths)
        self.approach_ends_ = None if O is None else fit_approach_ends(
            discovery, hands, np.split(np.asarray(O, dtype=float), np.cumsum(lengths)[:-1]))
        self.pose_classes_ = self._fit_pose_classes(inputs, stretched)
        self.hand_modes_ = self._fit_hand_modes(hands, inputs, stretched)
        return self

    def _fit_hand_modes(self, hands: list[np.ndarray], inputs: list[np.ndarray],
                        stretched: dict[float, list[np.ndarray]]) -> HandModes | None:
        """The ways the demonstrators held the hand and the pose classes refitted per way (``pose_hand_modes``)."""
        if not self.pose_hand_modes or tuple(self.marker_names_) != MARKER_NAMES:
            return None
        refit = self._with_mean_model() if self.pose_mean_model else self
        def fit_class(c: PrimitiveClass) -> ClassModel:  # the whole class's count of states: a particle's state indexes
            return refit._fit_class(c, inputs, stretched, None, self.classes_[int(c.primitive_id)].phmm.n_states)

        return fit_hand_modes(self.discovery_.classes_, self.discovery_.segmentations_, hands, fit_class,
                              self.pose_hand_modes)

    def _fit_pose_classes(self, inputs: list[np.ndarray], stretched: dict[float, list[np.ndarray]]
                          ) -> dict[int, ClassModel]:
        """Every class refitted with ``pose_mean_model``: the arm's pose on the way to, at and from the object
        bends with where the object is more than a linear mean follows (validation in
        ``docs/experiments/tracking.md``)."""
        if self.pose_mean_model is None:
            return {}
        refit = self._with_mean_model()
        return {int(c.primitive_id): refit._fit_class(c, inputs, stretched, None) for c in self.discovery_.classes_}

    def _with_mean_model(self) -> ActionModels:
        """An unfitted copy of these hyper-parameters with ``mean_model = pose_mean_model``."""
        return ActionModels(**{**self.get_params(), "mean_model": self.pose_mean_model, "pose_mean_model": None})

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
        return fit_grasp_offset([(hands[d][a:b].reshape(shape), objects[d][a:b])
                                 for d, (a, b) in sorted(spans.items())],
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
                   covars_prior: np.ndarray | None, n_states: int | None = None) -> ClassModel:
        """The class's PHMM from its segments of ``inputs`` and of each time-stretched copy in ``stretched``
        (``n_states``: that many states, else as many as its segments allow)."""
        movements = [inputs[s.demo][s.start:s.end] for s in cls.segments]
        copies = [stretched[f][s.demo][round(s.start * f):round(s.end * f)]
                  for f in self.speed_augmentation for s in cls.segments]
        phis = np.tile(cls.phis, (1 + len(self.speed_augmentation), 1))
        return self._fit_model(int(cls.primitive_id), str(cls.kind), movements + copies, phis, covars_prior,
                               n_original=len(movements), n_states=n_states)

    def _fit_model(self, model_id: int, kind: str, movements: list[np.ndarray], phis: np.ndarray,
                   covars_prior: np.ndarray | None, n_original: int | None = None,
                   n_states: int | None = None) -> ClassModel:
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
        n_states = n_states or max(1, int(min(self.max_states, self.state_fraction * shortest)))
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
        return self._synthesize(lookup_model(self.classes_, class_id, "class", "classes"), phi, n_frames)

    def synthesize_action(self, action_id: int, phi: np.ndarray, n_frames: int | None = None) -> np.ndarray:
        """Marker trajectory ``(T, M, 3)`` (m) of a whole action (``actions_``) for ``phi`` (6,): for
        approach and remove the hand's start and end, for a manipulation the object's. Which
        manipulation carries (lifts) the object: :attr:`action_lifts_` (m)."""
        check_is_fitted(self)
        if not self.actions_:
            raise InvalidInputError("these models have no action level: fit them with the object poses O "
                                    "(hoap-actions learn does), or load a models directory of format_version 2")
        return self._synthesize(lookup_model(self.actions_, action_id, "action", "actions"), phi, n_frames)

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
            ranges = "; ".join(f"{PHI_NAMES[i]} {phi[i]:.3f} m, demonstrated {low[i]:.3f}..{high[i]:.3f} m"
                               for i in far)
            warnings.warn(f"phi is far outside what class {model.class_id}'s demonstrations show ({ranges}): the "
                          "movement is an unchecked extrapolation", ExtrapolationWarning, stacklevel=3)

    # ----------------------------------------------------------------------------------- files
    def _write(self, path: Path, overwrite: bool) -> None:
        """A models directory (:mod:`~hoap_actions.primitives.models.models_directory`) that appears whole once
        complete; an existing one is replaced only with ``overwrite``."""
        with claimed_directory(path, overwrite, what="action models", foreign=foreign_entries) as staging:
            self.write_files(staging)

    def write_files(self, folder: Path) -> None:
        """Write the models' files into ``folder``, an empty directory the caller has claimed
        (:func:`hoap_actions.outputs.claimed_directory`); use :meth:`save` otherwise."""
        check_is_fitted(self)
        write_models_directory(self, Path(folder))

    @classmethod
    def _read(cls, path: Path) -> tuple[object, object, dict]:
        return read_models_directory(path)

    @classmethod
    def _from_file(cls, path: Path, manifest: dict, version: int) -> ActionModels:
        """The models of the directory ``path``: every file validated, each error naming its file and entry."""
        return models_from_directory(cls, path, manifest, version)



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
    if (lengths.ndim != 1 or not np.issubdtype(lengths.dtype, np.integer) or np.any(lengths < 1)
            or lengths.sum() != len(H)):
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
