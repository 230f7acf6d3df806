"""The ``hoap-actions`` command line: run demos, record demonstrations, discover primitives."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from hoap_actions.episodes import run_episodes, summarise
from hoap_actions.errors import HoapActionsError


def _demo(args: argparse.Namespace) -> int:
    from hoap_actions.controllers.policies import policy_class

    policy = policy_class(args.policy)
    results = run_episodes(
        env_id=args.env,
        policy_factory=policy,
        episodes=args.episodes,
        seed=args.seed,
        video=args.video,
        snapshot=args.snapshot,
        env_kwargs={"control_mode": policy.control_mode},  # the scripted expert acts through ee_delta
    )
    summary = summarise(results)
    print(
        f"{args.policy} policy on {args.env}: success rate {summary['success_rate']:.1%} "
        f"over {len(results)} episodes (seeds {args.seed}..{args.seed + args.episodes - 1}), falls: {summary['falls']}"
    )
    for reason, count in summary["reasons"].items():
        print(f"  {reason}: {count}")
    if args.video:
        print(f"video of the first episode: {args.video}")
    if args.snapshot:
        print(f"scene snapshot: {args.snapshot}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(summary, indent=2) + "\n")
        print(f"results: {args.json}")
    return 0


def _record(args: argparse.Namespace) -> int:
    from hoap_actions.envs.recording import record

    path = record(args.preset, args.out, seed=args.seed, overwrite=args.overwrite)
    print(f"wrote {path}")
    return 0


def _discover(args: argparse.Namespace) -> int:
    from hoap_actions.primitives.discovery_report import discover_to_dir

    summary = discover_to_dir(
        args.demos, args.out, threshold=args.threshold, spacing=args.spacing, overwrite=args.overwrite
    )
    print(summary.report())
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hoap-actions", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="run a policy for N episodes and report its success rate")
    demo.add_argument("--policy", default="random", help="policy name (default: random)")
    demo.add_argument("--env", default="hoap_actions/PegInsert-v0", help="environment id")
    demo.add_argument("--episodes", type=int, default=10)
    demo.add_argument("--seed", type=int, default=0, help="layouts are drawn from seeds S, S+1, ...")
    demo.add_argument("--video", type=Path, help="write an mp4 of the first episode here")
    demo.add_argument("--snapshot", type=Path, help="write a PNG of the first episode's scene here")
    demo.add_argument("--json", type=Path, help="write per-episode results here")
    demo.set_defaults(func=_demo)

    rec = sub.add_parser("record", help="record simulated human demonstrations to an HDF5 dataset")
    rec.add_argument("--preset", required=True, choices=["paper", "approach-grid", "small"])
    rec.add_argument("--out", type=Path, required=True, help="dataset file to write (.h5)")
    rec.add_argument("--seed", type=int, default=0)
    rec.add_argument("--overwrite", action="store_true", help="replace an existing dataset at --out")
    rec.set_defaults(func=_record)

    disc = sub.add_parser("discover", help="discover action primitives in recorded demonstrations (paper's method)")
    disc.add_argument("--demos", type=Path, required=True, help="demonstrations dataset (.h5, from `record`)")
    disc.add_argument("--out", type=Path, required=True, help="directory for the model, classes, grammar, figures")
    disc.add_argument("--threshold", type=float, help="state-merge threshold, nats (default: the tuned one)")
    disc.add_argument("--spacing", type=float, help="arc length per Gaussian, m (default: the tuned one)")
    disc.add_argument("--overwrite", action="store_true", help="replace previous results in --out")
    disc.set_defaults(func=_discover)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s"
    )
    try:
        return args.func(args)
    except HoapActionsError as error:  # a user's mistake or a bad file: say what, no traceback
        print(f"hoap-actions {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
