"""Recognise what a demonstrator does in an episode the models never saw, from the arm markers alone.

Learns action models from ``paper`` recordings (discovery on the object trajectories, one parametric
HMM per discovered class, the action grammar), then cuts a held-out episode into primitives and
names each, with where it started and ended (its effect phi), as discovery would from the object.

    python examples/phmm_recognition.py [--train data/paper-s0.h5 data/paper-s2.h5] [--test data/paper-s3.h5]
        [--episode 5]

Missing recordings are made first (about half a minute each). The full evaluation is
``benchmarks/phmm_recognition.py``; the command line has the same pipeline as ``hoap-actions learn``
and ``hoap-actions recognize``.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

from hoap_actions.demonstration.datasets import load_demonstrations
from hoap_actions.demonstration.recording import record
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.pipelines.learn import learn


def recording(path: Path) -> Path:
    """``path`` (named ``paper-s<seed>.h5``), recorded first if it is missing."""
    if not path.exists():
        seed = re.search(r"-s(\d+)\.h5$", path.name)
        if seed is None:
            raise SystemExit(f"{path} does not exist; name it paper-s<seed>.h5 to have it recorded")
        print(f"recording {path} (paper preset, seed {seed.group(1)})")
        record("paper", path, seed=int(seed.group(1)))
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", type=Path, nargs="+", default=[Path("data/paper-s0.h5"), Path("data/paper-s2.h5")])
    parser.add_argument("--test", type=Path, default=Path("data/paper-s3.h5"))
    parser.add_argument("--episode", type=int, default=5, help="held-out episode to recognise")
    args = parser.parse_args()
    train = [recording(p) for p in args.train]
    test = load_demonstrations(recording(args.test))
    episode = test[args.episode]

    models, summary = learn(train)
    print(summary.report())

    decoded = models.decode(episode.H)  # cut and classify from the arm markers alone
    truth = models.discovery_.predict(episode.O, [episode.T])[0]  # what discovery says from the object
    print(f"episode {args.episode}: {episode.ground_truth.action} {episode.ground_truth.direction} "
          f"({episode.T} frames at {test.fps:.0f} Hz)")
    print("  recognised from the arm markers:")
    for s in decoded:
        kind = models.classes_[s.class_id].kind
        print(f"    frames {s.start:4d}-{s.end:4d}: class {s.class_id:2d} ({kind}), from {np.round(s.phi[:3], 3)} "
              f"to {np.round(s.phi[3:], 3)} m")
    print("  discovery's classes from the object: "
          + ", ".join(f"{c} ({a}-{b})" for c, a, b in runs(truth)))


if __name__ == "__main__":
    main()
