"""Recognition of a demonstrator by models that never saw them, against models that did.

Two sets of action models (:func:`hoap_actions.primitives.pipelines.learn.learn`) are learned from the same
number of ``paper`` recordings: one from the test demonstrator's own other recordings (same-demonstrator),
one from other demonstrators (cross-demonstrator). Both recognise the same held-out recording
(:func:`~hoap_actions.primitives.pipelines.recognize.recognize_recording`); the difference of each figure
says what a body and way of moving never seen cost.

    python benchmarks/cross_demonstrator.py [--test relaxed:1 [relaxed:11 ...]] [--same relaxed:2 relaxed:3 relaxed:4]
                                            [--cross reference:2 short:2 tall:2] [--jobs 2]

With several ``--test`` recordings (of one demonstrator) each figure and each cost is also reported as
mean, standard deviation and 95 % t-interval over them. A recording is ``demonstrator:seed``
(``hoap-actions record --preset paper --demonstrator D --seed S``), looked for in (and made in)
``--data``. Writes ``results/cross_demonstrator.json``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, write_json

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
    parser.add_argument("--test", type=recording, nargs="+", default=[("relaxed", 1)])
    parser.add_argument("--same", type=recording, nargs="+", default=[("relaxed", s) for s in (2, 3, 4)])
    parser.add_argument("--cross", type=recording, nargs="+", default=[("reference", 2), ("short", 2), ("tall", 2)])
    parser.add_argument("--jobs", type=int, default=2, help="worker processes for recording and recognition")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.demonstration.bodies import demonstrator_profile
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.pipelines.learn import learn
    from hoap_actions.primitives.pipelines.recognize import recognize_recording

    for name, seed in [*args.test, *args.same, *args.cross]:
        demonstrator_profile(name, seed)  # an unknown demonstrator fails before any recording
    tested = {name for name, _ in args.test}
    if tested & {name for name, _ in args.cross} or len(tested) > 1:
        raise SystemExit(f"the tests must be one demonstrator's recordings and the cross-demonstrator models must "
                         f"not see it; got tests of {sorted(tested)}")
    if set(args.test) & set(args.same):
        raise SystemExit("a test recording must not be among the same-demonstrator training recordings")

    def path(item: tuple[str, int]) -> Path:
        return ensure_recording("paper", item[1], args.data, workers=args.jobs, demonstrator=item[0])

    tests = {f"{d}:{s}": load_demonstrations(path((d, s))) for d, s in args.test}
    per_test = {test: {} for test in tests}
    training_of = {}
    for name, training in (("same", args.same), ("cross", args.cross)):
        models, learned = learn([path(item) for item in training])
        print(f"{name}: learned {learned.report()}", flush=True)
        training_of[name] = {"training": [f"{d}:{s}" for d, s in training], "classes": learned.n_classes}
        for test, demos in tests.items():
            result = recognize_recording(models, demos, jobs=args.jobs)
            per_test[test][name] = {k: result[k] for k in FIGURES}
            print(f"{test}, {name}: " + ", ".join(f"{k} {result[k]:.4g}" for k in FIGURES), flush=True)
    for test, results in per_test.items():
        cost = {k: results["same"][k] - results["cross"][k] for k in FIGURES}
        cost["phi_error_median_m"] *= -1  # an error: larger is worse
        cost["oracle_cut_phi_error_median_m"] *= -1
        results["same_minus_cross"] = cost
        print(f"{test}, cost of a demonstrator never seen: " + ", ".join(f"{k} {v:.4g}" for k, v in cost.items()))
    summary = {part: {k: spread([r[part][k] for r in per_test.values()]) for k in FIGURES}
               for part in ("same", "cross", "same_minus_cross")} if len(per_test) > 1 else None
    for part, figures in (summary or {}).items():
        print(f"{part}: " + ", ".join(f"{k} {s['mean']:.4g} [{s['ci95'][0]:.4g}, {s['ci95'][1]:.4g}]"
                                      for k, s in figures.items()))
    document = {"benchmark": "cross_demonstrator", "tests": list(per_test), "models": training_of,
                "per_test": per_test, "summary": summary, "goals_at_most": GOALS,
                "params": models.get_params(), "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
