"""Plot recorded demonstrations: 3-D marker paths and the object's path, coloured by the true phase.

One panel per recording (the first of each action by default); thin lines are the six arm and hand
markers, the thick line is the object's centre, the grey rectangle the 80 x 30 cm active region.

    hoap-actions record --preset small --out demos.h5
    python examples/plot_demonstrations.py --demos demos.h5 --out demonstrations.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from mpl_toolkits.mplot3d.art3d import Line3DCollection

from hoap_actions.demonstration.datasets import Demonstrations, load_demonstrations


def pick(demos: Demonstrations, count: int) -> list[int]:
    """Indices of up to ``count`` episodes, the first of each action first."""
    first = {}
    for index, episode in enumerate(demos):
        first.setdefault(episode.ground_truth.action, index)
    rest = [i for i in range(len(demos)) if i not in first.values()]
    return (sorted(first.values()) + rest)[:count]


def draw(ax, path: np.ndarray, codes: np.ndarray, colours: np.ndarray, width: float) -> None:
    """A 3-D polyline whose segments take the colour of their phase."""
    segments = np.stack([path[:-1], path[1:]], axis=1)
    ax.add_collection3d(Line3DCollection(segments, colors=colours[codes[1:]], linewidths=width))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--demos", type=Path, required=True, help="HDF5 file written by `hoap-actions record`")
    parser.add_argument("--out", type=Path, required=True, help="figure file (png, pdf, ...)")
    parser.add_argument("--episodes", type=int, default=4, help="how many recordings to draw")
    args = parser.parse_args()

    demos = load_demonstrations(args.demos)
    phases = demos.phase_names
    kinds = {
        "approach": "tab:blue", "push": "tab:orange", "move": "tab:red", "rotate": "tab:purple", "remove": "tab:green"
    }
    colours = np.array([matplotlib.colors.to_rgba(kinds.get(p.split("-")[0], "tab:gray")) for p in phases])
    low = np.array(demos.scene.get("active_region_low", [-0.15, -0.4]))
    high = np.array(demos.scene.get("active_region_high", [0.15, 0.4]))
    chosen = pick(demos, args.episodes)
    fig = plt.figure(figsize=(5.0 * len(chosen), 5.0))
    used = set()
    for column, index in enumerate(chosen):
        episode = demos[index]
        truth = episode.ground_truth
        codes = truth.labels
        used.update(codes.tolist())
        ax = fig.add_subplot(1, len(chosen), column + 1, projection="3d")
        for marker in range(episode.H.shape[1]):
            draw(ax, episode.H[:, marker], codes, colours, 0.8)
        draw(ax, episode.O[:, :3], codes, colours, 3.0)
        corners = np.array([low, [high[0], low[1]], high, [low[0], high[1]], low])
        ax.plot(corners[:, 0], corners[:, 1], np.zeros(5), color="0.6")
        points = np.concatenate([episode.H.reshape(-1, 3), episode.O[:, :3]])
        centre, half = points.mean(axis=0), np.ptp(points, axis=0).max() / 2.0
        ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
               zlim=(centre[2] - half, centre[2] + half), xlabel="x (m)", ylabel="y (m)", zlabel="z (m)")
        label = " ".join(filter(None, [truth.action, truth.direction]))
        if truth.distance:
            label += f" {100 * truth.distance:.0f} cm"
        ax.set_title(f"#{index}: {label}")
        ax.view_init(elev=25, azim=-125)
    handles = [plt.Line2D([], [], color=colours[code], lw=3) for code in sorted(used)]
    fig.legend(handles, [phases[code] for code in sorted(used)], loc="lower center", ncol=len(used), frameon=False)
    fig.suptitle(f"{args.demos.name}: marker paths (thin) and object path (thick), coloured by true phase")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=120, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
