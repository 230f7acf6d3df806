"""Synthesise reaching movements with a parametric HMM (the paper's Fig. 8 experiment, one location).

Trains a 40-state approach PHMM on the 2x2 or 3x3 grid of an ``approach-grid`` recording (phi = where
the block is), with a linear or a thin-plate-spline mean model, synthesises the reach to a 5x7 test
location it never saw, and compares it with the four real reaches there after time warping (eq. 5).
Saves a picture of the wrist paths.

    python examples/phmm_synthesis.py [--data data/approach-grid-s0.h5] [--grid 3x3] [--mean-model tps]
                                      [--row 2 --col 1] [--out reach.png]

A missing recording is made first (about 30 s), under the name the benchmark uses too.
The full benchmark over the 35 locations is ``benchmarks/phmm_synthesis_error.py``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.primitives.evaluation.grid_synthesis import fit_grid_model, grid_data
from hoap_actions.primitives.trajectory_metrics import warped_rms_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("data/approach-grid-s0.h5"),
                        help="an approach-grid recording (recorded with seed 0 first if missing)")
    parser.add_argument("--grid", default="3x3", choices=("2x2", "3x3"), help="training grid")
    parser.add_argument("--mean-model", default="tps", choices=("linear", "tps"))
    parser.add_argument("--smoothing", type=float, default=0.01, help="ridge on the thin-plate bend (tps)")
    parser.add_argument("--row", type=int, default=2, choices=range(5), help="test location: row of the 5x7 grid")
    parser.add_argument("--col", type=int, default=1, choices=range(7), help="test location: column of the 5x7 grid")
    parser.add_argument("--out", type=Path, default=Path("reach.png"))
    args = parser.parse_args()
    if not args.data.exists():
        from hoap_actions.demonstration.recording import record

        print(f"recording {args.data} (approach-grid preset, seed 0)")
        record("approach-grid", args.data, seed=0)
    data = grid_data(load_demonstrations(args.data))
    model, fit_s = fit_grid_model(data, args.grid, n_states=40, reg_covar=1e-5, n_iter=200, tol=1e-3,
                                  mean_model=args.mean_model, smoothing=args.smoothing)

    key = (args.row, args.col)
    target = data.location(key)
    synthesised = model.synthesize(target)  # (T, 18): 6 markers x 3, timing from the expected state durations
    print(f"test location {target.round(3)} m; {args.mean_model} PHMM trained on the {args.grid} grid in {fit_s:.1f} s")
    print(f"synthesis error e = {100 * warped_rms_error(synthesised, data.references[key]):.2f} cm; the "
          f"demonstrator's own (leave-one-out) {100 * data.human_loo[key]:.2f} cm")

    fig, ax = plt.subplots(figsize=(6, 4))
    for k, (x, _) in enumerate(data.test[key]):
        ax.plot(x[:, 7], x[:, 8], color="tab:blue", alpha=0.5, label="human" if k == 0 else None)
    ax.plot(synthesised[:, 7], synthesised[:, 8], color="tab:red", linewidth=2, label=f"{args.mean_model} PHMM "
                                                                                      "synthesis")
    ax.set_xlabel("wrist y (m)")
    ax.set_ylabel("wrist z (m)")
    ax.set_title(f"reach to {target.round(2)} m")
    ax.legend()
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(f"saved {args.out}")


if __name__ == "__main__":
    main()
