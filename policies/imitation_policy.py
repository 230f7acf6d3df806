"""Doing to the robot's block what a demonstration did to the person's: from an action and its effect
to the hand skills of :mod:`~hoap_actions.policies.block_skills`.

:class:`BlockImitation` is the part every imitation policy shares: given what was shown (an
:class:`Intent`: the action, and for a push, move or rotate the block's displacement on the robot's
table and its turn), it looks at its own block with the overhead camera, sets the target (its own start
moved and turned by the effect: the same at both of ``Imitate-v0``'s levels) and runs the skills:

- approach: the hand over the block, held there;
- move: the block grasped, slid over the table to the target and let go (:meth:`BlockHand.place`),
  unless the target is turned as the grasp cannot leave it (an inner push's or a turn through's);
- push, rotate, and a move that left it off: a thumb push along the line through the target that
  leaves the block turned as the target (:meth:`BlockHand.push`), the block first slid behind the
  target on that line when it is not there (or too close to it to turn on the way).

It then looks again and, while the episode lasts, tries once more from where the block is.
Subclasses say where the intent comes from: :class:`ExecutionCeiling` takes the true one from the env
(the oracle), so what it misses is what execution misses; :class:`FrequentImitation` always does the
same one (the most frequent action with its mean effect), the baseline that ignores the demonstration;
:class:`MarkerImitation` reads it from the demonstration's recorded markers and block path with the
action models (the oracle of vision); :class:`CameraImitation` watches the demonstration's camera
frames, as a person would show them.
"""

from __future__ import annotations

import logging
import time
from abc import ABC, abstractmethod
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import gymnasium
import numpy as np

from hoap_actions.demonstration.tasks import MARKER_NAMES
from hoap_actions.envs import world
from hoap_actions.envs.controls import HAND_CONTROL_MODES
from hoap_actions.errors import InvalidInputError
from hoap_actions.imitation.goals import block_turn
from hoap_actions.models.shipped import load_default_models
from hoap_actions.policies.block_skills import BlockHand

if TYPE_CHECKING:
    from hoap_actions.imitation.reading import DemonstrationReading
    from hoap_actions.imitation.watching import WatchedDemonstration

__all__ = ["ACTIONS", "BlockImitation", "DoNothing", "CameraImitation", "ExecutionCeiling", "FrequentImitation",
           "Intent", "MarkerImitation", "frequent_intent", "intent_of"]

logger = logging.getLogger(__name__)

ACTIONS = ("approach", "move", "push", "rotate")
MAX_ATTEMPTS = 3  # tries at the block's target within one episode (each after a fresh look)


@dataclass(frozen=True)
class Intent:
    """What a demonstration did, on the robot's table: the ``action`` (one of :data:`ACTIONS`), the block's
    ``displacement`` (2,) (m, robot table) and its ``turn`` about the vertical (rad)."""

    action: str
    displacement: np.ndarray
    turn: float

    def __post_init__(self) -> None:
        if self.action not in ACTIONS:
            raise InvalidInputError(f"action {self.action!r} is not one the robot imitates; accepted: {list(ACTIONS)}")


def intent_of(action: str, human_start: np.ndarray, human_end: np.ndarray) -> Intent:
    """The :class:`Intent` of a demonstration whose block went from ``human_start`` to ``human_end`` (6,:
    centre m and rotation vector rad, the person's table): the displacement mapped to the robot's table
    by the project's one human-to-robot scale, the turn as it was."""
    start, end = np.asarray(human_start, float), np.asarray(human_end, float)
    if action == "approach":
        return Intent(action, np.zeros(2), 0.0)
    turn = block_turn(start, end)
    return Intent(action, world.HUMAN_TO_ROBOT_SCALE * (end[:2] - start[:2]), turn)


def frequent_intent(shown: Sequence[tuple[str, np.ndarray, np.ndarray]]) -> Intent:
    """The most frequent action among demonstrations given as (action, human block start, human block end)
    and its mean effect on the robot's table (the displacements' mean, the turns' circular mean): what a
    robot that ignores the demonstration before it would best do. Ties go to the first of :data:`ACTIONS`."""
    if not shown:
        raise InvalidInputError("frequent_intent needs at least one demonstration")
    intents = [intent_of(action, start, end) for action, start, end in shown]
    counts = Counter(intent.action for intent in intents)
    action = max(ACTIONS, key=lambda a: (counts[a], -ACTIONS.index(a)))
    mine = [intent for intent in intents if intent.action == action]
    turn = float(np.angle(np.mean(np.exp(1j * np.array([intent.turn for intent in mine])))))
    return Intent(action, np.mean([intent.displacement for intent in mine], axis=0), turn)


class BlockImitation(ABC):
    """``obs -> action`` on ``hoap_actions/Imitate-v0`` (the :class:`~hoap_actions.apps.episodes.Policy`
    protocol): the skills for an :class:`Intent` (module docstring). Subclasses give the intent
    (:meth:`intent`). Its own control mode is ``"ee_heading_delta"``: a push whose face lies past the thumb's
    closed stop turns the hand left instead of turning the block through
    (:class:`~hoap_actions.policies.block_skills.BlockHand`); in an ``"ee_delta"`` env the hand is headed as
    the IK chooses."""

    control_mode = "ee_heading_delta"
    env_ids = ("hoap_actions/Imitate-v0",)
    taken_from = "told the true action"  # how the intent was had, written on the video
    failure: str | None

    def __init__(self, env: gymnasium.Env) -> None:
        spec_id = getattr(env.spec, "id", None)
        if spec_id not in self.env_ids:
            raise InvalidInputError(f"{type(self).__name__} imitates a demonstration on its block; it needs one of "
                                    f"{list(self.env_ids)}, not {spec_id or type(env).__name__}")
        control_mode = env.get_wrapper_attr("control_mode")
        if control_mode not in HAND_CONTROL_MODES:
            raise InvalidInputError(f"{type(self).__name__} needs control_mode in {list(HAND_CONTROL_MODES)}; this env "
                                    f"uses {control_mode!r}")
        self.env = env
        self.hand = BlockHand(env)
        self.failure = None
        self._reading_s = self._filming_s = 0.0
        self.finished = False
        self.program: Iterator[np.ndarray] | None = None

    @abstractmethod
    def intent(self) -> Intent | None:
        """What this episode's demonstration did, or None when it cannot be told (then :attr:`failure`
        says why)."""

    def shown_markers(self) -> np.ndarray | None:
        """The person's arm markers (T, M, 3) m, frame by frame, as this policy took them (None: not at all)."""
        return None

    def shown_frames(self) -> list[np.ndarray]:
        """The demonstration's camera frames as this policy took them, for the episode's video: the arm it
        estimated or read drawn on each, the action it did written on them."""
        from hoap_actions.imitation.film import annotated_frames

        demonstration = self.env.get_wrapper_attr("demonstration")()
        action = "not recognised" if self.shown is None else self.shown.action
        lines = [f"demonstration, {self.taken_from}", f"taken as: {action}"]
        return annotated_frames(demonstration, self.shown_markers(), MARKER_NAMES, lines)

    def reading_s(self) -> float:
        """Wall time (s) this episode's :meth:`intent` took reading the demonstration (its filming left out)."""
        return self._reading_s

    def filming_s(self) -> float:
        """Wall time (s) the env took to film the demonstration when :meth:`intent` first asked for its
        frames (a real camera films while the person acts); 0 for a policy that reads none."""
        return self._filming_s

    @property
    def skills(self) -> list[str]:
        """The hand skills this episode ran, in order (``"approach"``, ``"place"``, ``"push"``, ``"inner push"``,
        ``"turn through"``)."""
        return self.hand.skills

    @property
    def done(self) -> bool:
        """True once every attempt has run (the block did not reach its target)."""
        return self.finished and self.failure is None

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        self.hand.start(obs)
        self.failure, self.finished = None, False
        started, self._filming_s = time.perf_counter(), 0.0
        self.shown = self.intent()
        self._reading_s = time.perf_counter() - started - self._filming_s
        self.start_block = self.hand.look()
        if self.shown is None:
            self.failure = self.failure or "not recognised"
        elif self.start_block is None:
            self.failure = "block not seen"
        self.program = self._program() if self.failure is None else None

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        self.hand.observe(obs)
        if self.program is not None:
            try:
                return next(self.program)
            except StopIteration:
                self.program, self.finished = None, True
        return self.hand.still()

    def _program(self) -> Iterator[np.ndarray]:
        shown, block = self.shown, self.start_block
        if shown.action == "approach":
            yield from self.hand.approach(block.xy)
            return
        target = block.xy + shown.displacement
        yaw = block.yaw + shown.turn
        face = self.hand.push_face(target, yaw)
        inner = self.hand.inner_face(target, yaw, face)  # None: the outer face's push
        first = None if inner is not None else self.hand.overturn_face(target, yaw, face)  # None: the usual push
        if shown.action == "move" and inner is None and first is None:  # a grasp leaves it turned as the hand
            yield from self.hand.place(block, target)
        for _ in range(MAX_ATTEMPTS):
            block = self.hand.look()
            if block is None:
                self.failure = "block not seen"
                return
            logger.debug("block at %s turned %.1f deg; target %s turned %.1f deg (face %.1f deg%s)",
                         np.round(block.xy, 4), np.degrees(block.yaw), np.round(target, 4), np.degrees(yaw),
                         np.degrees(face), "" if first is None else f", turned through from {np.degrees(first):.1f}"
                         + ("" if inner is None else f", inner face {np.degrees(inner):.1f}"))
            if inner is not None:
                seen = yield from self.hand.push_to(block, target, inner, inner=True)
            elif first is not None:
                seen = yield from self.hand.turn_through(block, target, face, first)
            else:
                seen = yield from self.hand.push_to(block, target, face)
            if not seen:
                self.failure = "block not seen"
                return


class ExecutionCeiling(BlockImitation):
    """The execution ceiling of ``Imitate-v0``: the true action and effect of the demonstration, from the
    env's privileged accessor (``true_demonstration``, an oracle no imitating policy may call), done by
    the block skills. What it misses is lost in execution alone."""

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        self._truth = env.get_wrapper_attr("true_demonstration")

    def intent(self) -> Intent:
        shown = self._truth()
        return intent_of(shown.action, shown.object_start, shown.object_end)


class MarkerImitation(BlockImitation):
    """Imitation from the demonstration's recorded markers and block path (``--from-markers``), read with
    the shipped action models (:func:`~hoap_actions.imitation.reading.read_markers`): what it misses
    beyond :class:`ExecutionCeiling` is lost in recognition, none in vision. The markers and path come
    from the env's evaluation accessor, of which it reads nothing else."""

    taken_from = "read from its markers"

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        self._truth = env.get_wrapper_attr("true_demonstration")
        self.models = load_default_models()
        self.reading: DemonstrationReading | None = None

    def intent(self) -> Intent | None:
        from hoap_actions.imitation.reading import read_markers  # here: the registry's importers need no recognition

        shown = self._truth()
        self.reading = read_markers(self.models, shown.H, shown.O)
        if self.reading.action is None:
            return None
        return intent_of(self.reading.action, self.reading.object_start, self.reading.object_end)

    def recognised(self) -> str:
        """The action this episode's reading gave (``"not recognised"`` when none)."""
        return self.reading.action or "not recognised"

    def shown_markers(self) -> np.ndarray:
        """The recorded markers it read."""
        return self._truth().H


class CameraImitation(BlockImitation):
    """Imitation from the demonstration as a camera filmed it (``env.get_wrapper_attr("demonstration")()``:
    frames, the camera, its picture of the empty table), watched with the shipped action models
    (:func:`~hoap_actions.imitation.watching.watch`: the tracker on the arm, the block's top face at both
    ends). ``particles`` and ``seed`` are the tracker's."""

    taken_from = "watched through its camera"

    def __init__(self, env: gymnasium.Env, particles: int = 400, seed: int = 0) -> None:
        super().__init__(env)
        self._demonstration = env.get_wrapper_attr("demonstration")
        self.models = load_default_models()
        self.particles, self.seed = particles, seed
        self.watched: WatchedDemonstration | None = None

    def intent(self) -> Intent | None:
        from hoap_actions.imitation.watching import watch  # here: the tracker is not imported by every command

        started = time.perf_counter()
        demonstration = self._demonstration()  # the env films the person (rendered here, once): not reading time
        self._filming_s = time.perf_counter() - started
        self.watched = watch(self.models, demonstration, self.particles, self.seed)
        reading = self.watched.reading
        if reading.action is None:
            return None
        return intent_of(reading.action, reading.object_start, reading.object_end)

    def recognised(self) -> str:
        """The action this episode's watching gave (``"not recognised"`` when none)."""
        return self.watched.reading.action or "not recognised"

    def shown_markers(self) -> np.ndarray:
        """The markers the tracker estimated, frame by frame."""
        return np.stack([frame.markers for frame in self.watched.frames])


class FrequentImitation(BlockImitation):
    """The baseline that ignores the demonstration: every episode it does the same ``intent`` (from
    :func:`frequent_intent` over demonstrations it was fitted on) to its block."""

    taken_from = "not looked at (the most frequent action)"

    def __init__(self, env: gymnasium.Env, intent: Intent | None = None) -> None:
        if not isinstance(intent, Intent):
            raise InvalidInputError("the frequent-action baseline needs its intent: Intent from frequent_intent() over "
                                    f"demonstrations it may see; got {intent!r}")
        super().__init__(env)
        self._intent = intent

    def intent(self) -> Intent:
        return self._intent


class DoNothing:
    """The floor of ``Imitate-v0``: the robot does nothing. Its episode ends at once (it is ``done`` from the
    reset on), scored on the world as reset: no block is at its target, no hand over its block."""

    failure: str | None = None
    done = True
    control_mode = "ee_heading_delta"  # the imitation policies' own, so that it runs beside them
    env_ids = ("hoap_actions/Imitate-v0",)

    def __init__(self, env: gymnasium.Env) -> None:
        self._shape = env.action_space.shape  # all it reads

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """Nothing to reset."""

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return np.zeros(self._shape, dtype=np.float32)
