"""Primitive discovery on a demonstrations file, written to a directory, and its evaluation.

:func:`discover_to_dir` is what ``hoap-actions discover`` runs: it fits
:class:`~hoap_actions.primitives.discovery.PrimitiveDiscovery` to the object trajectories ``O`` (and
the arm markers ``H`` for the effects of approach and remove), learns the
:class:`~hoap_actions.primitives.grammar.ActionGrammar` over the demonstrations' primitive
sequences, and writes (every JSON carries ``format_version`` and ``kind``):

=============================  ======================================================================
``model.json``                 the fitted model (:meth:`PrimitiveDiscovery.save`, loadable)
``classes.json``               the equivalence classes: per primitive its kind, states, action group and
                               H segments with effects phi; and the action groups
``grammar.json``, ``.dot``     the grammar over primitive names (:meth:`ActionGrammar.save`, DOT text)
``grammar.png``                the grammar graph drawn with matplotlib (graphviz is not required)
``gaussians.png``              the joint HMM's Gaussians, 3-D position part, as ellipsoids (Fig. 4)
``primitives_per_action.png``  for each demonstrated action, its chains of primitives (Fig. 7)
``summary.json``               parameters, counts, timing and the evaluation below
=============================  ======================================================================

**Action groups.** The paper's classes are per primitive (one equivalence class of H segments per
primitive); a push over the longest distance is the chain P1 P2 P3 and a shorter one P1 P2 or P1
(Fig. 7). To count *actions* without ground truth, manipulation primitives that follow one another
in some demonstration are put in one group (connected components of the chains); approach and
remove are a group each. A group is what one box of Fig. 7 shows.

**Evaluation** (:func:`evaluate_discovery`) uses the dataset's hidden per-frame phase labels, which
never reach ``fit``. Discovered ids are arbitrary, so they are mapped to true phases over all
demonstrations at once: one-to-one (Hungarian; a phase cut into P1 P2 P3 then scores one of the
three) and many-to-one (each id to the phase it overlaps most; several primitives or groups may map
to one phase, e.g. the two turning directions to ``rotate``). Edit score and boundary F1 are computed
on the many-to-one mapped group labels, so consecutive primitives of one action form one segment.

The hidden labels follow the paper's decomposition (Fig. 7; "the grasping movement could not be
detected"): the demonstrator labels each frame from its own plan, not from ``O``
(:mod:`hoap_actions.envs.demonstrator`): the grasp and the hand closing the gap to a block it pushes
are approach, letting go (holding still on the placed block, releasing it, opening the fingers, easing
off after a push) is remove, and the manipulation is what changes the object. Manipulation frames in
which the object is nevertheless still are invisible to a method that reads only ``O``:
:func:`effect_visible_labels` moves them to approach / remove, and its agreement with the true labels
is the best frame accuracy such a method can reach, reported as the ceiling
(``ceiling_effect_visible``) beside the scores. With plan-based labels it falls short of 1 only
by frames in which the plan and the physics differ slightly (e.g. the hand touches the block a little
after the measured gap is closed). Datasets of labelling 1 (``labels_version`` absent from their
``generator``, recorded before the change) gave the grasp, the hold and release and a push's first gap
and ease-off to the manipulation: a ceiling of about 83 % on the paper preset. The evaluation records
the dataset's ``labels_version``.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections import Counter, defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.errors import InvalidInputError, NotFittedError
from hoap_actions.outputs import claimed_files
from hoap_actions.primitives.datasets import Demonstrations, Episode, load_demonstrations
from hoap_actions.primitives.discovery import APPROACH, MANIPULATION, REMOVE, PrimitiveDiscovery
from hoap_actions.primitives.evaluation import (
    boundary_f1,
    edit_score,
    hungarian_frame_accuracy,
    hungarian_mapping,
    many_to_one_frame_accuracy,
    many_to_one_mapping,
    relabel,
)
from hoap_actions.primitives.grammar import ActionGrammar

logger = logging.getLogger(__name__)

FORMAT_VERSION = 1
OUTPUT_FILES = (
    "model.json",
    "classes.json",
    "grammar.json",
    "grammar.dot",
    "grammar.png",
    "gaussians.png",
    "primitives_per_action.png",
    "summary.json",
)
BOUNDARY_TOLERANCES = (10, 25, 50)  # frames: 0.1, 0.25, 0.5 s at the recordings' 100 Hz
EFFECT_TOLERANCE = 1e-3  # m (pose metric): the object has visibly moved


# ------------------------------------------------------------------------------------ structure


def _require_fitted(model: PrimitiveDiscovery) -> None:
    if not hasattr(model, "primitives_"):
        raise NotFittedError("this PrimitiveDiscovery is not fitted yet: call fit() or load() first")


def frame_labels(model: PrimitiveDiscovery) -> list[np.ndarray]:
    """Per training demonstration, the primitive id of every frame ``(T_i,)``, from ``segmentations_``."""
    _require_fitted(model)
    return [
        np.concatenate([np.full(end - start, pid) for pid, start, end in segments])
        for segments in model.segmentations_
    ]


def action_groups(model: PrimitiveDiscovery) -> list[int]:
    """Per primitive id, its action group (module docstring), numbered by first primitive."""
    _require_fitted(model)
    parent = list(range(len(model.primitives_)))

    def root(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for segments in model.segmentations_:
        chain = [pid for pid, *_ in segments if model.primitive_kinds_[pid] == MANIPULATION]
        for a, b in zip(chain, chain[1:]):
            parent[max(root(a), root(b))] = min(root(a), root(b))
    numbers: dict[int, int] = {}
    return [numbers.setdefault(root(pid), len(numbers)) for pid in range(len(model.primitives_))]


def primitive_names(model: PrimitiveDiscovery) -> list[str]:
    """Readable primitive names: ``approach``, ``remove`` and ``p<id>`` for manipulation primitives."""
    _require_fitted(model)
    return [kind if kind != MANIPULATION else f"p{pid}" for pid, kind in enumerate(model.primitive_kinds_)]


def effect_visible_labels(episode: Episode, rotation_radius: float = 0.05) -> np.ndarray:
    """True phase labels with the manipulation frames where the object is still moved to approach / remove.

    A frame before the object first moves more than :data:`EFFECT_TOLERANCE` (``|dp| + rotation_radius
    * angle``) from its initial pose becomes approach; one after it last is that far from its final
    pose becomes remove. If the object never moves, nothing in ``O`` marks where the approach ends,
    so every frame becomes approach. Evaluation only: it reads the ground truth.
    """
    truth = episode.ground_truth
    labels = np.array(truth.labels, dtype=int)
    names = truth.phase_names
    codes = {name: code for code, name in enumerate(names)}
    if APPROACH not in codes or REMOVE not in codes:
        raise InvalidInputError(f"phase names {names} lack {APPROACH!r} or {REMOVE!r}")
    manipulation = (labels != codes[APPROACH]) & (labels != codes[REMOVE])
    moved_from_start = _pose_distance(episode.O, episode.O[0], rotation_radius) > EFFECT_TOLERANCE
    moved_from_end = _pose_distance(episode.O, episode.O[-1], rotation_radius) > EFFECT_TOLERANCE
    if not moved_from_start.any():
        return np.full(len(labels), codes[APPROACH])
    first = int(np.argmax(moved_from_start))
    last = len(labels) - int(np.argmax(moved_from_end[::-1])) if moved_from_end.any() else len(labels)
    frames = np.arange(len(labels))
    labels[manipulation & (frames < first)] = codes[APPROACH]
    labels[manipulation & (frames >= max(first, last))] = codes[REMOVE]
    return labels


def _pose_distance(poses: np.ndarray, reference: np.ndarray, rotation_radius: float) -> np.ndarray:
    """``|p - p_ref| + rotation_radius * angle(R R_ref^-1)`` per row (m)."""
    angle = (Rotation.from_rotvec(poses[:, 3:]) * Rotation.from_rotvec(reference[3:]).inv()).magnitude()
    return np.linalg.norm(poses[:, :3] - reference[:3], axis=1) + rotation_radius * angle


# ----------------------------------------------------------------------------------- evaluation


def evaluate_discovery(
    model: PrimitiveDiscovery, demos: Demonstrations, tolerances: Sequence[int] = BOUNDARY_TOLERANCES
) -> dict:
    """Compare a model's training segmentation with the hidden phase labels of the demos it was fitted on.

    Returns a JSON-ready dict (module docstring): the dataset's ``labels_version`` (1 if it records
    none), counts (true actions are the distinct ground-truth
    (action, direction) pairs that move the object, plus approach and remove: the paper preset has
    12, its ``rotate`` phase label covering both turning directions), the groups and the phase each maps to
    (with ``purity``, the share of its frames from that phase, and ``manipulation_purity``, the same among
    its frames labelled with a manipulation: below 1 only if it mixes manipulations),
    frame accuracies (one-to-one and many-to-one, primitives and groups, the effect-visible
    ceiling), edit scores and boundary F1 at each tolerance (frames).
    """
    _require_fitted(model)
    if len(model.segmentations_) != len(demos):
        raise InvalidInputError(f"the model was fitted on {len(model.segmentations_)} demonstrations, got {len(demos)}")
    names = demos.phase_names
    true = [np.asarray(e.ground_truth.labels, dtype=int) for e in demos]
    primitives = frame_labels(model)
    for i, (p, t) in enumerate(zip(primitives, true)):
        if len(p) != len(t):
            raise InvalidInputError(f"demonstration {i}: the model segmented {len(p)} frames, the labels have {len(t)}")
    group_of = np.asarray(action_groups(model))
    groups = [group_of[p] for p in primitives]
    visible = [effect_visible_labels(e, model.rotation_radius) for e in demos]
    to_phase = many_to_one_mapping(groups, true)
    strict = hungarian_mapping(groups, true)
    mapped, mapped_strict = relabel(groups, to_phase), relabel(groups, strict)
    present = sorted({int(c) for t in true for c in np.unique(t)})

    all_groups, all_true = np.concatenate(groups), np.concatenate(true)
    acting = np.array([name not in (APPROACH, REMOVE) for name in names])
    group_rows = []
    for g in range(int(group_of.max()) + 1):
        in_group = all_groups == g
        counts = np.bincount(all_true[in_group], minlength=len(names))
        members = np.flatnonzero(group_of == g)
        acts = counts[acting]
        group_rows.append(
            {
                "group": g,
                "kind": model.primitive_kinds_[members[0]],
                "primitives": members.tolist(),
                "frames": int(in_group.sum()),
                "phase": names[to_phase[g]] if g in to_phase else None,
                "purity": float(counts.max() / max(1, counts.sum())),
                # of its frames labelled with a manipulation, the share of the most common one (1 if none)
                "manipulation_purity": float(acts.max() / acts.sum()) if acts.sum() else 1.0,
            }
        )
    recovered = sorted({names[to_phase[g]] for g in to_phase})
    still = {names.index(k) for k in (APPROACH, REMOVE) if k in names}
    actions = sorted(
        {f"{e.ground_truth.action} {e.ground_truth.direction}".strip() for e, t in zip(demos, true) if set(t) - still}
    )
    true_actions = [k for k in (APPROACH,) if names.index(k) in present] + actions
    true_actions += [k for k in (REMOVE,) if names.index(k) in present]
    true_sequences = [[names[c] for c in _runs(t)] for t in true]
    mapped_sequences = [[names[c] for c in _runs(m)] for m in mapped]
    return {
        "labels_version": int(demos.generator.get("labels_version", 1)),
        "n_demonstrations": len(demos),
        "n_frames": int(sum(len(t) for t in true)),
        "true_phases": [names[c] for c in present],
        "n_true_phases": len(present),
        "true_actions": true_actions,
        "n_true_actions": len(true_actions),
        "n_primitives": len(model.primitives_),
        "n_action_groups": len(group_rows),
        "phases_recovered": recovered,
        "phases_missed": [names[c] for c in present if names[c] not in recovered],
        "groups": group_rows,
        "frame_accuracy": {
            "one_to_one_primitives": hungarian_frame_accuracy(primitives, true),
            "one_to_one_groups": hungarian_frame_accuracy(groups, true),
            "many_to_one_primitives": many_to_one_frame_accuracy(primitives, true),
            "many_to_one_groups": many_to_one_frame_accuracy(groups, true),
            "ceiling_effect_visible": float(np.mean(np.concatenate(visible) == all_true)),
            "many_to_one_groups_vs_effect_visible": many_to_one_frame_accuracy(groups, visible),
        },
        "edit_score": {
            "many_to_one_groups": edit_score(mapped, true),
            "one_to_one_groups": edit_score(mapped_strict, true),
        },
        "boundary_f1": {
            "many_to_one_groups": {str(k): boundary_f1(mapped, true, k) for k in tolerances},
            "primitives": {str(k): boundary_f1(primitives, true, k) for k in tolerances},
            "many_to_one_groups_vs_effect_visible": {str(k): boundary_f1(mapped, visible, k) for k in tolerances},
        },
        "demonstrations_with_true_action_sequence": float(
            np.mean([m == t for m, t in zip(mapped_sequences, true_sequences)])
        ),
    }


def _runs(labels: np.ndarray) -> list[int]:
    """The label of each run of equal labels."""
    return [int(labels[0]), *labels[1:][labels[1:] != labels[:-1]].tolist()] if len(labels) else []


# ---------------------------------------------------------------------------------------- files


@dataclass(frozen=True)
class Summary:
    """What :func:`discover_to_dir` did: where it wrote, what it found, how long fitting took."""

    out_dir: Path
    files: tuple[Path, ...]
    n_demonstrations: int
    n_frames: int
    spacing: float
    threshold: float
    n_joint_states: int
    n_primitives: int
    n_action_groups: int
    fit_seconds: float
    evaluation: dict = field(default_factory=dict)

    def report(self) -> str:
        """A few lines for a terminal: counts, time and the headline evaluation figures."""
        lines = [
            f"{self.n_demonstrations} demonstrations ({self.n_frames} frames), spacing {self.spacing} m, "
            f"threshold {self.threshold}: {self.n_joint_states} joint states, {self.n_primitives} primitives "
            f"in {self.n_action_groups} action groups, fitted in {self.fit_seconds:.1f} s",
        ]
        e = self.evaluation
        if e:
            acc, f1 = e["frame_accuracy"], e["boundary_f1"]["many_to_one_groups"]
            lines += [
                f"against the hidden labels: {e['n_action_groups']} action groups for {e['n_true_actions']} true "
                f"actions ({e['n_true_phases']} phase labels); phases missed: "
                f"{', '.join(e['phases_missed']) or 'none'}",
                f"  frame accuracy one-to-one {acc['one_to_one_groups']:.1%}, many-to-one "
                f"{acc['many_to_one_groups']:.1%} (ceiling from O alone {acc['ceiling_effect_visible']:.1%}); "
                f"edit score {e['edit_score']['many_to_one_groups']:.1%}; boundary F1 "
                + ", ".join(f"{v:.2f} (+-{k})" for k, v in f1.items()),
            ]
        lines.append(f"wrote {len(self.files)} files to {self.out_dir}")
        return "\n".join(lines)


def discover_to_dir(
    demos_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    threshold: float | None = None,
    spacing: float | None = None,
    overwrite: bool = False,
) -> Summary:
    """Discover primitives in a demonstrations file and write model, classes, grammar and figures to ``out_dir``.

    ``threshold`` / ``spacing`` default to :class:`PrimitiveDiscovery`'s. The files
    :data:`OUTPUT_FILES` in ``out_dir`` are claimed before the demonstrations are read
    (:func:`hoap_actions.outputs.claimed_files`): when any exists (unless ``overwrite``) or another
    run is writing them, DataExistsError comes at once; other files there are left alone. They are
    written to a staging folder and published together at the end, so a failure leaves the
    previous results (or nothing) rather than a mix.
    """
    out_dir = Path(out_dir)
    with claimed_files(out_dir, OUTPUT_FILES, overwrite, what="discovery results") as staging:
        summary = _discover(Path(demos_path), out_dir, staging, threshold, spacing)
    logger.info("discovery of %s written to %s", demos_path, out_dir)
    return summary


def _discover(
    demos_path: Path, out_dir: Path, staging: Path, threshold: float | None, spacing: float | None
) -> Summary:
    """The work of :func:`discover_to_dir`, writing every output file into ``staging``."""
    demos = load_demonstrations(demos_path)
    if len(demos) == 0:
        raise InvalidInputError(f"{demos_path} holds no demonstrations; discovery needs at least one")
    params = {k: v for k, v in (("spacing", spacing), ("threshold", threshold)) if v is not None}
    model = PrimitiveDiscovery(**params)
    objects = [e.O for e in demos]
    hands = [e.H.reshape(e.T, -1) for e in demos]
    started = time.perf_counter()
    model.fit(objects, hands)
    fit_seconds = time.perf_counter() - started
    names = primitive_names(model)
    grammar = ActionGrammar().fit([[names[pid] for pid, *_ in segments] for segments in model.segmentations_])
    evaluation = evaluate_discovery(model, demos)

    model.save(staging / "model.json")
    _write_json(staging / "classes.json", _classes_document(model))
    grammar.save(staging / "grammar.json")
    (staging / "grammar.dot").write_text(grammar.to_dot())
    groups = action_groups(model)
    colours = _group_colours(model)
    plot_grammar(grammar, [colours[groups[names.index(s)]] for s in grammar.symbols_], staging / "grammar.png")
    plot_gaussians(model, model.relative_trajectories(objects), staging / "gaussians.png")
    plot_primitives_per_action(model, demos, staging / "primitives_per_action.png")
    summary = Summary(
        out_dir=out_dir,
        files=tuple(out_dir / name for name in OUTPUT_FILES),
        n_demonstrations=len(demos),
        n_frames=int(sum(e.T for e in demos)),
        spacing=float(model.spacing),
        threshold=float(model.threshold),
        n_joint_states=len(model.joint_means_),
        n_primitives=len(model.primitives_),
        n_action_groups=max(groups) + 1,
        fit_seconds=fit_seconds,
        evaluation=evaluation,
    )
    _write_json(
        staging / "summary.json",
        {
            "format_version": FORMAT_VERSION,
            "kind": "DiscoverySummary",
            "demonstrations": str(Path(demos_path).resolve()),
            "dataset_generator": demos.generator,
            "params": model.get_params(),
            "n_demonstrations": summary.n_demonstrations,
            "n_frames": summary.n_frames,
            "n_joint_states": summary.n_joint_states,
            "n_primitives": summary.n_primitives,
            "n_action_groups": summary.n_action_groups,
            "fit_seconds": fit_seconds,
            "evaluation": evaluation,
            "files": list(OUTPUT_FILES),
        },
    )
    return summary


def _write_json(path: Path, document: dict) -> None:
    path.write_text(json.dumps(document, indent=1) + "\n")


def _classes_document(model: PrimitiveDiscovery) -> dict:
    """``classes.json``: the equivalence classes (H segments and effects per primitive) and action groups."""
    groups, names = action_groups(model), primitive_names(model)
    return {
        "format_version": FORMAT_VERSION,
        "kind": "DiscoveredClasses",
        "segment_fields": ["demo", "start_frame", "end_frame_exclusive", "initial_xyz_m", "final_xyz_m", "source"],
        "classes": [
            {
                "primitive_id": c.primitive_id,
                "name": names[c.primitive_id],
                "kind": c.kind,
                "group": groups[c.primitive_id],
                "states": list(c.states),
                "segments": [[s.demo, s.start, s.end, list(s.initial), list(s.final), s.source] for s in c.segments],
            }
            for c in model.classes_
        ],
        "groups": [{"group": g, "primitives": members} for g, members in enumerate(_members(groups))],
    }


# -------------------------------------------------------------------------------------- figures


def _group_colours(model: PrimitiveDiscovery) -> list:
    """One colour per action group: greys for approach and remove, distinct hues for the actions."""
    import matplotlib

    tab10, tab20 = matplotlib.colormaps["tab10"], matplotlib.colormaps["tab20"]
    hues = [tab10(i) for i in range(10) if i != 7] + [tab20(i) for i in range(1, 20, 2) if i != 15]
    groups = action_groups(model)
    kinds = {groups[pid]: kind for pid, kind in enumerate(model.primitive_kinds_)}
    colours, k = [], 0
    for g in range(max(groups) + 1):
        if kinds[g] == MANIPULATION:
            colours.append(hues[k % len(hues)])
            k += 1
        else:
            colours.append((0.8, 0.8, 0.8, 1.0) if kinds[g] == APPROACH else (0.55, 0.55, 0.55, 1.0))
    return colours


def plot_gaussians(model: PrimitiveDiscovery, relative: Sequence[np.ndarray], path: str | os.PathLike) -> None:
    """Fig. 4: the joint states' Gaussians (3-D position part, 2-sigma ellipsoids) over the relative trajectories.

    Coloured by action group; rest states grey. ``relative`` are the trajectories as
    :meth:`PrimitiveDiscovery.relative_trajectories` returns them.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    groups, names = action_groups(model), primitive_names(model)
    colours = _group_colours(model)
    state_group: dict[int, int] = {}
    for pid, states in enumerate(model.primitives_):
        if model.primitive_kinds_[pid] == MANIPULATION:
            for state in states:
                state_group.setdefault(state, groups[pid])
    fig = plt.figure(figsize=(9, 8))
    ax = fig.add_subplot(projection="3d")
    for demo, rel in enumerate(relative):
        chain = [pid for pid, *_ in model.segmentations_[demo] if model.primitive_kinds_[pid] == MANIPULATION]
        colour = colours[groups[chain[0]]] if chain else (0.6, 0.6, 0.6, 1.0)
        ax.plot(*(100 * rel[:, :3].T), color=colour, lw=0.6, alpha=0.6)
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 16), np.linspace(0, np.pi, 9))
    sphere = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], axis=-1)
    for state, (mean, cov) in enumerate(zip(model.joint_means_, model.joint_covars_)):
        values, vectors = np.linalg.eigh(cov[:3, :3])
        surface = 100 * (mean[:3] + 2.0 * (sphere * np.sqrt(np.maximum(values, 0))) @ vectors.T)
        colour = colours[state_group[state]] if state in state_group else (0.5, 0.5, 0.5, 1.0)
        ax.plot_surface(*np.moveaxis(surface, -1, 0), color=colour, alpha=0.25, linewidth=0, shade=True)
    handles = [
        Line2D([], [], color=colours[g], lw=4, label=f"group {g}: " + ", ".join(names[p] for p in members))
        for g, members in enumerate(_members(groups))
        if model.primitive_kinds_[members[0]] == MANIPULATION
    ]
    if handles:
        ax.legend(handles=handles, fontsize=6, loc="upper left", ncol=1 + len(handles) // 12)
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.set_zlabel("z (cm)")
    ax.set_title(
        f"Joint HMM states over the object's displacement from its initial pose\n"
        f"{len(model.joint_means_)} Gaussians (2-sigma, position part), colour = action group, grey = at rest"
    )
    _equal_axes(ax, np.concatenate([100 * r[:, :3] for r in relative]))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _members(groups: Sequence[int]) -> list[list[int]]:
    """Primitive ids of each group, by group id."""
    members: list[list[int]] = [[] for _ in range(max(groups) + 1)]
    for pid, g in enumerate(groups):
        members[g].append(pid)
    return members


def _equal_axes(ax, points: np.ndarray) -> None:
    """Equal scales on a 3-D axes around ``points``."""
    centre = (points.max(axis=0) + points.min(axis=0)) / 2
    half = max(float((points.max(axis=0) - points.min(axis=0)).max()) / 2, 1.0)
    for setter, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        setter(c - half, c + half)


def _action_name(episode: Episode) -> tuple[str, tuple[float, str]]:
    """``(action title, (sort key, variant))`` of an episode from its ground truth.

    E.g. ``("push left", (0.1, "10 cm"))``; the key sorts the variants by distance or angle.
    """
    truth = episode.ground_truth
    title = f"{truth.action} {truth.direction}".strip()
    if truth.action in ("push", "move"):
        return title, (truth.distance, f"{100 * truth.distance:.0f} cm")
    if truth.action == "rotate":
        return title, (truth.angle, f"{np.degrees(truth.angle):.0f} deg")
    return title, (0.0, truth.grid)


def plot_primitives_per_action(model: PrimitiveDiscovery, demos: Demonstrations, path: str | os.PathLike) -> None:
    """Fig. 7: for each demonstrated action, the chains of discovered primitives its demonstrations used.

    The ground truth only sorts the demonstrations into panels and rows; every box is a discovered
    primitive (colour = action group), ``xN`` says how many demonstrations used that chain.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    names, groups = primitive_names(model), action_groups(model)
    colours = _group_colours(model)
    panels: dict[str, Counter] = defaultdict(Counter)
    for episode, segments in zip(demos, model.segmentations_):
        title, variant = _action_name(episode)
        panels[title][(variant, tuple(pid for pid, *_ in segments))] += 1
    n_cols = min(4, len(panels))
    n_rows = -(-len(panels) // n_cols)
    rows_per_panel = max(len(c) for c in panels.values())
    longest = max(len(chain) for c in panels.values() for _, chain in c)
    fig, axes = plt.subplots(
        n_rows, n_cols, figsize=(n_cols * (1.2 + 0.75 * longest), n_rows * (0.6 + 0.32 * rows_per_panel)), squeeze=False
    )
    for ax in axes.ravel():
        ax.axis("off")
    for ax, (title, chains) in zip(axes.ravel(), panels.items()):
        ax.set_title(title, fontsize=10)
        ax.set_xlim(0, 1.6 + longest)
        ax.set_ylim(rows_per_panel, -0.3)
        for row, (((_, variant), chain), count) in enumerate(sorted(chains.items())):
            ax.text(0.05, row + 0.4, variant, fontsize=7, va="center")
            for k, pid in enumerate(chain):
                ax.add_patch(
                    FancyBboxPatch((0.9 + k, row + 0.1), 0.9, 0.6, boxstyle="round,pad=0.02",
                                   facecolor=colours[groups[pid]], edgecolor="black", linewidth=0.5)
                )
                label = {APPROACH: "A", REMOVE: "R"}.get(model.primitive_kinds_[pid], names[pid])
                ax.text(1.35 + k, row + 0.4, label, fontsize=7, ha="center", va="center")
            ax.text(1.0 + len(chain), row + 0.4, f"x{count}", fontsize=7, va="center")
    fig.suptitle(
        "Discovered primitives per demonstrated action (A = approach, R = remove, colour = action group; "
        "ground truth only arranges the panels)",
        fontsize=10,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_grammar(grammar: ActionGrammar, symbol_colours: Sequence, path: str | os.PathLike) -> None:
    """The grammar automaton drawn in layers (depth from ``<start>``), edges labelled with probabilities.

    ``symbol_colours``: a matplotlib colour for each of ``grammar.symbols_``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    if not hasattr(grammar, "transmat_"):
        raise NotFittedError("the grammar is not fitted yet: call fit() or load() first")
    n = len(grammar.symbols_)
    seen = grammar.counts_ > 0
    sources, targets = np.nonzero(seen & ~np.eye(n + 2, dtype=bool))
    depth = np.zeros(n + 2, dtype=int)
    for _ in range(n + 2):  # longest path from <start> (capped, should a loop exist): chains read left to right
        deeper = depth.copy()
        np.maximum.at(deeper, targets, depth[sources] + 1)
        deeper = np.minimum(deeper, n + 1)
        if np.array_equal(deeper, depth):
            break
        depth = deeper
    depth[n + 1] = depth[: n + 1].max() + 1
    columns: dict[int, list[int]] = defaultdict(list)
    for node in range(n + 2):
        columns[int(depth[node])].append(node)
    position = {}
    for col, nodes in columns.items():
        for row, node in enumerate(nodes):
            position[node] = (col, row - (len(nodes) - 1) / 2)
    height = max(len(nodes) for nodes in columns.values())
    fig, ax = plt.subplots(figsize=(1.8 * len(columns), 0.9 + 0.38 * height))
    ax.set_xlim(-0.6, len(columns) - 0.4)
    ax.set_ylim(-height / 2 - 0.2, height / 2 + 0.2)
    labels = ["start", *(str(s) for s in grammar.symbols_), "end"]
    boxes = {}
    for node, (x, y) in position.items():
        colour = "white" if node in (0, n + 1) else symbol_colours[node - 1]
        text = ax.text(x, y, labels[node], ha="center", va="center", fontsize=7, zorder=3,
                       bbox={"boxstyle": "round,pad=0.25", "facecolor": colour, "edgecolor": "black", "linewidth": 0.5})
        boxes[node] = text
    fig.canvas.draw()  # lays out the boxes, which the arrows below are clipped to
    edges = np.argwhere(seen)
    for source, target in edges:
        (x0, y0), (x1, y1) = position[source], position[target]
        ax.annotate("", xy=(x1, y1), xytext=(x0, y0), zorder=2,
                    arrowprops={"arrowstyle": "-|>", "mutation_scale": 8, "linewidth": 0.5, "color": "0.35",
                                "patchA": boxes[source].get_bbox_patch(), "patchB": boxes[target].get_bbox_patch(),
                                "connectionstyle": "arc3,rad=0.12" if source != target else "arc3,rad=-2.5"})
        if len(edges) <= 80:
            ax.text(x0 + 0.55 * (x1 - x0), y0 + 0.55 * (y1 - y0) + 0.12, f"{grammar.transmat_[source, target]:.2f}",
                    fontsize=5, color="0.2", ha="center", va="center")
    ax.axis("off")
    ax.set_title(f"Action grammar over {n} primitives from {grammar.n_sequences_} demonstrations "
                 "(edge labels: transition probabilities)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
