"""How well discovery holds up: Fig. 7's structure, independence of the order, and two simple baselines.

- :func:`structure_found`: the discovered action groups are the true actions, one each (as many
  groups as true actions, every manipulation group pure, no phase missed): Fig. 7's structure on the
  ``paper`` preset (approach, remove, push and move in four directions, two turns: 12 groups).
- :func:`order_signature`: what a fit found, in terms that do not depend on the order the
  demonstrations came in (each demonstration's segments, by its caller's index, grouped as found), so
  two fits on shuffled copies can be compared.
- Baselines that say what the method adds, scored by the same many-to-one frame accuracy:
  :func:`rest_baseline_labels` (rest before, one manipulation label, rest after: the rest detection
  alone) and :func:`kmeans_baseline_labels` (each demonstration's motion labelled by k-means on its
  displacement, k the number of true manipulations: the effect without the path).
"""

from __future__ import annotations

import numpy as np
from scipy.cluster.vq import kmeans2

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.discovery.groups import action_groups

__all__ = ["kmeans_baseline_labels", "order_signature", "rest_baseline_labels", "structure_found"]

REST_BEFORE, MOVING, REST_AFTER = 0, 1, 2  # the rest baseline's labels


def structure_found(evaluation: dict) -> bool:
    """From :func:`~hoap_actions.primitives.evaluation.discovery.evaluate_discovery`'s report: one pure
    group per true action and none missed (module docstring)."""
    manipulations = [g for g in evaluation["groups"] if g["kind"] == "manipulation"]
    return (evaluation["n_action_groups"] == evaluation["n_true_actions"] and not evaluation["phases_missed"]
            and all(g["manipulation_purity"] == 1.0 for g in manipulations))


def order_signature(model: PrimitiveDiscovery, order: np.ndarray | None = None) -> frozenset:
    """The fitted groups as a set of sets of ``(demonstration, start, end)`` segments; ``order[k]`` is
    the original index of the k-th demonstration the model was fitted on (None: the identity)."""
    check_is_fitted(model)
    group_of = action_groups(model)
    groups: dict[int, set] = {}
    for k, segments in enumerate(model.segmentations_):
        demo = int(order[k]) if order is not None else k
        for pid, start, end in segments:
            groups.setdefault(group_of[pid], set()).add((demo, int(start), int(end)))
    return frozenset(frozenset(g) for g in groups.values())


def rest_baseline_labels(model: PrimitiveDiscovery, demos: Demonstrations) -> list[np.ndarray]:
    """Per demonstration, each frame's label from the rest detection of ``model``'s parameters alone."""
    return [np.repeat([REST_BEFORE, MOVING, REST_AFTER], [moving, resting - moving, len(rel) - resting])
            for rel, moving, resting in model.motion_spans(*demos.object_data())]


def kmeans_baseline_labels(model: PrimitiveDiscovery, demos: Demonstrations, k: int, seed: int = 0) -> list[np.ndarray]:
    """The rest baseline with every demonstration's motion labelled by k-means (``k`` clusters, seeded)
    on its displacement (position and ``rotation_radius`` times the rotation vector, relative to the
    rest before it)."""
    spans = model.motion_spans(*demos.object_data())
    displacement = np.array([np.r_[rel[max(r - 1, 0), :3], model.rotation_radius * rel[max(r - 1, 0), 3:]]
                             for rel, _, r in spans])
    _, cluster = kmeans2(displacement, k, minit="++", seed=np.random.default_rng(seed))
    return [np.repeat([REST_BEFORE, REST_AFTER + 1 + c, REST_AFTER], [m, r - m, len(rel) - r])
            for (rel, m, r), c in zip(spans, cluster)]
