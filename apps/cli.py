"""The ``hoap-actions`` command line: run demos, record demonstrations, discover primitives, learn and recognise.

Every argument and output path is checked before the long work starts; a mistake is one line on
stderr and exit status 2, with no traceback. Outputs are claimed at the start
(:mod:`hoap_actions.outputs`) and appear only when complete; an interrupted run (Ctrl-C, SIGTERM)
leaves none of its partial files behind.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import signal
import sys
import threading
from pathlib import Path
from typing import NoReturn

from hoap_actions import ENV_IDS, __version__
from hoap_actions.apps.episode_commands import demo_command, imitate_command
from hoap_actions.apps.videos import write_video
from hoap_actions.demonstration.bodies import DEMONSTRATORS
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.envs.scene import CAMERAS
from hoap_actions.errors import HoapActionsError, InvalidInputError
from hoap_actions.outputs import claimed_file
from hoap_actions.parallel import LOCAL_RAY, check_ray_address
from hoap_actions.seeds import MAX_SEED

EXIT_USAGE = 2  # a user's mistake or a bad file, as argparse uses it
EXIT_INTERRUPTED = 130  # 128 + SIGINT, the shell's convention


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line (the usage text is one ``--help`` away)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see --help)\n")


def _positive_int(text: str) -> int:
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _nonnegative_int(text: str) -> int:
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {value}")
    return value


def _seed(text: str) -> int:
    value = _integer(text)
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"a seed is an integer in 0..{MAX_SEED}, got {text}")
    return value


def _noise(text: str):
    from hoap_actions.demonstration.mocap import parse_noise

    try:
        return parse_noise(text)
    except InvalidInputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None


def _path(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path; give a file or folder name")
    return Path(text)


def _ray_address(text: str) -> str:
    try:
        return check_ray_address(text)
    except InvalidInputError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _robot_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="full", choices=list(ROBOT_MODELS),
                        help="full: the free-standing humanoid (default); fixed_legs: bolted at the pelvis, legs "
                             "welded "
                             "(it cannot fall, and it simulates 3.8x faster in joint_delta, 2.0x in ee_delta)")


def _ray_option(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--ray", nargs="?", const=LOCAL_RAY, type=_ray_address, metavar="ADDRESS",
                        help=f"run the {what} on Ray (pip install 'hoap-actions[ray]'): alone, a Ray instance on this "
                             "machine; with an ADDRESS (auto, ray://head:10001), that cluster. --workers then sets the "
                             "actors (default: one per CPU of the cluster); the output is the same")


def _collect(args: argparse.Namespace) -> int:
    from hoap_actions.apps.collect import collect

    if args.models is not None and args.policy != "phmm":
        raise InvalidInputError("--models is for the phmm policy; use --policy phmm or leave --models out")
    kwargs = {"models": str(args.models)} if args.models is not None else {}
    path = collect(args.env, args.policy, args.episodes, args.seed, args.dataset_id, kwargs, overwrite=args.overwrite,
                   robot=args.robot)
    print(f"wrote the Minari dataset {args.dataset_id} ({args.episodes} episodes of the {args.policy} policy, "
          f"{args.robot} robot): {path}")
    return 0


def _record(args: argparse.Namespace) -> int:
    from hoap_actions.demonstration.recording import record

    path = record(args.preset, args.out, seed=args.seed, overwrite=args.overwrite, workers=args.workers,
                  ray_address=args.ray, noise=args.noise, demonstrator=args.demonstrator)
    print(f"wrote {path}")
    return 0


def _merging(text: str) -> str:
    """A ``--merging`` value, checked when given (discovery's module is not imported for every command)."""
    from hoap_actions.primitives.discovery.estimator import MERGINGS

    if text not in MERGINGS:
        raise argparse.ArgumentTypeError(f"merging must be one of {', '.join(MERGINGS)}; got {text!r}")
    return text


def _merging_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--merging", type=_merging, metavar="{agglomerative,fold}",
                        help="how pieces merge into states: agglomerative (all at once, closest first: the result does "
                             "not depend on the demonstrations' order; the default) or fold (the paper's, in the "
                             "order given)")


def _discover(args: argparse.Namespace) -> int:
    from hoap_actions.primitives.pipelines.discover import discover_to_dir

    summary = discover_to_dir(
        args.demos, args.out, threshold=args.threshold, spacing=args.spacing, overwrite=args.overwrite,
        merging=args.merging,
    )
    print(summary.report())
    return 0


def _learn(args: argparse.Namespace) -> int:
    from hoap_actions.primitives.pipelines.learn import learn_to_dir

    summary = learn_to_dir(args.demos, args.out, discovery_dir=args.discovery, overwrite=args.overwrite, progress=True,
                           merging=args.merging)
    print(f"{summary.report()}; wrote {args.out}")
    return 0


def _recognize(args: argparse.Namespace) -> int:
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import load_default_models
    from hoap_actions.primitives.models.action_models import ActionModels
    from hoap_actions.primitives.pipelines.recognize import recognize_recording

    with contextlib.ExitStack() as outputs:
        report = outputs.enter_context(claimed_file(args.json, args.overwrite, what="report")) if args.json else None
        models = ActionModels.load(args.models) if args.models else load_default_models()
        demos = load_demonstrations(args.demos)
        result = recognize_recording(models, demos, jobs=args.jobs, oracle=args.oracle, progress=True)
        result = {"demos": str(args.demos), "models": str(args.models or "shipped default models"), **result}
        if report:
            report.write_text(json.dumps(result, indent=2) + "\n")
    oracle = (f"; cuts given: {result['oracle_cut_accuracy']:.1%} of segments" if args.oracle else "")
    phi = result["phi_error_median_m"]
    print(
        f"{result['episodes']} episodes, {result['segments']} segments: frame accuracy {result['frame_accuracy']:.1%}, "
        f"segment accuracy {result['segment_accuracy']:.1%}, edit score {result['edit_score']:.3f}{oracle}; "
        f"phi error median {'-' if phi is None else f'{100 * phi:.2f} cm'}; "
        f"{result['movement_s']:.0f} s of movement in {result['wall_s']:.0f} s"
    )
    if args.json:
        print(f"results: {args.json}")
    return 0


def _track(args: argparse.Namespace) -> int:
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import load_default_models
    from hoap_actions.primitives.hmm.posture import PostureModel
    from hoap_actions.primitives.models.action_models import ActionModels
    from hoap_actions.tracking import (
        effect_figure,
        side_cameras,
        track_episode,
        track_markers_episode,
        tracking_video_frames,
    )
    from hoap_actions.tracking.smoothing import MAX_LAG
    from hoap_actions.vision.body_model import BodyModel
    from hoap_actions.vision.depth_sensor import DepthSensor

    if args.from_markers and (args.video or args.clutter or args.side_camera or args.edges_only or args.noise
                              or args.depth or args.refine):
        raise InvalidInputError("--from-markers tracks without images; leave out --video, --clutter, --side-camera, "
                                "--edges-only, --noise, --depth and --refine")
    if args.grid_model and (args.models or args.posture or args.from_markers or args.side_camera or args.clutter
                            or args.noise or args.depth or args.lag or args.refine):
        raise InvalidInputError("--grid-model trains its own approach model on the recording's 3 x 3 grid and tracks "
                                "its one camera; leave out --models, --posture, --from-markers, --side-camera, "
                                "--clutter, --noise, --depth, --lag and --refine")
    if not 0 <= args.lag <= MAX_LAG:
        raise InvalidInputError(f"--lag must be 0..{MAX_LAG} frames; got {args.lag}")
    if args.fingertip and not args.refine:
        raise InvalidInputError("--fingertip goes with --refine (the detector's findings hold the refined pose)")
    args.pose_proposal = args.pose_proposal or ("hand" if args.grid_model else "turned" if args.from_markers
                                                else "offsets")
    with contextlib.ExitStack() as outputs:
        claimed = {name: outputs.enter_context(claimed_file(path, args.overwrite, what=name))
                   for name, path in (("report", args.json), ("video", args.video), ("figure", args.figure)) if path}
        demos = load_demonstrations(args.demos)
        if args.grid_model:
            return _track_grid_reach(args, demos, claimed)
        models = ActionModels.load(args.models) if args.models else load_default_models()
        posture = PostureModel.load(args.posture) if args.posture else None
        if args.from_markers:
            result = track_markers_episode(models, demos, args.episode, particles=args.particles, seed=args.seed,
                                           pose_proposal=args.pose_proposal, posture=posture, lag=args.lag)
        else:
            result = track_episode(models, demos, args.episode, particles=args.particles, seed=args.seed,
                                   keep_images="video" in claimed, clutter=args.clutter, image_noise=args.noise,
                                   silhouette=not args.edges_only, more_cameras=side_cameras(args.side_camera),
                                   pose_proposal=args.pose_proposal, posture=posture,
                                   depth_sensor=DepthSensor() if args.depth else None, lag=args.lag,
                                   refine=_refine_settings(args))
        summary = result.summary()
        if "report" in claimed:
            document = {"demos": str(args.demos), "episode": args.episode, "seed": args.seed,
                        "models": str(args.models or "shipped default models"), "pose_proposal": args.pose_proposal,
                        "posture": None if args.posture is None else str(args.posture), "depth": args.depth,
                        "refine": args.refine, "fingertip": args.fingertip,
                        **summary}
            claimed["report"].write_text(json.dumps(document, indent=2) + "\n")
        if "video" in claimed:
            body = BodyModel(models.marker_names_, torso_base=result.torso_base)
            write_video(claimed["video"], tracking_video_frames(result, body), demos.fps / 4)
        if "figure" in claimed:
            effect_figure(result, claimed["figure"], demos.fps)
    rms = summary["rms_m"]
    phi = summary["phi_error_m"]
    print(f"episode {args.episode}: {summary['frames']} frames ({summary['frames'] / demos.fps:.1f} s at "
          f"{demos.fps:.0f} Hz) tracked at {summary['hz']:.0f} frames/s with {args.particles} particles: "
          f"RMS shoulder {100 * rms['shoulder']:.1f}, elbow {100 * rms['elbow']:.1f}, finger "
          f"{100 * rms['index_tip']:.1f} cm (pooled {100 * summary['rms_m_pooled']:.1f}); approach end "
          f"{'-' if phi is None else f'{100 * phi:.1f} cm'} off"
          + ("" if summary.get("read_from_task_error_m") is None else
             f" ({100 * summary['read_from_task_error_m']:.1f} cm read from the task that followed)") + "; "
          + ("no frame has a known class" if summary["frame_accuracy"] is None else
             f"class agrees with discovery's on {summary['frame_accuracy']:.0%} of frames, its kind on "
             f"{summary['kind_accuracy']:.0%}"))
    if args.lag:
        smoothed = summary["smoothed"]
        print(f"smoothed {args.lag} frames behind: RMS pooled {100 * smoothed['rms_m_pooled']:.1f} cm, all markers "
              f"{100 * smoothed['rms_m_all']:.1f} cm"
              + ("" if smoothed["frame_accuracy"] is None else f"; class agrees on {smoothed['frame_accuracy']:.0%}"))
    if "refined" in summary:
        refined = summary["refined"]
        print(f"refined against each frame's images: RMS shoulder {100 * refined['rms_m']['shoulder']:.1f}, elbow "
              f"{100 * refined['rms_m']['elbow']:.1f}, finger {100 * refined['rms_m']['index_tip']:.1f} cm (pooled "
              f"{100 * refined['rms_m_pooled']:.1f}), {refined['hz']:.0f} frames/s with the refinement")
    if summary.get("read_frame_accuracy") is not None:
        print(f"the manipulation read again as the chain the block's displacement fits: class agrees on "
              f"{summary['read_frame_accuracy']:.0%}")
    return 0


def _refine_settings(args: argparse.Namespace) -> dict | None:
    """The refinement ``track`` asks for: None, the refiner's defaults, or with the shipped fingertip detector."""
    if not args.refine:
        return None
    from hoap_actions.vision.fingertip import shipped_fingertip_detector

    return {"fingertip": shipped_fingertip_detector()} if args.fingertip else {}


def _track_grid_reach(args: argparse.Namespace, demos, claimed: dict) -> int:
    """``track --grid-model``: the paper's experiment on one reach of an approach-grid recording."""
    from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA
    from hoap_actions.tracking.episode import render_frames
    from hoap_actions.tracking.grid_experiment import (
        grid_reaches,
        grid_tracking_models,
        reach_effect_figure,
        reach_picture,
        track_grid_reach,
    )

    reaches = {r.episode: r for r in grid_reaches(demos)}
    if args.episode not in reaches:
        raise InvalidInputError(f"episode {args.episode} is not a reach of the 5 x 7 test grid; those are episodes "
                                f"{min(reaches)}-{max(reaches)}")
    reach = reaches[args.episode]
    print(f"training the approach PHMM ({args.grid_model}) on the recording's 3 x 3 grid (a minute or more)",
          flush=True)
    models = grid_tracking_models(demos, args.grid_model, posture=args.grid_model == "thin-plate")
    rendered = render_frames(demos, reach.episode, range(reach.end))
    track = track_grid_reach(models, demos, reach, rendered, args.particles, args.seed, args.pose_proposal,
                             silhouette=not args.edges_only, object_cue=not args.edges_only,
                             keep_images="video" in claimed)
    summary = track.summary()
    if "report" in claimed:
        document = {"demos": str(args.demos), "episode": args.episode, "seed": args.seed, "grid_model": args.grid_model,
                    "pose_proposal": args.pose_proposal, "cues": "edges" if args.edges_only else "default",
                    "target_m": reach.target.tolist(), **summary}
        claimed["report"].write_text(json.dumps(document, indent=2) + "\n")
    if "video" in claimed:
        write_video(claimed["video"], [reach_picture(track, DEMONSTRATOR_CAMERA, t)
                                       for t in range(0, len(track.frames), 4)], demos.fps / 4)
    if "figure" in claimed:
        reach_effect_figure(track, claimed["figure"], demos.fps)
    rms, settled = summary["rms_m"], summary["pointed_frame"]
    print(f"episode {args.episode}, reach to {reach.location} of the 5 x 7 grid: {summary['frames']} frames tracked at "
          f"{summary['hz']:.0f} frames/s with {args.particles} particles: RMS shoulder, elbow, finger pooled "
          f"{100 * summary['rms_m_pooled']:.1f} cm (shoulder {100 * rms['shoulder']:.1f}, elbow "
          f"{100 * rms['elbow']:.1f}, finger {100 * rms['index_tip']:.1f}); pointed position "
          + ("never stays within 2 cm" if settled is None else f"within 2 cm from frame {settled}")
          + f", {100 * summary['pointed_error_end_m']:.1f} cm off at the end")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="hoap-actions",
        description="A humanoid that learns table-top manipulation by watching: run its demo, record simulated "
        "human demonstrations, discover action primitives in them, learn models of them, recognise them.",
        epilog="Mistakes in arguments or files end with one line on stderr and exit status 2.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="run a policy for N episodes and report its success rate")
    demo.add_argument("--policy", nargs="+", default=["random"], choices=["random", "scripted", "phmm", "straight"],
                      help="random: any env, joint_delta; scripted: the grasp-and-insert expert (true poses, straight "
                           "paths); phmm: grasp-and-insert from the overhead camera with paths synthesised by the "
                           "learned "
                           "models (both PegInsert-v0, ee_delta); straight: the hand driven straight at the target "
                           "(Reach-v1, ee_delta). Several run side by side on the same layouts (default: random)")
    demo.add_argument("--models", type=_path, help="models directory for the phmm policy (default: the shipped models)")
    demo.add_argument("--env", default="hoap_actions/PegInsert-v0", choices=ENV_IDS, help="environment id")
    _robot_option(demo)
    demo.add_argument("--episodes", type=_positive_int, default=10, help="layouts to run (default: %(default)s)")
    demo.add_argument("--seed", type=_seed, default=0, help="layouts are drawn from seeds S, S+1, ...")
    demo.add_argument("--workers", type=_positive_int, default=1, help="processes running episodes (same results)")
    _ray_option(demo, "episodes")
    demo.add_argument("--video", type=_path, help="write an mp4 of one of the first policy's episodes here (--film)")
    demo.add_argument("--film", type=_nonnegative_int, default=0, metavar="K",
                      help="which episode --video and --snapshot show: K for seed S+K (default: 0, the first)")
    demo.add_argument("--camera", default="closeup", choices=sorted(CAMERAS), help="the video's camera (default: "
                                                                                   "%(default)s)")
    demo.add_argument("--snapshot", type=_path, help="write a PNG of the first episode here: for the phmm policy the "
                                                      "overhead image with what it located and the paths it "
                                                      "synthesised")
    demo.add_argument("--json", type=_path, help="write per-episode results here (the same file whatever --workers; "
                                                  "wall times are printed, not written)")
    demo.add_argument("--overwrite", action="store_true", help="replace existing --video, --snapshot, --json files")
    demo.set_defaults(func=demo_command)

    imitate = sub.add_parser("imitate", help="the robot watches a demonstration through a camera and does the same "
                                             "to its own block (Imitate-v0), for N drawn demonstrations")
    imitate.add_argument("--from-markers", action="store_true",
                         help="read the demonstration from its recorded markers and block path instead of the camera "
                              "frames (the oracle of vision)")
    imitate.add_argument("--ceiling", action="store_true",
                         help="also run the execution ceiling (told the true action and effect) on the same episodes")
    imitate.add_argument("--robot", default="fixed_legs", choices=list(ROBOT_MODELS),
                         help="fixed_legs: bolted at the pelvis (default, the measured one); full: free-standing")
    imitate.add_argument("--episodes", type=_positive_int, help="drawn demonstrations (default: 10)")
    imitate.add_argument("--seed", type=_seed, default=0, help="demonstrations and layouts from seeds S, S+1, ...")
    imitate.add_argument("--demos", type=_path, help="replay this recording's demonstrations (.h5, from the record "
                                                     "command) instead of drawing them; layouts from seeds S, S+1, ...")
    imitate.add_argument("--episode", type=_nonnegative_int, nargs="+", metavar="K",
                         help="which episodes of --demos to replay (default: all of them)")
    imitate.add_argument("--level", default="mapped", choices=["mapped", "shifted"],
                         help="mapped: the robot's block starts where the person's did (default); shifted: elsewhere, "
                              "the same displacement and turn asked of it")
    imitate.add_argument("--demonstrator", choices=sorted(DEMONSTRATORS),
                         help="who demonstrates (default: drawn from each seed)")
    imitate.add_argument("--workers", type=_positive_int, default=1, help="processes running episodes (same results)")
    imitate.add_argument("--video", type=_path, help="write an mp4 of one episode of the robot here (--film)")
    imitate.add_argument("--film", type=_nonnegative_int, default=0, metavar="K",
                         help="which episode --video and --snapshot show: K for seed S+K (default: 0)")
    imitate.add_argument("--camera", default="closeup", choices=sorted(CAMERAS),
                         help="the video's camera (default: %(default)s)")
    imitate.add_argument("--snapshot", type=_path, help="write a PNG of that episode's first frame here")
    imitate.add_argument("--json", type=_path, help="write per-episode results here")
    imitate.add_argument("--overwrite", action="store_true", help="replace existing --video, --snapshot, --json files")
    imitate.set_defaults(func=imitate_command, ray=None)

    col = sub.add_parser("collect", help="run a policy and save its episodes as a Minari dataset (offline RL, "
                                         "imitation)")
    col.add_argument("--policy", required=True, choices=["random", "scripted", "phmm", "straight"],
                     help="as for demo: random (any env), scripted and phmm (PegInsert-v0), straight (Reach-v1)")
    col.add_argument("--env", default="hoap_actions/PegInsert-v0", choices=ENV_IDS, help="environment id")
    _robot_option(col)
    col.add_argument("--episodes", type=_positive_int, default=10, help="episodes to collect (default: %(default)s)")
    col.add_argument("--seed", type=_seed, default=0, help="episodes are the layouts of seeds S, S+1, ...")
    col.add_argument("--dataset-id", required=True, help="Minari id, e.g. hoap_actions/PegInsert/scripted-v0")
    col.add_argument("--models", type=_path, help="models directory for the phmm policy (default: the shipped models)")
    col.add_argument("--overwrite", action="store_true", help="replace an existing dataset of that id")
    col.set_defaults(func=_collect)

    rec = sub.add_parser("record", help="record simulated human demonstrations to an HDF5 dataset")
    rec.add_argument("--preset", required=True, choices=["paper", "approach-grid", "small"],
                     help="paper: 104 episodes of pushes, moves and turns, each approach, act, remove (the "
                          "paper's set); approach-grid: reaches to a grid of targets (Fig. 8); small: 4 episodes, "
                          "for trying")
    rec.add_argument("--out", type=_path, required=True, help="dataset file to write (.h5)")
    rec.add_argument("--seed", type=_seed, default=0, help="draws the episodes' placements and variability")
    rec.add_argument("--workers", type=_positive_int, default=1,
                     help="processes sharing the episodes; the file is the same byte for byte (default: 1)")
    _ray_option(rec, "recordings")
    rec.add_argument("--noise", type=_noise, default="none",
                     help="what a motion-capture system adds: none (the default: the simulation's exact poses, what "
                          "the shipped models learned from), mocap (0.7 mm marker and object jitter, 0.7 deg, markers "
                          "5 mm off the joint centres, an occlusion gap every 5 s per marker), or magnitudes such as "
                          "marker=1,object=1,angle=1,gaps=0.2,skin=5 (mm, mm, deg, gaps per marker per s, mm)")
    rec.add_argument("--demonstrator", default="reference", choices=[*DEMONSTRATORS, "random"],
                     help="who demonstrates: reference (the default: the 1.75 m demonstrator the shipped models "
                          "learned "
                          "from), short (1.60 m, leans in, elbow tucked), tall (1.88 m, brisk, elbow out), relaxed "
                          "(slow, "
                          "more trunk), or random (body and way of moving drawn from --seed)")
    rec.add_argument("--overwrite", action="store_true", help="replace an existing dataset at --out")
    rec.set_defaults(func=_record)

    disc = sub.add_parser("discover", help="discover action primitives in recorded demonstrations (paper's method)")
    disc.add_argument("--demos", type=_path, required=True, help="demonstrations dataset (.h5, from the record "
                                                                 "command)")
    disc.add_argument("--out", type=_path, required=True, help="directory for the model, classes, grammar, figures")
    disc.add_argument("--threshold", type=float, help="state-merge threshold, nats (default: the tuned one)")
    disc.add_argument("--spacing", type=float, help="arc length per Gaussian, m (default: the tuned one)")
    _merging_argument(disc)
    disc.add_argument("--overwrite", action="store_true", help="replace previous results in --out")
    disc.set_defaults(func=_discover)

    learn = sub.add_parser("learn", help="learn one parametric HMM per discovered primitive class, and the grammar")
    learn.add_argument("--demos", type=_path, nargs="+", required=True,
                       help="demonstrations datasets (.h5, from the record command)")
    learn.add_argument("--out", type=_path, required=True, help="models directory to write")
    learn.add_argument("--discovery", type=_path,
                       help="a folder the discover command wrote for the same --demos (default: run discovery here)")
    _merging_argument(learn)
    learn.add_argument("--overwrite", action="store_true", help="replace an existing models directory at --out")
    learn.set_defaults(func=_learn)

    rec = sub.add_parser("recognize", help="recognise every episode of a recording from the arm markers alone")
    rec.add_argument("--demos", type=_path, required=True,
                     help="a recording the models never saw (.h5, from the record command)")
    rec.add_argument("--models", type=_path, help="models directory (from the learn command; default: the models "
                     "shipped in the package, learned from ten paper-preset recordings)")
    rec.add_argument("--json", type=_path, help="write the figures here")
    rec.add_argument("--jobs", type=_positive_int, default=1, help="worker processes (the figures do not depend on it)")
    rec.add_argument("--oracle", action=argparse.BooleanOptionalAction, default=True,
                     help="also recognise the true segments with their cuts given (slower; default: on)")
    rec.add_argument("--overwrite", action="store_true", help="replace an existing --json file")
    rec.set_defaults(func=_recognize)

    track = sub.add_parser("track", help="track a recorded demonstration from the camera across the table "
                                         "(particle filter over action, effect and state)")
    track.add_argument("--demos", type=_path, required=True, help="a recording (.h5, from the record command)")
    track.add_argument("--episode", type=_nonnegative_int, default=0, help="which episode (default: 0)")
    track.add_argument("--models", type=_path, help="models directory (default: the shipped models)")
    track.add_argument("--particles", type=_positive_int, default=400, help="particles (default: %(default)s)")
    track.add_argument("--seed", type=_seed, default=0, help="the filter's random seed")
    track.add_argument("--json", type=_path, help="write the figures and the per-frame classes here")
    track.add_argument("--video", type=_path, help="write Fig. 12 as an mp4: edge image beside the camera image "
                                                   "with the estimated body and target")
    track.add_argument("--figure", type=_path, help="write Fig. 11 (the estimated effect over time) as a PNG")
    track.add_argument("--clutter", action="store_true", help="put unrelated objects on the table in the images")
    track.add_argument("--side-camera", action="store_true",
                       help="score a second view from the demonstrator's right as well (eq. 9; about half the frame "
                            "rate)")
    track.add_argument("--edges-only", action="store_true",
                       help="score poses on the edge image alone (the paper's eq. 8), without the silhouette that "
                            "background subtraction against the empty table gives (the default uses both)")
    track.add_argument("--noise", type=float, default=0.0,
                       help="Gaussian image noise, standard deviation as a share of full intensity (default: 0)")
    track.add_argument("--from-markers", action="store_true",
                       help="track from the recording's markers and block instead of the camera's images "
                            "(recognition from motion capture)")
    track.add_argument("--depth", action="store_true",
                       help="an RGB-D camera: each view's depth image, as a structured-light sensor reads it (noise "
                            "and steps growing with distance, holes at edges), weighs the pose estimate; default: "
                            "colour images only")
    track.add_argument("--pose-proposal", choices=["offsets", "turned", "hand"],
                       help="how particles pose the arm: offsets of every marker from the PHMM's mean, those offsets "
                            "with the hand turned about the wrist by two persistent angles, or the hand shifted and "
                            "the shoulder and elbow generated from it (with --posture, by that posture model); "
                            "default: offsets, turned with --from-markers, and hand with --grid-model (each won on "
                            "its validation recordings)")
    track.add_argument("--posture", type=_path,
                       help="a posture model file (PostureModel JSON) that poses the shoulder and elbow from the hand "
                            "(--pose-proposal hand)")
    track.add_argument("--lag", type=int, default=0,
                       help="also report fixed-lag smoothed estimates, each frame read this many frames later (the "
                            "demonstration is recorded: later frames tell which particles were right); default 0")
    track.add_argument("--refine", action="store_true",
                       help="refine the estimated pose (the smoothed one with --lag) against each frame's images by a "
                            "local search beyond the particles' poses (tracking.refinement.PoseRefiner; slower)")
    track.add_argument("--fingertip", action="store_true",
                       help="with --refine: also hold the index tip where the shipped fingertip detector finds it in "
                            "each view (vision.fingertip)")
    track.add_argument("--grid-model", choices=["linear", "thin-plate"],
                       help="the paper's experiment (Figs. 10-12) on an approach-grid recording: train the approach "
                            "PHMM on its 3 x 3 grid (thin-plate: with a posture model; a minute or more) and track "
                            "the reach of --episode, one of the 5 x 7 test grid's")
    track.add_argument("--overwrite", action="store_true", help="replace existing --json, --video, --figure files")
    track.set_defaults(func=_track)
    return parser


def _stop_on_sigterm(signum: int, frame: object) -> NoReturn:
    """SIGTERM unwinds like Ctrl-C, so claimed outputs remove their partial files."""
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s"
    )
    in_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _stop_on_sigterm) if in_main_thread else None
    try:
        return args.func(args)
    except HoapActionsError as error:  # a user's mistake or a bad file: say what, no traceback
        print(f"hoap-actions {args.command}: error: {error}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"hoap-actions {args.command}: interrupted; no partial output was kept", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as error:  # the machine, not the input: a full disk, a file that vanished, no permission
        where = f" ({error.filename})" if error.filename else ""
        print(f"hoap-actions {args.command}: error: {error.strerror or error}{where}; no partial output was kept",
              file=sys.stderr)
        return EXIT_USAGE
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous)


if __name__ == "__main__":
    sys.exit(main())
