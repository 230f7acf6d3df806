"""The paper's tracking experiment (Figs. 10-12): reaches to the 5 x 7 test locations of ``approach-grid``
recordings, tracked from one camera across the table with the approach PHMM trained on the recording's own
3 x 3 grid (it never saw a test reach).

Protocol (:mod:`hoap_actions.tracking.grid_experiment`, declared in ``docs/experiments/tracking.md`` before
any run): per recording, the approach PHMM linear (the paper's) and thin-plate with a posture model of the
training grid's frames; the first repetition at each of the 35 test locations; 400 particles, filter seed
0; each reach rendered once and tracked by every variant (models x pose proposal x cues: the previous
proposal ``offsets`` beside poses generated from the hand ``hand``; ``default`` cues, edges, silhouette and
the block located in the image, beside the paper's eq. 8 alone, ``edges``). Figures per variant: RMS over
every frame of shoulder, elbow and finger pooled (the paper's 3.3 cm) and per marker, the share of reaches
whose pointed position (the red dot) stays within 2 cm from frame 60 on, frames per second (edge image,
masks, block, filter; rendering excluded). Baselines: the arm held at its first pose; the pointed position
put at the training effects' mean. Mean and 95 % interval over the recordings; Wilson interval of the
pooled share. Fig. 11 and Fig. 12 of the first recording's reach to location (1, 5), beside the JSON.

    python benchmarks/tracking_paper_experiment.py [--seeds 41 42 43] [--every 1] [--variants ...]

Seeds: ``approach-grid`` 40 is validation; 41, 42, 43 held-out. Recordings are
``data/approach-grid-s<seed>.h5``, recorded when missing. Writes ``results/tracking_paper_experiment.json``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, ensure_recording, numeric_environment, spread, use_blas_threads, write_json

MODELS = {"linear": ("linear", False), "thin-plate+posture": ("thin-plate", True)}
VARIANTS = (("linear", "offsets", "default"), ("linear", "hand", "default"),
            ("thin-plate+posture", "offsets", "default"), ("thin-plate+posture", "hand", "default"),
            ("linear", "hand", "edges"), ("thin-plate+posture", "hand", "edges"))
FIGURE_VARIANT = ("thin-plate+posture", "hand", "default")
FIGURE_LOCATION = (1, 5)  # off the centre and between the training grid's columns: the effect must move
PICTURE_SHARES = (0.25, 0.5, 0.75, 1.0)  # Fig. 12's frames, as shares of the reach
GOALS = {"rms_m_pooled": 0.02, "pointed_by_frame_share": 0.8, "hz": 50.0}
PAPER = {"rms_m_pooled": 0.033, "pointed_frame": 60, "particles": 400, "hz": 10}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("tracking_paper_experiment.json", data=True, threads=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=[41, 42, 43],
                        help="approach-grid recordings (default: the held-out %(default)s; 40 is validation)")
    parser.add_argument("--every", type=int, default=1, help="track every n-th test location only (quick looks)")
    parser.add_argument("--particles", type=int, default=400)
    parser.add_argument("--variants", nargs="+", default=None,
                        help="variants as models/proposal/cues, e.g. linear/hand/default (default: all of VARIANTS)")
    args = parser.parse_args(argv)
    if args.variants:
        args.variants = [tuple(v.split("/")) for v in args.variants]
        if any(len(v) != 3 or v[0] not in MODELS for v in args.variants):
            parser.error(f"a variant is models/proposal/cues with models in {sorted(MODELS)}")
    else:
        args.variants = list(VARIANTS)
    return args


def figures(track, out: Path, fps: float) -> dict:
    """Fig. 11 and Fig. 12 of ``track`` as PNGs beside ``out``; their paths."""
    import imageio.v3 as iio
    import numpy as np

    from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA
    from hoap_actions.tracking.grid_experiment import reach_effect_figure, reach_picture

    fig11, fig12 = out.with_name(out.stem + "_fig11.png"), out.with_name(out.stem + "_fig12.png")
    reach_effect_figure(track, fig11, fps)
    frames = [min(len(track.frames) - 1, int(share * len(track.frames))) for share in PICTURE_SHARES]
    iio.imwrite(fig12, np.vstack([reach_picture(track, DEMONSTRATOR_CAMERA, t) for t in frames]))
    return {"fig11": str(fig11), "fig12": str(fig12), "fig12_frames": frames, "episode": track.reach.episode}


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    use_blas_threads(args.threads)
    from hoap_actions.apps.episodes import wilson_interval
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.tracking.grid_experiment import (
        grid_reaches,
        grid_tracking_models,
        pool_reaches,
        run_grid_experiment,
        variant_name,
    )

    started = time.perf_counter()
    names = [variant_name(v) for v in args.variants]
    per_recording, drawn = {}, None
    for seed in args.seeds:
        demos = load_demonstrations(ensure_recording("approach-grid", seed, args.data))
        needed = sorted({v[0] for v in args.variants})
        fitted = time.perf_counter()
        models = {name: grid_tracking_models(demos, MODELS[name][0], posture=MODELS[name][1]) for name in needed}
        fit_s = time.perf_counter() - fitted
        reaches = [r for r in grid_reaches(demos) if r.repetition == 0][::args.every]
        keep = None
        if drawn is None and FIGURE_VARIANT in args.variants:
            centre = [r for r in reaches if r.location == FIGURE_LOCATION] or reaches
            keep = (centre[0].episode, variant_name(FIGURE_VARIANT))
        print(f"approach-grid seed {seed}: {len(reaches)} reaches, models fitted in {fit_s:.0f} s", flush=True)

        def report(reach, name, s):
            print(f"  episode {reach.episode} {reach.location} {name}: pooled {100 * s['rms_m_pooled']:.2f} cm "
                  f"(shoulder {100 * s['rms_m']['shoulder']:.1f}, elbow {100 * s['rms_m']['elbow']:.1f}, finger "
                  f"{100 * s['rms_m']['index_tip']:.1f}), pointed within 2 cm from frame {s['pointed_frame']} of "
                  f"{s['frames']}, {s['hz']:.0f} frames/s", flush=True)

        results, baselines, kept = run_grid_experiment(demos, models, args.variants, reaches, args.particles,
                                                       keep=keep, progress=report)
        if kept is not None:
            drawn = figures(kept, args.output, demos.fps)
        per_recording[seed] = {
            "variants": {name: {"pooled": pool_reaches(results[name]), "reaches": results[name]} for name in names},
            "baselines": baselines, "models_fit_s": fit_s,
            "posture_alpha": models["thin-plate+posture"].posture.alpha if "thin-plate+posture" in models else None}
    summary = {}
    for name in names:
        pooled = [r["variants"][name]["pooled"] for r in per_recording.values()]
        early = sum(p["pointed_by_frame_count"] for p in pooled)
        total = sum(p["reaches"] for p in pooled)
        summary[name] = {"rms_m_pooled": spread([p["rms_m_pooled"] for p in pooled]),
                         **{f"rms_m_{m}": spread([p["rms_m"][m] for p in pooled]) for m in pooled[0]["rms_m"]},
                         "rms_m_all": spread([p["rms_m_all"] for p in pooled]),
                         "pointed_by_frame_share": spread([p["pointed_by_frame_share"] for p in pooled]),
                         "pointed_by_frame_pooled": {"count": early, "reaches": total, "rate": early / total,
                                                     "wilson95": list(wilson_interval(early, total))},
                         "pointed_frame_median": spread([p["pointed_frame_median"] for p in pooled
                                                         if p["pointed_frame_median"] is not None]),
                         "never_settled": sum(p["never_settled"] for p in pooled),
                         "hz": spread([p["hz"] for p in pooled])}
        s = summary[name]
        print(f"{name}: pooled {100 * s['rms_m_pooled']['mean']:.2f} cm [{100 * s['rms_m_pooled']['ci95'][0]:.2f}, "
              f"{100 * s['rms_m_pooled']['ci95'][1]:.2f}], shoulder / elbow / finger "
              f"{100 * s['rms_m_shoulder']['mean']:.2f} / {100 * s['rms_m_elbow']['mean']:.2f} / "
              f"{100 * s['rms_m_index_tip']['mean']:.2f} cm; pointed within 2 cm by frame 60 in {early} of {total}; "
              f"{s['hz']['mean']:.0f} frames/s")
    baselines = [b for r in per_recording.values() for b in r["baselines"]]
    import numpy as np

    result = {
        "protocol": {"seeds": args.seeds, "reaches": "first repetition at each 5x7 test location"
                     + (f", every {args.every}th" if args.every > 1 else ""), "particles": args.particles,
                     "filter_seed": 0, "variants": names, "training": "each recording's own 3x3 grid reaches",
                     "cues": {"default": "edges, silhouette, block located in the image", "edges": "edge image alone"}},
        "goals": GOALS, "paper": PAPER, "summary": summary,
        "baselines": {"held_still_rms_m_pooled": float(np.sqrt(np.mean([b["held_still_rms_m_pooled"] ** 2
                                                                          for b in baselines]))),
                      "pointed_at_training_mean_m_median": float(np.median([b["pointed_at_training_mean_m"]
                                                                            for b in baselines]))},
        "figures": drawn, "per_recording": per_recording,
        "environment": {**numeric_environment(args.threads), "runtime_s": round(time.perf_counter() - started, 1),
                        "note": "frames per second on a shared 2-core machine, other jobs running"},
    }
    write_json(args.output, result)
    return result


if __name__ == "__main__":
    main()
