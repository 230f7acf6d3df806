"""The commands that run episodes: ``hoap-actions demo`` (policies on drawn layouts) and ``hoap-actions
imitate`` (the imitation policies on ``Imitate-v0``, drawn or replayed demonstrations)."""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
from pathlib import Path

from hoap_actions.apps.episodes import compare_policies, film_episode, summarise
from hoap_actions.errors import InvalidInputError
from hoap_actions.outputs import claimed_file
from hoap_actions.seeds import check_seed

__all__ = ["DRAWN_EPISODES", "demo_command", "imitate_command"]

DRAWN_EPISODES = 10  # imitate's demonstrations when neither --episodes nor --demos is given


def demo_command(args: argparse.Namespace) -> int:
    """``hoap-actions demo``: every policy on every seed's layout, the chosen episode filmed."""
    from hoap_actions.policies.registry import policy_class

    names = list(dict.fromkeys(args.policy))
    classes = {name: policy_class(name, args.env) for name in names}
    if len({c.control_mode for c in classes.values()}) > 1:
        raise InvalidInputError(f"policies {names} act through different control modes; run them separately")
    if args.models is not None and "phmm" not in names:
        raise InvalidInputError("--models is for the phmm policy; add --policy phmm or leave --models out")
    if args.models is not None:  # read once here: a bad directory is one line, not a broken worker pool
        from hoap_actions.primitives.models.action_models import ActionModels

        ActionModels.load(args.models)
    kwargs = {name: ({"models": str(args.models)} if name == "phmm" and args.models is not None else {})
              for name in names}
    check_seed(args.seed, count=args.episodes)
    last_seed = args.seed + args.episodes - 1
    if args.film >= args.episodes:
        raise InvalidInputError(f"--film {args.film} is past the last episode; accepted: 0..{args.episodes - 1}")
    with contextlib.ExitStack() as outputs:  # claimed before the first episode, published at the end
        claim = {
            name: outputs.enter_context(claimed_file(path, args.overwrite, what=name)) if path else None
            for name, path in (("video", args.video), ("snapshot", args.snapshot), ("report", args.json))
        }
        env_kwargs, options = getattr(args, "env_kwargs", None), getattr(args, "options", None)
        results = compare_policies(args.env, {name: (name, kwargs[name]) for name in names},
                                   range(args.seed, last_seed + 1), workers=args.workers, robot=args.robot,
                                   ray_address=args.ray, env_kwargs=env_kwargs, options=options)
        if claim["video"] or claim["snapshot"]:  # episodes depend on their seed alone: the chosen one again, filmed
            film_episode(args.env, functools.partial(classes[names[0]], **kwargs[names[0]]), args.seed + args.film,
                         classes[names[0]].control_mode, video=claim["video"], snapshot=claim["snapshot"],
                         camera=args.camera, robot=args.robot, env_kwargs=env_kwargs,
                         options=None if options is None else options[args.film])
        summaries = {name: summarise(episodes) for name, episodes in results.items()}
        if claim["report"]:  # without wall times: the same file whatever --workers
            report = {"env": args.env, "robot": args.robot, "seeds": [args.seed, last_seed],
                      "policies": {name: summarise(episodes, timings=False) for name, episodes in results.items()}}
            if env_kwargs:
                report["env_kwargs"] = env_kwargs
            if options is not None:
                report["reset_options"] = options
            claim["report"].write_text(json.dumps(report, indent=2) + "\n")
    replayed = f"; demonstrations from {args.demos}" if getattr(args, "demos", None) else ""
    for name, summary in summaries.items():
        low, high = summary["success_ci95"]
        print(f"{name} policy on {args.env} ({args.robot} robot): success rate {summary['success_rate']:.1%} (95 % "
              f"interval {low:.0%}-{high:.0%}) "
              f"over {args.episodes} episodes (seeds {args.seed}..{last_seed}{replayed}), falls: {summary['falls']}, "
              f"mean episode {summary['mean_wall_s']:.1f} s")
        for reason, count in summary["reasons"].items():
            print(f"  {reason}: {count}")
        if "perception_error_m" in summary and summary["perception_error_m"]["max"] is not None:
            print(f"  largest perception error of a target peg or hole: "
                  f"{1000 * summary['perception_error_m']['max']:.2f} mm")
        read = [e for e in results[name] if e.reading_s is not None]
        if read:  # an imitation policy: its time reading the demonstration apart from its acting
            acting = [e.wall_s - e.reset_s - e.reading_s - (e.filming_s or 0.0) for e in read]
            print(f"  per episode: reading the demonstration {sum(e.reading_s for e in read) / len(read):.1f} s, "
                  f"acting {sum(acting) / len(acting):.1f} s")
    if args.video:
        print(f"video of episode {args.film} ({names[0]}, seed {args.seed + args.film}, camera {args.camera}): "
              f"{args.video}")
    if args.snapshot:
        print(f"picture of episode {args.film} ({names[0]}, seed {args.seed + args.film}): {args.snapshot}")
    if args.json:
        print(f"results: {args.json}")
    return 0


def imitate_command(args: argparse.Namespace) -> int:
    """``demo`` on ``Imitate-v0`` with the imitation policy (and, with ``--ceiling``, the execution ceiling):
    drawn demonstrations, or with ``--demos`` episodes of a recording replayed (layouts from ``--seed`` on)."""
    reader = "imitation-markers" if args.from_markers else "imitation-camera"
    args.policy = [reader, "imitation-oracle"] if args.ceiling else [reader]
    args.env, args.models = "hoap_actions/Imitate-v0", None
    args.env_kwargs = {"level": args.level, "demonstrator": args.demonstrator}
    args.options = None
    if args.demos is not None:
        if args.episodes is not None:
            raise InvalidInputError("--episodes counts drawn demonstrations; with --demos pick the recording's "
                                    "episodes with --episode")
        if args.demonstrator is not None:
            raise InvalidInputError("--demonstrator draws who demonstrates; a recording (--demos) already has its own")
        episodes = _recorded_episodes(args.demos, args.episode)
        args.episodes = len(episodes)
        args.options = [{"demonstration": (str(args.demos), k)} for k in episodes]
    elif args.episode is not None:
        raise InvalidInputError("--episode picks episodes of a recording; give the recording with --demos")
    else:
        args.episodes = DRAWN_EPISODES if args.episodes is None else args.episodes
    return demo_command(args)


def _recorded_episodes(path: Path, chosen: list[int] | None) -> list[int]:
    """The episodes of the recording at ``path`` to replay (all when ``chosen`` is None), checked before any
    episode runs: a recording with camera frames to show (joint angles), the indices inside it."""
    from hoap_actions.demonstration.datasets import load_demonstrations

    demos = load_demonstrations(path)
    if not demos.joint_names:
        raise InvalidInputError(f"the recording {path} has no joint angles (Q), so it holds no camera frames to show; "
                                "record it again with this version: hoap-actions record")
    chosen = list(range(len(demos))) if chosen is None else chosen
    outside = [k for k in chosen if not 0 <= k < len(demos)]
    if outside:
        raise InvalidInputError(f"--episode {outside[0]} is not in the recording {path}; accepted: 0..{len(demos) - 1}")
    return chosen
