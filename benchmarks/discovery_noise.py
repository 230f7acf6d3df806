"""Discovery on recordings with motion-capture noise: Fig. 7's structure, order, and baselines.

Each recording (``paper`` preset, ``--seeds``, recorded with ``--noise``: 1 mm marker and object
jitter, 1 deg, 5 mm skin offsets and an occlusion gap every 5 s per marker by default) is cleaned as
its declared noise requires (:mod:`hoap_actions.primitives.pipelines.mocap_cleaning`) and discovered with each
``--merging``; per recording and merging it reports whether Fig. 7's structure was found
(:func:`~hoap_actions.primitives.evaluation.discovery_robustness.structure_found`), the number of action groups
and the many-to-one frame accuracy, beside two baselines (rest detection with one manipulation label;
k-means on each motion's displacement). The first recording is also fitted in ``--shuffles`` random
orders: the number of different results says whether the structure depends on the order.

    python benchmarks/discovery_noise.py [--seeds 401 ... 410] [--noise SPEC] [--shuffles 10] [--workers 2]

With ``--undeclared`` the recordings are made exact and the noise is added afterwards, outside the
recorder, so the files still say they are exact (as real motion-capture files do); each is then
discovered twice, as it is (what a reader trusting the declaration gets) and cleaned as its measured
noise requires (:func:`~hoap_actions.primitives.pipelines.mocap_cleaning.clean_demonstrations`); no gaps
and no skin offsets, which an exact file cannot carry.

Recordings are looked for in (and made in) ``--data``. Writes ``results/discovery_noise.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, write_json

DEFAULT_NOISE = "marker=1,skin=5,gaps=0.2,object=1,angle=1"


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("discovery_noise.json", data=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(401, 411)))
    parser.add_argument("--noise", default=DEFAULT_NOISE, help="noise model of the recordings (default: %(default)s)")
    parser.add_argument("--merging", nargs="+", default=["agglomerative", "fold"], choices=["agglomerative", "fold"])
    parser.add_argument("--shuffles", type=int, default=10, help="random orders of the first recording")
    parser.add_argument("--workers", type=int, default=2, help="processes recording a missing recording")
    parser.add_argument("--undeclared", action="store_true",
                        help="add the noise to exact recordings after recording, without declaring it")
    return parser.parse_args(argv)


def fit(demos, merging: str, order=None):
    import dataclasses

    from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery

    if order is not None:
        demos = dataclasses.replace(demos, episodes=tuple(demos[i] for i in order))
    X, lengths = demos.object_data()
    return PrimitiveDiscovery(merging=merging).fit(X, lengths, demos.movement_data()[0])


def recording_figures(demos, mergings: list[str]) -> dict:
    import numpy as np

    from hoap_actions.primitives.evaluation.discovery import evaluate_discovery
    from hoap_actions.primitives.evaluation.discovery_robustness import (
        kmeans_baseline_labels,
        rest_baseline_labels,
        structure_found,
    )
    from hoap_actions.primitives.evaluation.segmentation import many_to_one_frame_accuracy

    out = {}
    for merging in mergings:
        started = time.perf_counter()
        model = fit(demos, merging)
        seconds = time.perf_counter() - started
        report = evaluate_discovery(model, demos)
        out[merging] = {"structure_found": structure_found(report), "n_action_groups": report["n_action_groups"],
                        "frame_accuracy": report["frame_accuracy"]["many_to_one_groups"],
                        "phases_missed": report["phases_missed"], "fit_s": seconds}
    true = [np.asarray(e.ground_truth.labels, int) for e in demos]
    n_true = report["n_true_actions"] - 2  # the manipulations
    out["rest_baseline_frame_accuracy"] = many_to_one_frame_accuracy(rest_baseline_labels(model, demos), true)
    out["kmeans_baseline_frame_accuracy"] = many_to_one_frame_accuracy(
        kmeans_baseline_labels(model, demos, n_true, seed=0), true)
    return out


def order_figures(demos, mergings: list[str], shuffles: int) -> dict:
    import numpy as np

    from hoap_actions.primitives.evaluation.discovery_robustness import order_signature

    rng = np.random.default_rng(0)
    orders = [np.arange(len(demos))] + [rng.permutation(len(demos)) for _ in range(shuffles)]
    out = {}
    for merging in mergings:
        signatures = [order_signature(fit(demos, merging, order), order) for order in orders]
        groups = [len(s) for s in signatures]
        out[merging] = {"orders": len(orders), "distinct_results": len(set(signatures)), "action_groups": groups}
    return out


def undeclared_noise(demos, noise, seed: int):
    """``demos`` with ``noise`` added to every episode (its own random stream), still saying they are exact."""
    import dataclasses

    from hoap_actions.demonstration.mocap import add_mocap_noise

    episodes = []
    for index, episode in enumerate(demos.episodes):
        H, O = add_mocap_noise(episode.H, episode.O, noise, demos.fps, seed + 1_000_000, index)
        episodes.append(dataclasses.replace(episode, H=H, O=O))
    return dataclasses.replace(demos, episodes=tuple(episodes))


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.demonstration.mocap import parse_noise
    from hoap_actions.primitives.pipelines.mocap_cleaning import clean_demonstrations

    noise = parse_noise(args.noise)  # a bad model fails before any recording
    if args.undeclared and (noise.has_gaps or noise.skin_offset_sd_m):
        raise SystemExit("--undeclared takes jitter only (marker, object, angle): an exact file has no gaps")
    per_recording = {}
    for seed in args.seeds:
        if args.undeclared:
            demos = undeclared_noise(load_demonstrations(ensure_recording("paper", seed, args.data,
                                                                          workers=args.workers)), noise, seed)
            trusting = recording_figures(demos, args.merging)
        demos = clean_demonstrations(demos if args.undeclared else
                                     load_demonstrations(ensure_recording("paper", seed, args.data, noise=args.noise,
                                                                          workers=args.workers)))
        per_recording[seed] = recording_figures(demos, args.merging)
        if args.undeclared:
            per_recording[seed]["trusting_the_declaration"] = trusting
        if seed == args.seeds[0]:
            shuffled = order_figures(demos, args.merging, args.shuffles)
        line = ", ".join(f"{m}: {'structure' if r['structure_found'] else 'NOT'} {r['n_action_groups']} groups "
                         f"{r['frame_accuracy']:.2%}" for m, r in per_recording[seed].items() if m in args.merging)
        print(f"seed {seed}: {line}; baselines rest {per_recording[seed]['rest_baseline_frame_accuracy']:.2%}, "
              f"k-means {per_recording[seed]['kmeans_baseline_frame_accuracy']:.2%}", flush=True)
        if args.undeclared:
            print("  read as declared (not cleaned): " + ", ".join(
                f"{m}: {r['n_action_groups']} groups {r['frame_accuracy']:.2%}"
                for m, r in trusting.items() if m in args.merging), flush=True)
    summary = {}
    for merging in args.merging:
        rows = [r[merging] for r in per_recording.values()]
        summary[merging] = {"structure_found": sum(r["structure_found"] for r in rows), "recordings": len(rows),
                            "frame_accuracy": spread([r["frame_accuracy"] for r in rows]),
                            "order": shuffled[merging]}
        s = summary[merging]
        print(f"{merging}: Fig. 7 structure in {s['structure_found']} of {s['recordings']} recordings; frame accuracy "
              f"mean {s['frame_accuracy']['mean']:.2%} [{s['frame_accuracy']['ci95'][0]:.2%}, "
              f"{s['frame_accuracy']['ci95'][1]:.2%}]; {s['order']['distinct_results']} different result(s) in "
              f"{s['order']['orders']} orders of seed {args.seeds[0]} (groups {s['order']['action_groups']})")
    for name in ("rest_baseline_frame_accuracy", "kmeans_baseline_frame_accuracy"):
        summary[name] = spread([r[name] for r in per_recording.values()])
        print(f"{name}: mean {summary[name]['mean']:.2%}")
    if args.undeclared:
        for merging in args.merging:
            rows = [r["trusting_the_declaration"][merging] for r in per_recording.values()]
            summary[merging]["trusting_the_declaration"] = {
                "structure_found": sum(r["structure_found"] for r in rows),
                "frame_accuracy": spread([r["frame_accuracy"] for r in rows])}
            t = summary[merging]["trusting_the_declaration"]
            print(f"{merging}, read as declared (exact, not cleaned): Fig. 7 structure in {t['structure_found']} of "
                  f"{len(rows)}; frame accuracy mean {t['frame_accuracy']['mean']:.2%}")
    document = {"benchmark": "discovery_noise", "noise": args.noise, "undeclared": args.undeclared, "seeds": args.seeds,
                "per_recording": per_recording, "summary": summary,
                "goals": {"structure_found": "9 of 10", "frame_accuracy": 0.95, "distinct_results": 1},
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
