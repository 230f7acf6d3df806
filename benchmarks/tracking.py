"""Tracking in action space from the demonstration camera (the paper's Figs. 10-12): accuracy and speed.

Protocol: :func:`hoap_actions.tracking.track_episode` on held-out ``paper`` recordings (the current
tracker's: seeds 310-312, declared in ``docs/experiments/tracking.md`` before they were recorded; validation: seed
300), episodes 0, 13, ..., 91 of each (every action of the preset), with the shipped models and the
filter's seed 0. Per recording: RMS error of shoulder, elbow and finger (index tip) and of all six
markers over whole episodes, the approach's estimated end at its last frame and the frames it took to
stay within 2 cm, the share of frames whose most probable class is the one discovery reads from the
block. The tracker scores edges and the silhouette (the default); the same episodes tracked on edges
alone (the paper's eq. 8) are reported beside it. Baselines: the arm held in its first pose (RMS), and
the most frequent class (frame agreement). Speed: frames per second of edge image, foreground mask and
filter with 100 / 400 / 1600 particles (320 x 240) and at 160 x 120 / 320 x 240 / 640 x 480 (400
particles), on one episode, rendering excluded, with the demonstration camera alone (``--side-camera``
runs' own frame rates are in their per-episode figures).

    python benchmarks/tracking.py [--seeds 310 311 312] [--episodes 0 13 26 ...] [--clutter --noise 0.03]
        [--side-camera] [--depth] [--lag 25] [--refine [--fingertip]]
    python benchmarks/tracking.py --speed-only --output results/tracking_speed.json
    python benchmarks/tracking.py --from-markers --output results/tracking_markers.json

``--from-markers`` tracks the same episodes from their recorded markers and the block's recorded centre
instead of images (:func:`hoap_actions.tracking.track_markers_episode`): the filter's own error, with
vision taken out.

Recordings are ``data/paper-s<seed>.h5``, recorded when missing. Writes ``results/tracking.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, write_json

EPISODES = tuple(range(0, 104, 13))
GOALS = {"rms_shoulder_elbow_finger_m": 0.02, "phi_error_m": 0.02, "frames_to_converge": 60, "frame_accuracy": 0.9,
         "hz_400_particles": 50.0}
PARTICLE_COUNTS = (100, 400, 1600)
IMAGE_SIZES = ((160, 120), (320, 240), (640, 480))


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("tracking.json", data=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=[310, 311, 312], help="held-out paper recordings")
    parser.add_argument("--episodes", type=int, nargs="+", default=list(EPISODES))
    parser.add_argument("--particles", type=int, default=400)
    parser.add_argument("--clutter", action="store_true", help="unrelated objects on the table")
    parser.add_argument("--noise", type=float, default=0.0, help="Gaussian image noise (share of full intensity)")
    parser.add_argument("--side-camera", action="store_true", help="a second view from the demonstrator's right (eq. "
                                                                   "9)")
    parser.add_argument("--depth", action="store_true",
                        help="an RGB-D camera: each view's depth image as a structured-light sensor reads it is scored "
                             "too (vision.depth_sensor.DepthSensor); the edges-only variant stays colour alone")
    parser.add_argument("--from-markers", action="store_true",
                        help="track from the recorded markers and block instead of images (no speed part)")
    parser.add_argument("--models", type=Path, default=None,
                        help="an action models directory to track with (default: the shipped models), e.g. an older "
                             "one for a paired comparison")
    parser.add_argument("--no-far-leaps", action="store_true",
                        help="from markers: no particle leaps anywhere ahead in its chain (the tracker before them)")
    parser.add_argument("--no-hand-turn", action="store_true",
                        help="from markers: no persistent turn of the hand in the particles' poses (the tracker "
                             "before it)")
    parser.add_argument("--no-pose-sharpening", action="store_true",
                        help="from markers: the pose estimate weighs particles by the filter's own weights (the "
                             "tracker before the sharpened estimate)")
    parser.add_argument("--no-object-place", action="store_true",
                        help="with --from-markers: score the block's motion only, not its place against each "
                             "particle's class (the tracker before the place term)")
    parser.add_argument("--refine", action="store_true",
                        help="refine the quoted estimate (the smoothed one with --lag) against its frame's images "
                             "(tracking.refinement.PoseRefiner; the edges-only variant is not refined)")
    parser.add_argument("--fingertip", action="store_true",
                        help="with --refine: the refinement also holds the index tip where the shipped fingertip "
                             "detector finds it in each view (vision.fingertip)")
    parser.add_argument("--lag", type=int, default=0,
                        help="also score fixed-lag smoothed estimates, this many frames behind (the same filter run)")
    parser.add_argument("--no-ablation", action="store_true",
                        help="leave out the edges-only variant and the speed part (a run whose question is another, "
                             "e.g. the refined estimate against the unrefined one of the same filter runs)")
    parser.add_argument("--speed-only", action="store_true",
                        help="measure frames per second only (on the first seed's last episode), e.g. on a quiet "
                             "machine")
    args = parser.parse_args(argv)
    from hoap_actions.tracking.smoothing import MAX_LAG
    if not 0 <= args.lag <= MAX_LAG:
        parser.error(f"--lag must be 0..{MAX_LAG} frames; got {args.lag}")
    if args.fingertip and not args.refine:
        parser.error("--fingertip goes with --refine (the detector's findings hold the refined pose)")
    if args.no_object_place and not args.from_markers:
        parser.error("--no-object-place goes with --from-markers (the camera's tracker has no place term)")
    if args.no_hand_turn and not args.from_markers:
        parser.error("--no-hand-turn goes with --from-markers (the camera's tracker poses no turn of the hand)")
    if args.no_pose_sharpening and not args.from_markers:
        parser.error("--no-pose-sharpening goes with --from-markers (the camera's estimate is not sharpened)")
    if args.no_far_leaps and not args.from_markers:
        parser.error("--no-far-leaps goes with --from-markers (the camera's tracker makes no far leaps)")
    if args.from_markers and (args.clutter or args.noise or args.side_camera or args.speed_only or args.depth
                              or args.refine):
        parser.error("--from-markers tracks without images; leave out --clutter, --noise, --side-camera, --depth, "
                     "--refine and --speed-only")
    return args


def recording_figures(models, demos, episodes, particles, clutter=False, noise=0.0, silhouette=True,
                      side_camera=False, from_markers=False, depth=False, lag=0, object_place=True,
                      far_leaps=True, hand_turn=True, pose_sharpening=True, refine=None) -> dict:
    """Per-episode summaries of one recording, and its pooled figures beside the baselines; ``refine``: the
    refinement's settings (None: no refinement)."""
    import numpy as np

    from hoap_actions.primitives.discovery.estimator import UNKNOWN
    from hoap_actions.tracking import SCORED_MARKERS, side_cameras, track_episode, track_markers_episode
    from hoap_actions.vision.depth_sensor import DepthSensor

    runs = []
    for index in episodes:
        if from_markers:
            result = track_markers_episode(models, demos, index, particles=particles, seed=0, lag=lag,
                                           **({} if object_place else {"object_place_m": None}),
                                           **({} if far_leaps else {"far_leap_share": 0.0}),
                                           **({} if hand_turn else {"pose_proposal": "offsets"}),
                                           **({} if pose_sharpening else {"pose_sharpening": 1.0}))
        else:
            result = track_episode(models, demos, index, particles=particles, seed=0, clutter=clutter,
                                   image_noise=noise, silhouette=silhouette, more_cameras=side_cameras(side_camera),
                                   depth_sensor=DepthSensor() if depth else None, lag=lag,
                                   refine=refine)
        summary = result.summary()
        held = np.linalg.norm(result.truth_markers[:1] - result.truth_markers, axis=2)
        summary["baseline_rms_m_all"] = float(np.sqrt(np.mean(held**2)))
        summary["episode"] = index
        runs.append(summary)
        print(f"  episode {index:3d} ({demos[index].ground_truth.action}): RMS all {100 * summary['rms_m_all']:.1f} cm "
              f"(held still {100 * summary['baseline_rms_m_all']:.1f}), classes {summary['frame_accuracy']:.0%}, "
              f"{summary['hz']:.0f} Hz" + (f"; smoothed {100 * summary['smoothed']['rms_m_all']:.1f} cm, "
                                         f"{summary['smoothed']['frame_accuracy']:.0%}" if lag else "")
              + ("" if summary.get("read_frame_accuracy") is None else
                 f"; read from the block {summary['read_frame_accuracy']:.0%}")
              + (f"; refined {100 * summary['refined']['rms_m_all']:.1f} cm" if refine is not None else ""), flush=True)
    truth = np.concatenate([r["truth"] for r in runs])
    known = truth != UNKNOWN
    majority = np.bincount(truth[known]).argmax()

    def scores(estimates: list[dict]) -> dict:
        recognized = np.concatenate([e["recognized"] for e in estimates])
        return {
            "rms_m": {m: float(np.sqrt(np.mean([e["rms_m"][m] ** 2 for e in estimates]))) for m in SCORED_MARKERS},
            "rms_m_all": float(np.sqrt(np.mean([e["rms_m_all"] ** 2 for e in estimates]))),
            "rms_m_pooled": float(np.sqrt(np.mean([e["rms_m_pooled"] ** 2 for e in estimates]))),
            "frame_accuracy": float(np.mean(recognized[known] == truth[known])),
        }
    pooled = {
        **scores(runs),
        "baseline_rms_m_all": float(np.sqrt(np.mean([r["baseline_rms_m_all"] ** 2 for r in runs]))),
        "phi_error_m": float(np.median([r["phi_error_m"] for r in runs if r["phi_error_m"] is not None])),
        "approaches_converged": sum(r["approaches_converged"] for r in runs),
        "approaches": sum(r["approaches"] for r in runs),
        "kind_accuracy": float(np.average([r["kind_accuracy"] for r in runs],  # each episode's share of known frames
                                          weights=[np.sum(np.asarray(r["truth"]) != UNKNOWN) for r in runs])),
        "baseline_frame_accuracy": float(np.mean(truth[known] == majority)),
        "hz": float(np.median([r["hz"] for r in runs])),
    }
    if all("approaches_read_from_task" in r for r in runs):  # approach ends read from the task (approach_goal.py)
        pooled["approaches_read_from_task"] = sum(r["approaches_read_from_task"] for r in runs)
    if all("read_classes" in r for r in runs):  # manipulations read again from the block (tracking/chain_reading.py)
        read = np.concatenate([r["read_classes"] for r in runs])
        pooled["read_frame_accuracy"] = float(np.mean(read[known] == truth[known]))
    found = [r["frames_to_converge"] for r in runs if r["frames_to_converge"] is not None]
    pooled["frames_to_converge_median"] = float(np.median(found)) if found else None
    if refine is not None:  # the same estimates refined against their frames (their classes are the estimates')
        refined = [{**r["refined"], "recognized": (r["smoothed"] if lag else r)["recognized"]} for r in runs]
        pooled["refined"] = {**scores(refined), "hz": float(np.median([r["refined"]["hz"] for r in runs]))}
    if lag:
        pooled["smoothed"] = {"lag": lag, **scores([r["smoothed"] for r in runs])}
        for r in runs:
            del r["smoothed"]["recognized"]
    return {"pooled": pooled,
            "episodes": [{k: v for k, v in r.items() if k not in ("recognized", "truth", "read_classes")}
                         for r in runs]}


def speed(models, demos, episode) -> dict:
    """Frames per second (edge image + filter) against particles and image size."""
    from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA
    from hoap_actions.tracking import track_episode

    out = {"particles": {}, "image_size_400_particles": {}}
    for n in PARTICLE_COUNTS:
        out["particles"][n] = track_episode(models, demos, episode, particles=n, seed=0).summary()["hz"]
    for width, height in IMAGE_SIZES:
        camera = dataclasses.replace(DEMONSTRATOR_CAMERA, width=width, height=height)
        out["image_size_400_particles"][f"{width}x{height}"] = track_episode(
            models, demos, episode, particles=400, seed=0, camera=camera).summary()["hz"]
    print(f"  speed: {out}", flush=True)
    return out


def share_found(found: int, approaches: int) -> dict:
    """Approaches whose estimated end came within 2 cm: count, share and Wilson 95 % interval."""
    from hoap_actions.apps.episodes import wilson_interval

    return {"found": found, "approaches": approaches, "share": found / approaches if approaches else None,
            "wilson95": list(wilson_interval(found, approaches)) if approaches else None}


def summarise(per_recording: dict) -> dict:
    """Mean and 95 % interval over the recordings of each pooled figure (the classes read again from the block's
    displacement among them; the smoothed and refined estimates' when the runs made them); the approaches whose
    estimated end came within 2 cm, the filter's and read from the task, over all recordings, with their Wilson
    intervals."""
    pooled = [r["pooled"] for r in per_recording.values()]
    summary = {key: spread([p[key] for p in pooled]) for key in
               ("rms_m_all", "rms_m_pooled", "baseline_rms_m_all", "phi_error_m", "frame_accuracy", "kind_accuracy",
                "baseline_frame_accuracy", "hz")}
    if all("read_frame_accuracy" in p for p in pooled):
        summary["read_frame_accuracy"] = spread([p["read_frame_accuracy"] for p in pooled])
    for marker in pooled[0]["rms_m"]:
        summary[f"rms_m_{marker}"] = spread([p["rms_m"][marker] for p in pooled])
    found, approaches = sum(p["approaches_converged"] for p in pooled), sum(p["approaches"] for p in pooled)
    summary["approach_end_within_2cm"] = share_found(found, approaches)
    if all("approaches_read_from_task" in p for p in pooled):  # the same ends read from the task that followed
        summary["approach_end_read_from_task_within_2cm"] = share_found(
            sum(p["approaches_read_from_task"] for p in pooled), approaches)
    if "smoothed" in pooled[0]:  # the fixed-lag estimates of the same filter runs
        for key in ("rms_m_all", "rms_m_pooled", "frame_accuracy"):
            summary[f"smoothed_{key}"] = spread([p["smoothed"][key] for p in pooled])
        for marker in pooled[0]["smoothed"]["rms_m"]:
            summary[f"smoothed_rms_m_{marker}"] = spread([p["smoothed"]["rms_m"][marker] for p in pooled])
    if "refined" in pooled[0]:  # the same estimates refined against their frames (tracking.refinement)
        for key in ("rms_m_all", "rms_m_pooled", "hz"):
            summary[f"refined_{key}"] = spread([p["refined"][key] for p in pooled])
        for marker in pooled[0]["refined"]["rms_m"]:
            summary[f"refined_rms_m_{marker}"] = spread([p["refined"]["rms_m"][marker] for p in pooled])
    return summary


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import load_default_models
    from hoap_actions.primitives.models.action_models import ActionModels

    started = time.perf_counter()
    models = load_default_models() if args.models is None else ActionModels.load(args.models)
    if args.speed_only:
        result = {"protocol": {"seed": args.seeds[0], "episode": args.episodes[-1], "filter_seed": 0},
                  "speed": speed(models, load_demonstrations(ensure_recording("paper", args.seeds[0], args.data)),
                                 args.episodes[-1])}
        result["environment"] = {**numeric_environment(None), "runtime_s": round(time.perf_counter() - started, 1)}
        write_json(args.output, result)
        return result
    per_recording, edges_only = {}, {}
    variants = ((("markers and block", per_recording, True),) if args.from_markers else
                (("edges and silhouette", per_recording, True),) if args.no_ablation else
                (("edges and silhouette", per_recording, True), ("edges only", edges_only, False)))
    refine = None
    if args.refine:
        from hoap_actions.vision.fingertip import shipped_fingertip_detector
        refine = {"fingertip": shipped_fingertip_detector()} if args.fingertip else {}
    for seed in args.seeds:
        demos = load_demonstrations(ensure_recording("paper", seed, args.data))
        for cues, store, silhouette in variants:
            print(f"paper seed {seed}, {cues}:", flush=True)
            store[seed] = recording_figures(models, demos, args.episodes, args.particles, args.clutter, args.noise,
                                            silhouette, args.side_camera, args.from_markers,
                                            args.depth and silhouette, args.lag, not args.no_object_place,
                                            not args.no_far_leaps, not args.no_hand_turn,
                                            not args.no_pose_sharpening, refine if silhouette else None)
    summaries = {title: summarise(store) for title, store, _ in variants}
    result = {
        "protocol": {"seeds": args.seeds, "episodes": args.episodes, "particles": args.particles,
                     "clutter": args.clutter, "image_noise": args.noise, "side_camera": args.side_camera,
                     "from_markers": args.from_markers, "depth": args.depth,
                     "depth_weighs": "pose" if args.depth else None, "lag": args.lag, "refine": args.refine,
                     "fingertip": args.fingertip,
                     "object_place": args.from_markers and not args.no_object_place,
                     "far_leaps": args.from_markers and not args.no_far_leaps,
                     "hand_turn": args.from_markers and not args.no_hand_turn,
                     "pose_sharpening": args.from_markers and not args.no_pose_sharpening,
                     "models": "shipped default models" if args.models is None else str(args.models),
                     "filter_seed": 0},
        "goals": GOALS, "paper": {"rms_m": 0.033, "hz": 10, "particles": 400, "frames_to_converge": 60},
        "summary": summaries[variants[0][0]], "per_recording": per_recording,
    }
    if not (args.from_markers or args.no_ablation):
        result.update(summary_edges_only=summaries["edges only"], per_recording_edges_only=edges_only,
                      speed=speed(models, load_demonstrations(ensure_recording("paper", args.seeds[0], args.data)),
                                  args.episodes[-1]))
    for title, figures in summaries.items():
        print(title)
        for key, s in figures.items():
            if "mean" in s:
                print(f"{key:>28}: mean {s['mean']:.4g} [{s['ci95'][0]:.4g}, {s['ci95'][1]:.4g}]")
            else:
                print(f"{key:>28}: {s}")
    result["environment"] = {**numeric_environment(None), "runtime_s": round(time.perf_counter() - started, 1)}
    write_json(args.output, result)
    return result


if __name__ == "__main__":
    main()
