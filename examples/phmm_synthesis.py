"""Synthesise reaching movements with a parametric HMM (the paper's Fig. 8 experiment, one location).

Trains a 40-state approach PHMM on the 2x2 grid of an ``approach-grid`` recording (phi = where the
block is), synthesises the reach to a 5x7 test location it never saw, and compares it with the four
real reaches there after time warping (eq. 5).  Saves a picture of the wrist paths.

    python examples/phmm_synthesis.py [--data data/approach-grid-s0.h5] [--row 2 --col 3] [--out reach.png]

A missing recording is made first (about a minute), under the name the benchmark uses too.

The full benchmark over the 35 locations is ``benchmarks/phmm_synthesis_error.py``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from hoap_actions.primitives.datasets import load_demonstrations
from hoap_actions.primitives.parametric_hmm import ParametricHMM
from hoap_actions.primitives.trajectory_metrics import dtw_average, warped_rms_error


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("data/approach-grid-s0.h5"),
                        help="an approach-grid recording (recorded with seed 0 first if missing)")
    parser.add_argument("--row", type=int, default=2, help="test location: row of the 5x7 grid (0-4)")
    parser.add_argument("--col", type=int, default=3, help="test location: column of the 5x7 grid (0-6)")
    parser.add_argument("--out", type=Path, default=Path("reach.png"))
    args = parser.parse_args()
    if not args.data.exists():
        from hoap_actions.envs.recording import record

        print(f"recording {args.data} (approach-grid preset, seed 0)")
        record("approach-grid", args.data, seed=0)
    demos = load_demonstrations(args.data)

    # The approach segment of each episode (the ground-truth labels only select it) and its effect phi:
    # the block's (x, y), where the hand goes.
    approach = demos.phase_names.index("approach")
    train, test = [], []
    for episode in demos:
        frames = np.flatnonzero(episode.ground_truth.labels == approach)
        reach = episode.H[frames[0]:frames[-1] + 1].reshape(len(frames), -1)  # (T, 18): 6 markers x 3
        phi = episode.O[frames[-1], :2]
        truth = episode.ground_truth
        if truth.grid == "2x2":
            train.append((reach, phi))
        elif truth.grid == "5x7" and tuple(truth.grid_index) == (args.row, args.col):
            test.append((reach, phi))

    model = ParametricHMM(n_states=40, reg_covar=1e-5, n_iter=200, tol=1e-3, random_state=0)
    model.fit(np.concatenate([x for x, _ in train]), [len(x) for x, _ in train], np.array([p for _, p in train]))

    target = np.mean([p for _, p in test], axis=0)
    synthesised = model.synthesize(target)                  # (T, 18), timing from the expected state durations
    average = dtw_average([x for x, _ in test])             # the 4 real reaches, aligned by DTW and averaged
    print(f"test location {target.round(3)} m; trained on {len(train)} reaches to the 4 corners")
    print(f"synthesis error e = {100 * warped_rms_error(synthesised, average):.2f} cm")
    for k, (x, _) in enumerate(test):
        print(f"  repetition {k}: e = {100 * warped_rms_error(x, average):.2f} cm from the average")

    fig, ax = plt.subplots(figsize=(6, 4))
    for k, (x, _) in enumerate(test):
        ax.plot(x[:, 7], x[:, 8], color="tab:blue", alpha=0.5, label="human" if k == 0 else None)
    ax.plot(synthesised[:, 7], synthesised[:, 8], color="tab:red", linewidth=2, label="PHMM synthesis")
    ax.set_xlabel("wrist y (m)")
    ax.set_ylabel("wrist z (m)")
    ax.set_title(f"reach to {target.round(2)} m")
    ax.legend()
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(f"saved {args.out}")


if __name__ == "__main__":
    main()
