"""What ``hoap-actions discover`` writes: the files of a discovery on a demonstrations file, and its summary.

:func:`discover_to_dir` fits :class:`~hoap_actions.primitives.discovery.estimator.PrimitiveDiscovery` to the
object trajectories ``O`` (and the arm markers ``H`` for the effects of approach and remove), learns
the :class:`~hoap_actions.primitives.discovery.grammar.ActionGrammar` over the demonstrations' primitive
sequences, evaluates the segmentation (:mod:`hoap_actions.primitives.evaluation.discovery`) and
writes (every JSON carries ``format_version`` and ``kind``):

=============================  ======================================================================
``model.json``                 the fitted model (:meth:`PrimitiveDiscovery.save`, loadable)
``classes.json``               the equivalence classes: per primitive its kind, states, action group and
                               H segments with effects phi; and the action groups
``grammar.json``, ``.dot``     the grammar over primitive names (:meth:`ActionGrammar.save`, DOT text)
``grammar.png``                the grammar graph drawn with matplotlib (graphviz is not required)
``gaussians.png``              the joint HMM's Gaussians, 3-D position part, as ellipsoids (Fig. 4)
``primitives_per_action.png``  for each demonstrated action, its chains of primitives (Fig. 7)
``summary.json``               parameters, counts, timing and the evaluation
=============================  ======================================================================

Action groups are defined in :mod:`hoap_actions.primitives.discovery.groups`.
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.errors import InvalidInputError
from hoap_actions.outputs import claimed_files
from hoap_actions.primitives.base import file_params
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.discovery.groups import action_groups, group_members, primitive_names
from hoap_actions.primitives.discovery.plots import (
    group_colours,
    plot_gaussians,
    plot_grammar,
    plot_primitives_per_action,
)
from hoap_actions.primitives.evaluation.discovery import evaluate_discovery
from hoap_actions.primitives.pipelines.mocap_cleaning import clean_demonstrations

__all__ = ["FORMAT_VERSION", "OUTPUT_FILES", "Summary", "discover_to_dir"]

logger = logging.getLogger(__name__)

FORMAT_VERSION = 1  # of classes.json and summary.json
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
    merging: str | None = None,
) -> Summary:
    """Discover primitives in a demonstrations file and write model, classes, grammar and figures to ``out_dir``.

    ``threshold`` / ``spacing`` / ``merging`` default to :class:`PrimitiveDiscovery`'s. The files
    :data:`OUTPUT_FILES` in ``out_dir`` are claimed before the demonstrations are read
    (:func:`hoap_actions.outputs.claimed_files`): when any exists (unless ``overwrite``) or another
    run is writing them, DataExistsError comes at once; other files there are left alone. They are
    written to a staging folder and published together at the end, so a failure leaves the
    previous results (or nothing) rather than a mix.
    """
    out_dir = Path(out_dir)
    with claimed_files(out_dir, OUTPUT_FILES, overwrite, what="discovery results") as staging:
        summary = _discover(Path(demos_path), out_dir, staging, threshold, spacing, merging)
    logger.info("discovery of %s written to %s", demos_path, out_dir)
    return summary


def _discover(
    demos_path: Path, out_dir: Path, staging: Path, threshold: float | None, spacing: float | None,
    merging: str | None,
) -> Summary:
    """The work of :func:`discover_to_dir`, writing every output file into ``staging``."""
    demos = clean_demonstrations(load_demonstrations(demos_path))
    if len(demos) == 0:
        raise InvalidInputError(f"{demos_path} holds no demonstrations; discovery needs at least one")
    given = {"spacing": spacing, "threshold": threshold, "merging": merging}
    params = {name: value for name, value in given.items() if value is not None}
    model = PrimitiveDiscovery(**params)
    X, lengths = np.concatenate([e.O for e in demos]), [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    started = time.perf_counter()
    model.fit(X, lengths, H)
    fit_seconds = time.perf_counter() - started
    names = primitive_names(model)
    grammar = ActionGrammar().fit([[names[pid] for pid, *_ in segments] for segments in model.segmentations_])
    evaluation = evaluate_discovery(model, demos)

    model.save(staging / "model.json")
    _write_json(staging / "classes.json", _classes_document(model))
    grammar.save(staging / "grammar.json")
    (staging / "grammar.dot").write_text(grammar.to_dot())
    groups = action_groups(model)
    colours = group_colours(model)
    plot_grammar(grammar, [colours[groups[names.index(s)]] for s in grammar.symbols_], staging / "grammar.png")
    plot_gaussians(model, model.relative_trajectories(X, lengths), staging / "gaussians.png")
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
            "params": file_params(model),
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
        "groups": [{"group": g, "primitives": members} for g, members in enumerate(group_members(groups))],
    }
