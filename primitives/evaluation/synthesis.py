"""Whole-action synthesis against held-out demonstrations: how closely a synthesised action follows the hand.

Every manipulation run that the models' discovery cuts from a held-out object trajectory (its pieces
joined, as :mod:`~hoap_actions.primitives.models.whole_actions` joins training runs) is synthesised by its whole
action (:attr:`ActionModels.action_of_class_` of its first piece) at phi = the object's start and end,
with the run's length; its error is the median over frames of the hand marker's distance to the
demonstrator's. Baseline, to show what the model adds: the hand moving in a straight line, at the
demonstrator's own pace along it, between the demonstrator's own start and end (information the
model is not given).
"""

from __future__ import annotations

import warnings

import numpy as np

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.errors import ExtrapolationWarning, InvalidInputError
from hoap_actions.primitives.discovery.estimator import MANIPULATION, UNKNOWN
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.action_models import ActionModels

__all__ = ["whole_action_errors"]


def whole_action_errors(models: ActionModels, demos: Demonstrations) -> dict[int, dict]:
    """Per manipulation action: ``runs``, the model's and the baseline's median hand errors (m) per run."""
    if not models.actions_:
        raise InvalidInputError("these models have no action level; learn them with hoap-actions learn")
    discovery, hand = models.discovery_, models.discovery_.hand_marker
    labels = discovery.predict(np.concatenate([e.O for e in demos]), [e.T for e in demos])
    result: dict[int, dict] = {}
    for episode, frames in zip(demos, labels):
        pieces = [r for r in runs(frames) if r[0] != UNKNOWN and discovery.primitive_kinds_[r[0]] == MANIPULATION]
        if not pieces or any(a[2] != b[1] for a, b in zip(pieces, pieces[1:])):
            continue  # no manipulation, or one broken by frames discovery cannot parse
        start, end = pieces[0][1], pieces[-1][2]
        action = models.action_of_class_[pieces[0][0]]
        phi = np.r_[episode.O[start, :3], episode.O[end - 1, :3]]
        with warnings.catch_warnings():  # a held-out run may reach a little beyond the training range
            warnings.simplefilter("ignore", ExtrapolationWarning)
            made = models.synthesize_action(action, phi, n_frames=end - start)[:, hand]
        shown = episode.H[start:end, hand]
        entry = result.setdefault(action, {"runs": 0, "model_m": [], "baseline_m": [],
                                           "lift_m": models.action_lifts_[action]})
        entry["runs"] += 1
        entry["model_m"].append(float(np.median(np.linalg.norm(made - shown, axis=1))))
        entry["baseline_m"].append(float(np.median(np.linalg.norm(_straight(shown) - shown, axis=1))))
    return dict(sorted(result.items()))


def _straight(path: np.ndarray) -> np.ndarray:
    """The straight line from the path's start to its end, travelled at the path's own pace."""
    travelled = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
    share = travelled / travelled[-1] if travelled[-1] > 0 else np.zeros(len(path))
    return path[0] + share[:, None] * (path[-1] - path[0])
