"""What the tracker needs of learned models, gathered in one value: the classes' PHMMs with their effect maps,
the grammar that orders them, the markers, and optionally a posture model that poses the shoulder and elbow
from the hand.

:class:`~hoap_actions.primitives.models.action_models.ActionModels` carry all of it but the posture model
(:meth:`TrackingModels.from_action_models`); the paper's tracking experiment builds one from a single approach
PHMM trained on a grid of reaches (:mod:`~hoap_actions.tracking.grid_experiment`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.demonstration.tasks import MARKER_NAMES
from hoap_actions.errors import InvalidInputError, MissingModelPartWarning
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.posture import PostureModel, choose_alpha
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.models.class_models import ClassModel
from hoap_actions.primitives.models.hand_modes import HandModes

__all__ = ["POSTURE_GROUPS", "TrackingModels", "posture_from_recording"]

POSTURE_GROUPS = 8  # groups of episodes left out in turn when a posture model's penalty is chosen


@dataclass(frozen=True, eq=False)
class TrackingModels:
    """The classes ``{id: ClassModel}``, their fitted :class:`ActionGrammar` (its symbols are class ids), the
    marker names, the index of the marker whose path is an approach's effect (``hand_marker``) and an optional
    fitted :class:`PostureModel` (markers in the recordings' order: shoulder, elbow, then the hand).

    ``object_end``: where an approach ends relative to the block it reaches, when the models know it: an offset
    (3,) m (x, y from the block; z the end's height) and a spread (m). None: the tracker learns the offset from
    the classes' training effects (:attr:`ActionTracker.hand_from_object`) and uses its default spread.
    ``approach_ends``: where the training approaches ended, ``(n, 3)`` (the hand's x and y from the object's, its
    height; ``ActionModels.approach_ends_``), from which the tracker draws approach goals around a seen block
    when ``object_end`` is not given. ``hand_modes``: the ways the hand is held through a demonstration, with the
    classes refitted per mode (``ActionModels.hand_modes_``); the tracker's particles then hold a mode each."""

    classes: Mapping[int, ClassModel]
    grammar: ActionGrammar
    marker_names: tuple[str, ...]
    hand_marker: int
    posture: PostureModel | None = None
    object_end: tuple[np.ndarray, float] | None = None
    approach_ends: np.ndarray | None = None
    hand_modes: HandModes | None = None

    def __post_init__(self) -> None:
        if not self.classes:
            raise InvalidInputError("tracking needs at least one class model")
        check_is_fitted(self.grammar)
        unknown = sorted({int(s) for s in self.grammar.symbols_} - {int(c) for c in self.classes})
        if unknown:
            raise InvalidInputError(f"the grammar names classes {unknown} that have no model (models: "
                                    f"{sorted(self.classes)})")
        if not 0 <= self.hand_marker < len(self.marker_names):
            raise InvalidInputError(f"hand_marker must index one of the {len(self.marker_names)} markers; got "
                                    f"{self.hand_marker}")
        if self.object_end is not None:
            offset, spread = self.object_end
            if np.shape(offset) != (3,) or not np.all(np.isfinite(offset)) or not (np.isfinite(spread) and spread > 0):
                raise InvalidInputError(f"object_end must be an offset (3,) m and a spread > 0 m; got "
                                        f"{self.object_end!r}")
        if self.approach_ends is not None and (np.ndim(self.approach_ends) != 2 or np.shape(self.approach_ends)[1] != 3
                                               or len(self.approach_ends) == 0
                                               or not np.all(np.isfinite(self.approach_ends))):
            raise InvalidInputError(f"approach_ends must be finite (n, 3) rows (m), n >= 1; got shape "
                                    f"{np.shape(self.approach_ends)}")
        if self.hand_modes is not None:
            strangers = sorted({cid for cid, _ in self.hand_modes.classes} - {int(c) for c in self.classes})
            if strangers:
                raise InvalidInputError(f"hand modes refit classes {strangers} that have no model (models: "
                                        f"{sorted(self.classes)})")
            uneven = sorted(key for key, m in self.hand_modes.classes.items()
                            if m.phmm.n_states != self.classes[key[0]].phmm.n_states)
            if uneven:
                raise InvalidInputError(f"hand-mode classes {uneven} must have their class's number of states")
        if self.posture is not None:
            check_is_fitted(self.posture)
            if tuple(self.marker_names) != MARKER_NAMES:
                raise InvalidInputError(f"a posture model poses the markers {list(MARKER_NAMES)}; these models have "
                                        f"{list(self.marker_names)}")

    @classmethod
    def from_action_models(cls, models: ActionModels, posture: PostureModel | None = None) -> TrackingModels:
        """The tracker's view of fitted action models, with ``posture`` if given (else the models' own posture
        model, ``posture_``, when they carry one). Classes are posed by the models' pose classes
        (``pose_classes_``: every class, or approach and remove in models learned before manipulations were
        posed) when they have them; models without (learned before them, or without ``pose_mean_model``) track
        with their recognition classes, and a warning says so. The approaches' training ends come along
        (``approach_ends_``); models learned with object poses before they were kept warn that they lack them. So do
        the hand modes (``hand_modes_``), when the models have them."""
        check_is_fitted(models)
        posture = posture if posture is not None else getattr(models, "posture_", None)
        if models.pose_mean_model is None:  # learned without them, or loaded from a directory made before them
            warnings.warn("these action models have no pose classes (learned without pose_mean_model, or before "
                          "models kept them): the tracker poses the arm with their recognition classes; "
                          "learn them with pose_mean_model='tps' for the tracker's figures", MissingModelPartWarning,
                          stacklevel=2)
        ends = getattr(models, "approach_ends_", None)
        if ends is None and models.actions_:  # learned with object poses, before models kept where approaches end
            warnings.warn("these action models have no approach ends (learned before models kept them): the tracker "
                          "draws approach goals around the seen block with one spread; learn them again for the "
                          "tracker's figures", MissingModelPartWarning, stacklevel=2)
        return cls({**models.classes_, **models.pose_classes_}, models.grammar_, tuple(models.marker_names_),
                   int(models.discovery_.hand_marker), posture, approach_ends=ends,
                   hand_modes=getattr(models, "hand_modes_", None))


def posture_from_recording(demos: Demonstrations, n_groups: int = POSTURE_GROUPS) -> PostureModel:
    """A :class:`PostureModel` of every frame of a training recording (e.g. one the action models learned
    from), its penalty chosen by leaving out one of ``n_groups`` groups of whole episodes at a time (every
    ``n_groups``-th episode in a group: each holds every action). Frames with a missing marker are left out.
    Save it (``.save(path)``) for ``hoap-actions track --posture``."""
    if tuple(demos.marker_names) != MARKER_NAMES:
        raise InvalidInputError(f"the recording's markers {list(demos.marker_names)} are not {list(MARKER_NAMES)}")
    if isinstance(n_groups, bool) or not isinstance(n_groups, (int, np.integer)) or not 2 <= n_groups <= len(demos):
        raise InvalidInputError(f"n_groups must be an int from 2 to the recording's {len(demos)} episodes; got "
                                f"{n_groups!r}")
    frames = [episode.H.reshape(episode.T, -1) for episode in demos]
    frames = [x[np.all(np.isfinite(x), axis=1)] for x in frames]
    groups = [frames[k::n_groups] for k in range(n_groups)]
    alpha, _ = choose_alpha(groups)
    return PostureModel(alpha=alpha).fit(np.concatenate(frames))
