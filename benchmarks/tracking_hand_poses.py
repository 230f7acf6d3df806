"""Poses generated from the hand against the previous proposal, paired, on whole ``paper`` demonstrations.

Protocol: :func:`hoap_actions.tracking.track_episode` (or, ``--from-markers``,
:func:`~hoap_actions.tracking.track_markers_episode`) on episodes 0, 13, ..., 91 of each recording, the shipped
models, 400 particles, filter seed 0, edges and silhouette and the block located in the image, once per pose
proposal on the same rendered frames and seeds: ``offsets`` (every marker coordinate on its own, the previous
design), ``hand`` (the hand shifted, shoulder and elbow from the PHMM state given the hand: the shipped
models' diagonal covariances give the state's mean) and ``hand+posture`` (shoulder and elbow from a
:class:`~hoap_actions.primitives.hmm.posture.PostureModel` of every frame of a training recording of the
shipped models, ``paper`` seed 0, :func:`~hoap_actions.tracking.tracking_models.posture_from_recording`).
Figures per proposal and recording: RMS per marker, over all markers and over shoulder, elbow and finger
pooled; frames whose class agrees with discovery's; approach ends within 2 cm; frames per second.

    python benchmarks/tracking_hand_poses.py [--seeds 300] [--episodes 0 13 ...] [--from-markers]

Seed 300 is the tracker's validation recording (``docs/experiments/tracking.md``). Writes
``results/tracking_hand_poses.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, use_blas_threads, write_json

EPISODES = tuple(range(0, 104, 13))
PROPOSALS = ("offsets", "hand", "hand+posture")
POSTURE_TRAINING_SEED = 0  # a training recording of the shipped models (models/shipped.py TRAINING_SEEDS)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("tracking_hand_poses.json", data=True, threads=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=[300], help="paper recordings (300: validation)")
    parser.add_argument("--episodes", type=int, nargs="+", default=list(EPISODES))
    parser.add_argument("--particles", type=int, default=400)
    parser.add_argument("--proposals", nargs="+", default=list(PROPOSALS), choices=PROPOSALS)
    parser.add_argument("--from-markers", action="store_true", help="track from the recorded markers and block")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    use_blas_threads(args.threads)
    import numpy as np

    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import load_default_models
    from hoap_actions.primitives.discovery.estimator import UNKNOWN
    from hoap_actions.tracking import SCORED_MARKERS, track_episode, track_markers_episode
    from hoap_actions.tracking.tracking_models import posture_from_recording

    started = time.perf_counter()
    models = load_default_models()
    posture = None
    if "hand+posture" in args.proposals:
        posture = posture_from_recording(load_demonstrations(ensure_recording("paper", POSTURE_TRAINING_SEED,
                                                                              args.data)))
    per_recording = {}
    for seed in args.seeds:
        demos = load_demonstrations(ensure_recording("paper", seed, args.data))
        per_recording[seed] = {}
        for proposal in args.proposals:
            kind, body = ("hand", posture) if proposal == "hand+posture" else (proposal, None)
            runs = []
            for index in args.episodes:
                if args.from_markers:
                    result = track_markers_episode(models, demos, index, particles=args.particles, seed=0,
                                                   pose_proposal=kind, posture=body)
                else:
                    result = track_episode(models, demos, index, particles=args.particles, seed=0,
                                           pose_proposal=kind, posture=body)
                runs.append(result.summary())
                r = runs[-1]
                print(f"paper seed {seed}, episode {index}, {proposal}: all {100 * r['rms_m_all']:.1f} cm, pooled "
                      f"{100 * r['rms_m_pooled']:.1f} (shoulder {100 * r['rms_m']['shoulder']:.1f}, elbow "
                      f"{100 * r['rms_m']['elbow']:.1f}, finger {100 * r['rms_m']['index_tip']:.1f}), classes "
                      f"{r['frame_accuracy']:.0%}, {r['hz']:.0f} frames/s", flush=True)
            frames = np.array([r["frames"] for r in runs], float)

            def pooled(values: list[float], frames=frames) -> float:
                return float(np.sqrt(np.sum(frames * np.square(values)) / frames.sum()))

            truth = np.concatenate([r["truth"] for r in runs])
            recognized = np.concatenate([r["recognized"] for r in runs])
            known = truth != UNKNOWN
            per_recording[seed][proposal] = {
                "rms_m": {m: pooled([r["rms_m"][m] for r in runs]) for m in SCORED_MARKERS},
                "rms_m_pooled": pooled([r["rms_m_pooled"] for r in runs]),
                "rms_m_all": pooled([r["rms_m_all"] for r in runs]),
                "frame_accuracy": float(np.mean(recognized[known] == truth[known])),
                "approaches_converged": sum(r["approaches_converged"] for r in runs),
                "approaches": sum(r["approaches"] for r in runs),
                "hz": float(np.median([r["hz"] for r in runs])),
                "episodes": [{k: v for k, v in r.items() if k not in ("recognized", "truth")} for r in runs]}
    summary = {}
    for proposal in args.proposals:
        figures = [per_recording[seed][proposal] for seed in args.seeds]
        summary[proposal] = {key: spread([f[key] for f in figures])
                             for key in ("rms_m_pooled", "rms_m_all", "frame_accuracy", "hz")}
        summary[proposal].update({f"rms_m_{m}": spread([f["rms_m"][m] for f in figures]) for m in SCORED_MARKERS})
        s = summary[proposal]
        print(f"{proposal}: all {100 * s['rms_m_all']['mean']:.2f} cm, pooled {100 * s['rms_m_pooled']['mean']:.2f}, "
              f"shoulder / elbow / finger {100 * s['rms_m_shoulder']['mean']:.2f} / "
              f"{100 * s['rms_m_elbow']['mean']:.2f} / {100 * s['rms_m_index_tip']['mean']:.2f} cm, "
              f"classes {100 * s['frame_accuracy']['mean']:.1f} %")
    result = {"protocol": {"seeds": args.seeds, "episodes": args.episodes, "particles": args.particles,
                           "filter_seed": 0, "proposals": args.proposals, "from_markers": args.from_markers,
                           "models": "shipped default models",
                           "posture": f"posture_from_recording(paper seed {POSTURE_TRAINING_SEED})"},
              "posture_alpha": None if posture is None else posture.alpha,
              "summary": summary, "per_recording": per_recording,
              "environment": {**numeric_environment(args.threads),
                              "runtime_s": round(time.perf_counter() - started, 1),
                              "note": "frames per second on a shared 2-core machine, other jobs running"}}
    write_json(args.output, result)
    return result


if __name__ == "__main__":
    main()
