"""How much each demonstrator varies from one repetition to the next, marker by marker.

For every demonstrator (``--demonstrators``, names of :data:`hoap_actions.demonstration.bodies.DEMONSTRATORS`
or ``random``, drawn from the seed), each ``approach-grid`` recording (``--seeds``) gives, at each of the
35 test locations, 4 repetitions of the same reach;
:func:`~hoap_actions.primitives.evaluation.grid_synthesis.repetition_spread` measures each repetition
against the average of the other three, per marker; the mean and 95 % interval over the recordings are
reported. People vary at least as much in the trunk and elbow as in the hand; a tightly scripted arm
varies least at the shoulder.

    python benchmarks/demonstrator_variability.py [--demonstrators reference short tall relaxed random]
        [--seeds 0 1 2 3 4]

Recordings are looked for in (and made in) ``--data``. Writes ``results/demonstrator_variability.json``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, write_json


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("demonstrator_variability.json", data=True)])
    parser.add_argument("--demonstrators", nargs="+", default=["reference", "short", "tall", "relaxed", "random"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4], help="approach-grid recordings")
    parser.add_argument("--workers", type=int, default=2, help="processes recording a missing recording")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.demonstration.bodies import demonstrator_profile
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.evaluation.grid_synthesis import grid_data, repetition_spread

    for name in args.demonstrators:
        demonstrator_profile(name, args.seeds[0])  # an unknown name fails before any recording
    results = {}
    for name in args.demonstrators:
        recordings = {}
        for seed in args.seeds:
            path = ensure_recording("approach-grid", seed, args.data, workers=args.workers, demonstrator=name)
            demos = load_demonstrations(path)
            values = repetition_spread(grid_data(demos))
            recordings[seed] = {"profile": demonstrator_profile(name, seed).to_dict(),
                                "spread_cm": {m: round(float(v) * 100, 3) for m, v in zip(demos.marker_names, values)},
                                "missed_grasp_episodes": demos.generator["missed_grasp_episodes"],
                                "table_contact_episodes": demos.generator["table_contact_episodes"]}
        markers = list(recordings[args.seeds[0]]["spread_cm"])
        summary = {m: spread([r["spread_cm"][m] for r in recordings.values()]) for m in markers}
        results[name] = {"spread_cm": summary, "recordings": recordings}
        print(f"{name:>10}: " + ", ".join(f"{m} {s['mean']:.2f} [{s['ci95'][0]:.2f}, {s['ci95'][1]:.2f}]"
                                          for m, s in summary.items()) + " cm", flush=True)
    document = {"benchmark": "demonstrator_variability", "seeds": args.seeds, "results": results,
                "environment": numeric_environment(blas_threads=None)}
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
