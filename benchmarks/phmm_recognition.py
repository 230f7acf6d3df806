"""Recognition of discovered primitives on held-out recordings, from the arm markers alone and with the cuts given.

Protocol: action models are learned (:func:`hoap_actions.primitives.pipelines.learn.learn`: discovery
on the training recordings' object trajectories, one PHMM per class on the arm markers) from the
``paper`` recordings with ``--train-seeds``, then every held-out recording (``--test-seeds``, never
used to choose a setting) is recognised with
:func:`hoap_actions.primitives.pipelines.recognize.recognize_recording`: frame and segment accuracy,
edit score and phi error from the markers alone, class accuracy with the cuts given, and a
frame-by-frame baseline. Each figure is reported per recording and as mean, standard deviation and
95 % t-interval over the held-out recordings. How the defaults were chosen: ``docs/experiments/recognition.md``.

    python benchmarks/phmm_recognition.py [--train-seeds 0 1 ... 9] [--test-seeds 101 102 103] [--jobs 2]

Recordings are looked for in ``--data`` (``data/`` under the checkout) as ``paper-s<seed>.h5`` and
recorded there when missing. Writes ``results/phmm_recognition.json``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, write_json

GOALS = {"frame_accuracy": 0.90, "edit_score": 0.90, "oracle_cut_accuracy": 0.97, "phi_error_median_m": 0.01}
FIGURES = ("frame_accuracy", "segment_accuracy", "edit_score", "oracle_cut_accuracy", "phi_error_median_m",
           "oracle_cut_phi_error_median_m", "baseline_frame_accuracy", "baseline_edit_score", "wall_s", "movement_s")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("phmm_recognition.json", data=True)])
    parser.add_argument("--train-seeds", type=int, nargs="+", default=list(range(10)))
    parser.add_argument("--test-seeds", type=int, nargs="+", default=[101, 102, 103])
    parser.add_argument("--models", type=Path, help="use this models directory instead of learning one")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes for recognition")
    parser.add_argument("--no-oracle", dest="oracle", action="store_false", help="skip recognition with the cuts given")
    parser.add_argument("--mean-model", default="linear", choices=("linear", "tps"),
                        help="the class PHMMs' mean model (default: %(default)s)")
    parser.add_argument("--smoothing", type=float, default=1.0, help="ridge on the thin-plate bend (tps)")
    parser.add_argument("--object-vote", type=float,
                        help="nats for the class of each piece (cuts given) or frame (markers alone) in discovery's "
                             "parse of the object path estimated from the hand (default: the models' own; 0: off)")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.models.action_models import ActionModels
    from hoap_actions.primitives.pipelines.learn import learn
    from hoap_actions.primitives.pipelines.recognize import recognize_recording

    train = [ensure_recording("paper", seed, args.data) for seed in args.train_seeds]
    tests = [ensure_recording("paper", seed, args.data) for seed in args.test_seeds]
    learned = None
    if args.models is None:
        models, learned = learn(train, progress=True, mean_model=args.mean_model, smoothing=args.smoothing)
        print(f"learned {learned.report()}")
    else:
        models = ActionModels.load(args.models)
    if args.object_vote is not None:
        models.set_params(object_vote=args.object_vote)
    per_recording = {}
    for seed, path in zip(args.test_seeds, tests):
        result = recognize_recording(models, load_demonstrations(path), jobs=args.jobs, oracle=args.oracle,
                                     progress=True)
        per_recording[seed] = result
        print(f"seed {seed}: " + ", ".join(f"{k} {_show(result[k])}" for k in FIGURES if result[k] is not None))
    summary = {k: spread([r[k] for r in per_recording.values()]) for k in FIGURES
               if all(r[k] is not None for r in per_recording.values())}
    for name, s in summary.items():
        print(f"{name:>32}: mean {_show(s['mean'])}, sd {_show(s['sd'])}, 95 % interval "
              f"[{_show(s['ci95'][0])}, {_show(s['ci95'][1])}]")
    document = {
        "protocol": {"train_seeds": args.train_seeds, "test_seeds": args.test_seeds, "preset": "paper",
                     "models": str(args.models) if args.models else "learned here", "params": models.get_params()},
        "learning": None if learned is None else {"classes": learned.n_classes, "states": learned.n_states,
                                                  "discovery_s": learned.discovery_s, "training_s": learned.training_s},
        "per_recording": per_recording,
        "summary": summary,
        "goals": GOALS,
        "environment": numeric_environment(blas_threads=None),
    }
    write_json(args.output, document)
    return document


def _show(value: float) -> str:
    return f"{value:.4g}"


if __name__ == "__main__":
    main()
