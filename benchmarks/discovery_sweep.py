"""How the two parameters of primitive discovery, spacing and threshold, move the evaluation figures.

A grid of spacing (m of arc length per Gaussian) x threshold (nats of symmetrised KL for merging)
on the ``paper`` preset; for each cell: action groups found (against the true actions), frame
accuracy (many-to-one and one-to-one mapping, see ``discovery_evaluation``), edit score, boundary F1.
A cell is marked when it recovers the paper's Fig. 7: as many groups as true actions, every true
phase recovered and every manipulation group mapped to a manipulation and pure (> 99 % of its frames
labelled with a manipulation from one phase). Frames a group takes from approach or remove at its
edges (e.g. a move's group runs on while the released block settles its 2 mm set-down clearance,
which the plan-based labels give to remove) are boundary errors, counted by frame accuracy and
boundary F1, not mixed actions.

    python benchmarks/discovery_sweep.py [--seeds 0 1] [--spacings ...] [--thresholds ...]

Recordings are looked for in ``--data`` (``data/`` under the checkout) as ``paper-s<seed>.h5`` and
recorded there when missing. Writes every number to ``results/discovery_sweep.json`` and the heat
maps beside it (``discovery_sweep.png``); earlier figures are in ``docs/experiments/discovery.md``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

SPACINGS = (0.02, 0.025, 0.03, 0.04)
THRESHOLDS = (1.0, 2.0, 3.0, 5.0)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("discovery_sweep.json", data=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="paper-preset recordings")
    parser.add_argument("--spacings", type=float, nargs="+", default=list(SPACINGS))
    parser.add_argument("--thresholds", type=float, nargs="+", default=list(THRESHOLDS))
    parser.add_argument("--rerecord-stale", action="store_true",
                        help="record again the recordings older than the demonstrator's sources")
    return parser.parse_args(argv)


def recovers_fig7(result: dict) -> bool:
    """As many groups as true actions, no phase missed, every manipulation group one manipulation (module docstring)."""
    pure = all(
        g["phase"] not in (None, "approach", "remove") and g["manipulation_purity"] > 0.99
        for g in result["groups"] if g["kind"] == "manipulation"
    )
    return result["n_action_groups"] == result["n_true_actions"] and not result["phases_missed"] and pure


def sweep(path: Path, spacings: list[float], thresholds: list[float]) -> list[dict]:
    """Fit and evaluate every grid cell on one dataset."""
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
    from hoap_actions.primitives.evaluation.discovery import evaluate_discovery

    demos = load_demonstrations(path)
    X, lengths = np.concatenate([e.O for e in demos]), [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    cells = []
    for spacing in spacings:
        for threshold in thresholds:
            model = PrimitiveDiscovery(spacing=spacing, threshold=threshold).fit(X, lengths, H)
            r = evaluate_discovery(model, demos)
            cells.append({
                "spacing": spacing,
                "threshold": threshold,
                "n_joint_states": len(model.joint_means_),
                "n_primitives": r["n_primitives"],
                "n_action_groups": r["n_action_groups"],
                "n_true_actions": r["n_true_actions"],
                "phases_missed": r["phases_missed"],
                "min_manipulation_group_purity": min(
                    (g["purity"] for g in r["groups"] if g["kind"] == "manipulation"), default=1.0),
                "fig7_recovered": recovers_fig7(r),
                "frame_accuracy_many_to_one": r["frame_accuracy"]["many_to_one_groups"],
                "frame_accuracy_one_to_one": r["frame_accuracy"]["one_to_one_groups"],
                "frame_accuracy_ceiling": r["frame_accuracy"]["ceiling_effect_visible"],
                "edit_score": r["edit_score"]["many_to_one_groups"],
                "boundary_f1_25": r["boundary_f1"]["many_to_one_groups"]["25"],
            })
            print(f"  spacing {spacing:<6} threshold {threshold:<4}: {r['n_action_groups']:>3} groups "
                  f"({r['n_true_actions']} true), {r['n_primitives']:>3} primitives, frame acc. m2o "
                  f"{cells[-1]['frame_accuracy_many_to_one']:.3f} 1-1 {cells[-1]['frame_accuracy_one_to_one']:.3f}, "
                  f"edit {cells[-1]['edit_score']:.3f}{'  <- Fig. 7' if cells[-1]['fig7_recovered'] else ''}")
    return cells


def plot(per_seed: dict[int, list[dict]], spacings: list[float], thresholds: list[float], path: Path) -> None:
    """One row of heat maps per recording: groups found, many-to-one and one-to-one frame accuracy, edit score."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    panels = [
        ("n_action_groups", "action groups found", "{:.0f}"),
        ("frame_accuracy_many_to_one", "frame accuracy, many-to-one", "{:.3f}"),
        ("frame_accuracy_one_to_one", "frame accuracy, one-to-one", "{:.3f}"),
        ("edit_score", "edit score", "{:.2f}"),
    ]
    fig, axes = plt.subplots(len(per_seed), len(panels), figsize=(4.2 * len(panels), 3.6 * len(per_seed)),
                             squeeze=False)
    for row, (seed, cells) in enumerate(per_seed.items()):
        for col, (key, title, fmt) in enumerate(panels):
            ax = axes[row, col]
            grid = np.array([[next(c[key] for c in cells if c["spacing"] == s and c["threshold"] == t)
                              for t in thresholds] for s in spacings], dtype=float)
            if key == "n_action_groups":
                true = cells[0]["n_true_actions"]
                off = np.abs(grid - true)
                image = ax.imshow(off, cmap="Oranges", vmin=0, vmax=max(4.0, off.max()))
                title = f"{title} (true: {true})"
            else:
                image = ax.imshow(grid, cmap="viridis", vmin=min(0.6, grid.min()), vmax=1.0)
                fig.colorbar(image, ax=ax, fraction=0.046)
            for i, s in enumerate(spacings):
                for j, t in enumerate(thresholds):
                    ax.text(j, i, fmt.format(grid[i, j]), ha="center", va="center", fontsize=8,
                            color="white" if key != "n_action_groups" and grid[i, j] < 0.85 else "black")
                    cell = next(c for c in cells if c["spacing"] == s and c["threshold"] == t)
                    if cell["fig7_recovered"]:
                        ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, edgecolor="red", linewidth=2))
            ax.set_xticks(range(len(thresholds)), [f"{t:g}" for t in thresholds])
            ax.set_yticks(range(len(spacings)), [f"{100 * s:g}" for s in spacings])
            ax.set_xlabel("threshold (nats)")
            ax.set_ylabel("spacing (cm)")
            ax.set_title(f"seed {seed}: {title}", fontsize=9)
    ceiling = np.mean([c["frame_accuracy_ceiling"] for cells in per_seed.values() for c in cells[:1]])
    fig.suptitle(f"Primitive discovery on the paper preset: red box = Fig. 7 recovered (groups = true actions, "
                 f"each one manipulation); frame-accuracy ceiling from O alone ~{ceiling:.3f}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from _discovery_data import paper_recording, sources_digest

    per_seed = {}
    for seed in args.seeds:
        path = paper_recording(seed, args.data, args.rerecord_stale)
        print(f"seed {seed}: {path}")
        per_seed[seed] = sweep(path, args.spacings, args.thresholds)
    png = args.output.with_suffix(".png")
    png.parent.mkdir(parents=True, exist_ok=True)
    plot(per_seed, args.spacings, args.thresholds, png)
    document = {
        "benchmark": "discovery_sweep",
        "demonstrator_sources_sha256_16": sources_digest(),
        "spacings": args.spacings,
        "thresholds": args.thresholds,
        "cells": {str(seed): cells for seed, cells in per_seed.items()},
        "environment": numeric_environment(blas_threads=None),
    }
    write_json(args.output, document)
    print(f"wrote {png}")
    return document


if __name__ == "__main__":
    main()
