"""The figures of a discovery: joint HMM Gaussians (Fig. 4), primitives per action (Fig. 7), the grammar.

Colours follow the action groups (:mod:`hoap_actions.primitives.discovery.groups`): greys for
approach and remove, one hue per manipulation group. matplotlib draws off screen (Agg); graphviz is
not required.
"""

from __future__ import annotations

import os
from collections import Counter, defaultdict
from collections.abc import Sequence

import numpy as np

from hoap_actions.demonstration.datasets import Demonstrations, Episode
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION, REMOVE, PrimitiveDiscovery
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.discovery.groups import action_groups, group_members, primitive_names

__all__ = ["group_colours", "plot_gaussians", "plot_grammar", "plot_primitives_per_action"]

MAX_LABELLED_EDGES = 80  # more labels than this overlap into an unreadable figure


def group_colours(model: PrimitiveDiscovery) -> list:
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
    colours = group_colours(model)
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
        for g, members in enumerate(group_members(groups))
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
    colours = group_colours(model)
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
    check_is_fitted(grammar)
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
        if len(edges) <= MAX_LABELLED_EDGES:
            ax.text(x0 + 0.55 * (x1 - x0), y0 + 0.55 * (y1 - y0) + 0.12, f"{grammar.transmat_[source, target]:.2f}",
                    fontsize=5, color="0.2", ha="center", va="center")
    ax.axis("off")
    note = ("edge labels: transition probabilities" if len(edges) <= MAX_LABELLED_EDGES else
            f"{len(edges)} edges, too many to label: their probabilities are in grammar.json")
    ax.set_title(f"Action grammar over {n} primitives from {grammar.n_sequences_} demonstrations ({note})", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
