"""Primitive discovery on the ``paper`` preset, evaluated against the hidden phase labels.

Fits :class:`PrimitiveDiscovery` (tuned defaults unless ``--spacing`` / ``--threshold``) on each
recording and prints what :func:`evaluate_discovery` measures: action groups found against the true
actions, frame accuracy after one-to-one (Hungarian) and many-to-one mapping, with the ceiling any
method reading only the object trajectories can reach, edit score, boundary F1 within +-k frames
(100 Hz). The first seed is the headline; further seeds are other recordings (other start poses,
speeds and paths) checking that the tuned parameters are not specific to one.

    python benchmarks/discovery_eval.py [--seeds 0 1] [--demos PATH] [--spacing S] [--threshold T]

Recordings are looked for in ``--data`` (``data/`` under the checkout) as ``paper-s<seed>.h5`` and
recorded there when missing (about 2 minutes each). Writes ``results/discovery_eval.json``; earlier
figures are in ``docs/experiments/discovery.md``.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

HEADLINE = ("labels_version", "n_action_groups", "n_true_actions", "n_true_phases", "phases_missed", "frame_accuracy",
            "edit_score", "boundary_f1", "fit_seconds", "params")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("discovery_eval.json", data=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1], help="paper-preset recordings to evaluate")
    parser.add_argument("--demos", type=Path, help="evaluate this dataset instead of the seeds' recordings")
    parser.add_argument("--spacing", type=float, help="override the tuned spacing (m)")
    parser.add_argument("--threshold", type=float, help="override the tuned threshold (nats)")
    parser.add_argument("--rerecord-stale", action="store_true",
                        help="record again the recordings older than the demonstrator's sources")
    return parser.parse_args(argv)


def evaluate(path: Path, spacing: float | None, threshold: float | None) -> dict:
    """Fit on one dataset, time it and evaluate it."""
    import numpy as np

    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
    from hoap_actions.primitives.evaluation.discovery import evaluate_discovery

    demos = load_demonstrations(path)
    params = {k: v for k, v in (("spacing", spacing), ("threshold", threshold)) if v is not None}
    model = PrimitiveDiscovery(**params)
    X, lengths = np.concatenate([e.O for e in demos]), [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    started, cpu = time.perf_counter(), time.process_time()
    model.fit(X, lengths, H)
    wall, cpu = time.perf_counter() - started, time.process_time() - cpu
    result = evaluate_discovery(model, demos)
    return {
        "demonstrations_file": str(path),
        "generator": demos.generator.get("preset"),
        "seed": demos.seed,
        "params": {"spacing": model.spacing, "threshold": model.threshold},
        "fit_seconds": wall,
        "fit_cpu_seconds": cpu,
        "n_joint_states": len(model.joint_means_),
        **result,
    }


def print_result(r: dict) -> None:
    acc, edit, f1 = r["frame_accuracy"], r["edit_score"], r["boundary_f1"]
    print(f"\n=== {r['demonstrations_file']} (seed {r['seed']}): {r['n_demonstrations']} demonstrations, "
          f"{r['n_frames']} frames, labels_version {r['labels_version']}")
    print(f"spacing {r['params']['spacing']} m, threshold {r['params']['threshold']} nats: {r['n_joint_states']} "
          f"joint states, {r['n_primitives']} primitives, fit {r['fit_seconds']:.2f} s wall "
          f"({r['fit_cpu_seconds']:.2f} s CPU)")
    print(f"action groups found: {r['n_action_groups']}   true actions: {r['n_true_actions']} "
          f"({', '.join(r['true_actions'])}); {r['n_true_phases']} phase labels, missed: "
          f"{', '.join(r['phases_missed']) or 'none'}")
    print(f"  {'group':>5} {'kind':<13} {'primitives':<34} {'frames':>6}  {'-> phase':<14} purity  "
          f"(among manipulation frames)")
    for g in r["groups"]:
        ids = g["primitives"]
        prims = " ".join(map(str, ids)) if len(ids) <= 6 else f"{' '.join(map(str, ids[:5]))} ... ({len(ids)})"
        print(f"  {g['group']:>5} {g['kind']:<13} {prims:<34} {g['frames']:>6}  {g['phase'] or '-':<14} "
              f"{g['purity']:.3f}   " + (f"{g['manipulation_purity']:.3f}" if g["kind"] == "manipulation" else "-"))
    print("frame accuracy:")
    for name, key in (("one-to-one (Hungarian)", "one_to_one"), ("many-to-one", "many_to_one")):
        print(f"  {name:<23} primitives {acc[key + '_primitives']:.3f}   groups {acc[key + '_groups']:.3f}")
    print(f"  ceiling from O alone (effect-visible labels vs true) {acc['ceiling_effect_visible']:.3f};  "
          f"groups vs effect-visible labels {acc['many_to_one_groups_vs_effect_visible']:.3f}")
    print(f"edit score: many-to-one groups {edit['many_to_one_groups']:.3f}, one-to-one groups "
          f"{edit['one_to_one_groups']:.3f};  demonstrations with the true action sequence "
          f"{r['demonstrations_with_true_action_sequence']:.3f}")
    for name, values in f1.items():
        print(f"boundary F1 ({name}): " + ", ".join(f"+-{k}: {v:.3f}" for k, v in values.items()))


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from _discovery_data import paper_recording, sources_digest

    paths = [args.demos] if args.demos else [paper_recording(s, args.data, args.rerecord_stale) for s in args.seeds]
    results = [evaluate(path, args.spacing, args.threshold) for path in paths]
    for r in results:
        print_result(r)
    document = {
        "benchmark": "discovery_eval",
        "demonstrator_sources_sha256_16": sources_digest(),
        "headline": {k: results[0][k] for k in HEADLINE},
        "results": results,
        "environment": numeric_environment(blas_threads=None),
    }
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
