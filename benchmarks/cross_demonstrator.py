"""Recognition of a demonstrator by models that never saw them, against models that did.

Two sets of action models (:func:`hoap_actions.primitives.learning.learn`) are learned from the same
number of ``paper`` recordings: one from the test demonstrator's own other recordings (same-demonstrator),
one from other demonstrators (cross-demonstrator). Both recognise the same held-out recording
(:func:`~hoap_actions.primitives.recognition_eval.recognize_recording`); the difference of each figure
says what a body and way of moving never seen cost.

    python benchmarks/cross_demonstrator.py [--test relaxed:1] [--same relaxed:2 relaxed:3 relaxed:4]
                                            [--cross reference:2 short:2 tall:2] [--jobs 2]

A recording is ``demonstrator:seed`` (``hoap-actions record --preset paper --demonstrator D --seed S``),
looked for in (and made in) ``--data``. Writes ``results/cross_demonstrator.json``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, write_json  # noqa: E402

FIGURES = ("frame_accuracy", "segment_accuracy", "edit_score", "oracle_cut_accuracy", "phi_error_median_m",
           "oracle_cut_phi_error_median_m")
GOALS = {"frame_accuracy": 0.02, "edit_score": 0.02, "oracle_cut_accuracy": 0.02, "phi_error_median_m": 0.002}


def recording(text: str) -> tuple[str, int]:
    name, _, seed = text.partition(":")
    try:
        return name, int(seed)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a recording is demonstrator:seed, e.g. tall:2; got {text!r}") from None


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("cross_demonstrator.json", data=True)])
    parser.add_argument("--test", type=recording, default=("relaxed", 1))
    parser.add_argument("--same", type=recording, nargs="+", default=[("relaxed", s) for s in (2, 3, 4)])
    parser.add_argument("--cross", type=recording, nargs="+", default=[("reference", 2), ("short", 2), ("tall", 2)])
    parser.add_argument("--jobs", type=int, default=2, help="worker processes for recording and recognition")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.envs.demonstrators import demonstrator_profile
    from hoap_actions.primitives.datasets import load_demonstrations
    from hoap_actions.primitives.learning import learn
    from hoap_actions.primitives.recognition_eval import recognize_recording

    for name, seed in [args.test, *args.same, *args.cross]:
        demonstrator_profile(name, seed)  # an unknown demonstrator fails before any recording
    if args.test[0] in {name for name, _ in args.cross}:
        raise SystemExit(f"the cross-demonstrator models must not see {args.test[0]!r}")

    def path(item: tuple[str, int]) -> Path:
        return ensure_recording("paper", item[1], args.data, workers=args.jobs, demonstrator=item[0])

    test = load_demonstrations(path(args.test))
    results = {}
    for name, training in (("same", args.same), ("cross", args.cross)):
        models, learned = learn([path(item) for item in training])
        print(f"{name}: learned {learned.report()}", flush=True)
        result = recognize_recording(models, test, jobs=args.jobs)
        results[name] = {"training": [f"{d}:{s}" for d, s in training], "classes": learned.n_classes,
                         **{k: result[k] for k in FIGURES}}
        print(f"{name}: " + ", ".join(f"{k} {result[k]:.4g}" for k in FIGURES), flush=True)
    difference = {k: results["same"][k] - results["cross"][k] for k in FIGURES}
    difference["phi_error_median_m"] *= -1  # an error: larger is worse
    difference["oracle_cut_phi_error_median_m"] *= -1
    print("cost of a demonstrator never seen: " + ", ".join(f"{k} {v:.4g}" for k, v in difference.items()))
    document = {"benchmark": "cross_demonstrator", "test": f"{args.test[0]}:{args.test[1]}", "results": results,
                "same_minus_cross": difference, "goals_at_most": GOALS,
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
