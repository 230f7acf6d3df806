"""Whole-action synthesis on held-out recordings: each carry, push or rotation a demonstrator made,
synthesised by the learned action at phi = (the object's start, its end) and compared with the hand.

Protocol and baseline: :mod:`hoap_actions.primitives.evaluation.synthesis`. Models: the shipped ones
(``paper`` seeds 0-9) unless ``--models``; held-out recordings: ``--test-seeds`` (default 107, declared
for this check before it was recorded).

    python benchmarks/action_synthesis.py [--models DIR] [--test-seeds 107]

Writes ``results/action_synthesis.json``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, write_json


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("action_synthesis.json", data=True)])
    parser.add_argument("--models", type=Path, help="models directory (default: the shipped models)")
    parser.add_argument("--test-seeds", type=int, nargs="+", default=[107])
    args = parser.parse_args(argv)
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import load_default_models
    from hoap_actions.primitives.evaluation.synthesis import whole_action_errors
    from hoap_actions.primitives.models.action_models import ActionModels

    models = ActionModels.load(args.models) if args.models else load_default_models()
    document = {"models": str(args.models or "shipped"), "test_seeds": args.test_seeds, "actions": {}}
    for seed in args.test_seeds:
        errors = whole_action_errors(models, load_demonstrations(ensure_recording("paper", seed, args.data)))
        for action, entry in errors.items():
            merged = document["actions"].setdefault(str(action),
                                                    {"lift_m": entry["lift_m"], "model_m": [], "baseline_m": []})
            merged["model_m"] += entry["model_m"]
            merged["baseline_m"] += entry["baseline_m"]
    for action, entry in document["actions"].items():
        model, baseline = np.array(entry["model_m"]), np.array(entry["baseline_m"])
        entry.update(runs=len(model), model_median_m=float(np.median(model)),
                     model_p90_m=float(np.percentile(model, 90)), baseline_median_m=float(np.median(baseline)))
        print(f"action {action} (lift {100 * entry['lift_m']:.1f} cm): {len(model)} runs, hand error median "
              f"{100 * entry['model_median_m']:.2f} cm (p90 {100 * entry['model_p90_m']:.2f}); straight-line baseline "
              f"{100 * entry['baseline_median_m']:.2f} cm")
    document["environment"] = numeric_environment(None)
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
