"""Unseen demonstrators against the reference one, paired: the runs of ``benchmarks/imitation.py`` with
``--demonstrator`` named on the same seeds (a named demonstrator draws the same task and layout from a
seed whoever it is), each policy's success for each unseen demonstrator minus the reference one's.

    for who in reference relaxed short tall; do python benchmarks/imitation.py --seeds 94200 94250 \\
        --demonstrator $who --policies camera oracle --workers 2 \\
        --output benchmarks/results/imitation_demonstrator_$who.json; done
    python benchmarks/imitation_demonstrators.py

Reads ``results/imitation_demonstrator_<name>.json`` and writes ``results/imitation_demonstrators_paired.json``:
per policy and unseen demonstrator, the success rates, the episodes only one of the pair solved, the exact
McNemar p and the difference with its 95 % bootstrap interval
(:func:`~hoap_actions.apps.episodes.paired_outcomes`); and on how many seeds the two were shown the same
action (a demonstration that missed its aim is drawn again, which can change the task).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from hoap_actions.apps.episodes import paired_outcomes
from hoap_actions.demonstration.bodies import DEMONSTRATORS

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import RESULTS, arguments, write_json

REFERENCE = "reference"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("imitation_demonstrators_paired.json")])
    parser.add_argument("--runs", type=Path, default=RESULTS, help="folder of the imitation_demonstrator_*.json runs")
    args = parser.parse_args()
    runs = {who: json.loads((args.runs / f"imitation_demonstrator_{who}.json").read_text()) for who in DEMONSTRATORS}
    reference = runs[REFERENCE]
    document: dict = {"seeds": reference["seeds"], "level": reference["level"], "robot": reference["robot"]}
    for who, run in runs.items():
        if run["seeds"] != reference["seeds"] or run["demonstrator"] != who:
            raise SystemExit(f"the {who} run is not the named demonstrator on the reference run's seeds")
        if who == REFERENCE:
            continue
        pairs = zip(run["camera"]["episodes"], reference["camera"]["episodes"])
        same = sum(a["action"] == b["action"] for a, b in pairs)
        document[who] = {"same_action_shown": same, "of": len(reference["camera"]["episodes"])}
        for policy in ("camera", "oracle"):
            pair = paired_outcomes(run[policy]["episodes"], reference[policy]["episodes"])
            document[who][policy] = {"success_rate": run[policy]["success_rate"],
                                     "reference_success_rate": reference[policy]["success_rate"], **pair}
            low, high = pair["difference_ci95"]
            print(f"{policy:>7}, {who} - reference: {100 * pair['difference']:+.1f} points [{100 * low:+.1f}, "
                  f"{100 * high:+.1f}] ({run[policy]['success_rate']:.0%} against "
                  f"{reference[policy]['success_rate']:.0%}); only {who} {pair['only_first']}, only reference "
                  f"{pair['only_second']}, McNemar p {pair['mcnemar_p']:.2g}; same action shown on {same} of "
                  f"{document[who]['of']} seeds")
    write_json(args.output, document)


if __name__ == "__main__":
    main()
