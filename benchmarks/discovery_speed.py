"""Speed of primitive discovery on the ``paper`` preset and on 4x and 16x as many demonstrations.

The larger workloads replicate every episode with small independent noise on the object pose (0.2 mm
on the position, 0.2 mm of arc on the rotation: marker-like jitter), so replicas are alike but not
identical and go through every stage as new data would. For each scale: the wall and CPU time of
``fit`` (best of ``--repeats``), the model size, and where the time goes, from a cProfile run:
cutting the trajectories into pieces, merging states into the joint HMM (eq. 1-3), the Gaussian
densities and the Viterbi decoding, the LCS step, and building segments and classes. At 1x the
sparse Viterbi used by discovery is also timed against the dense ``hmm_math.viterbi`` on the
same joint HMM.

    python benchmarks/discovery_speed.py [--scales 1 4 16] [--repeats 3] [--threads 1]

BLAS threads default to 1 (set before numpy loads): on a shared 2-core machine multithreaded BLAS
on these small products is slower and erratic. The recording is ``paper-s<seed>.h5`` in ``--data``
(``data/`` under the checkout), recorded there when missing. Writes ``results/discovery_speed.json``;
earlier figures are in ``docs/experiments/speed.md``.
"""

from __future__ import annotations

import argparse
import cProfile
import logging
import os
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, use_blas_threads, write_json

GOAL_SECONDS = 30.0  # the paper preset on 2 cores
POSITION_NOISE = 2e-4  # m
STAGES = {  # report name: (module file, function names whose cumulative time it is)
    "cut into rest / motion pieces": ("discovery.py", ("_prepare",)),
    "state merging (KL, eqs. 1-3)": ("discovery.py", ("_build_joint_hmm",)),
    "Gaussian densities": ("hmm_math.py", ("log_gaussian_density",)),
    "Viterbi (sparse)": ("sparse_viterbi.py", ("sparse_viterbi",)),
    "LCS (find_primitives)": ("substrings.py", ("find_primitives",)),
    "segments and classes": ("discovery.py", ("_assign_primitives", "_make_classes")),
}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("discovery_speed.json", data=True, threads=True)])
    parser.add_argument("--scales", type=int, nargs="+", default=[1, 4, 16], help="multiples of the paper preset")
    parser.add_argument("--repeats", type=int, default=3, help="timed fits per scale (best reported)")
    parser.add_argument("--seed", type=int, default=0, help="paper-preset recording")
    parser.add_argument("--rerecord-stale", action="store_true",
                        help="record again the recording if older than the demonstrator's sources")
    return parser.parse_args(argv)


def replicate(objects: list, hands: list, scale: int, rotation_radius: float) -> tuple[list, list]:
    """``scale`` copies of the demonstrations; every copy after the first with independent pose noise."""
    import numpy as np

    rng = np.random.default_rng(0)
    noise = np.array([POSITION_NOISE] * 3 + [POSITION_NOISE / rotation_radius] * 3)
    out = list(objects)
    for _ in range(scale - 1):
        out += [o + noise * rng.standard_normal(o.shape) for o in objects]
    return out, list(hands) * scale


def stage_times(profile: cProfile.Profile) -> dict[str, float]:
    """Cumulative seconds of each stage in :data:`STAGES`, from a profile of one ``fit``."""
    stats = pstats.Stats(profile).stats  # (file, line, name) -> (calls, primitive calls, tottime, cumtime, callers)
    out = {}
    for stage, (filename, names) in STAGES.items():
        out[stage] = sum(v[3] for (f, _, name), v in stats.items() if f.endswith(filename) and name in names)
    return out


def time_fit(objects: list, hands: list, repeats: int) -> dict:
    """Best wall / CPU time of ``fit`` over ``repeats``, the fitted model's size, and a profiled breakdown."""
    import numpy as np

    from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery

    X, lengths, H = np.concatenate(objects), [len(o) for o in objects], np.concatenate(hands)
    walls, cpus = [], []
    for _ in range(repeats):
        model = PrimitiveDiscovery()
        started, cpu = time.perf_counter(), time.process_time()
        model.fit(X, lengths, H)
        walls.append(time.perf_counter() - started)
        cpus.append(time.process_time() - cpu)
    profile = cProfile.Profile()
    profile.enable()
    started = time.perf_counter()
    PrimitiveDiscovery().fit(X, lengths, H)
    profiled = time.perf_counter() - started
    profile.disable()
    stages = stage_times(profile)
    stages["other"] = max(0.0, profiled - sum(stages.values()))
    return {
        "n_demonstrations": len(objects),
        "n_frames": int(sum(len(o) for o in objects)),
        "fit_seconds": min(walls),
        "fit_cpu_seconds": min(cpus),
        "n_joint_states": len(model.joint_means_),
        "n_primitives": len(model.primitives_),
        "profiled_seconds": profiled,
        "stage_fraction": {k: v / profiled for k, v in stages.items()},
        "stage_seconds_profiled": stages,
        "model": model,
    }


def viterbi_comparison(model, objects: list) -> dict:
    """Dense ``hmm_math.viterbi`` against the sparse one on the fitted joint HMM and all frames."""
    import numpy as np

    from hoap_actions.primitives.hmm import hmm_math
    from hoap_actions.primitives.hmm.sparse_viterbi import sparse_viterbi

    relative = model.relative_trajectories(np.concatenate(objects), [len(o) for o in objects])
    X, lengths = np.concatenate(relative), np.array([len(r) for r in relative])
    log_frameprob = hmm_math.log_gaussian_density(X, model.joint_means_, model.joint_covars_)
    with np.errstate(divide="ignore"):
        log_start, log_trans = np.log(model.startprob_), np.log(model.transmat_)
    timings = {}
    for name, viterbi in (("dense", hmm_math.viterbi), ("sparse", sparse_viterbi)):
        started = time.perf_counter()
        _, path = viterbi(log_start, log_trans, log_frameprob, lengths)
        timings[name] = time.perf_counter() - started
        timings[f"{name}_path"] = path
    same = bool(np.array_equal(timings.pop("dense_path"), timings.pop("sparse_path")))
    return {"dense_seconds": timings["dense"], "sparse_seconds": timings["sparse"], "same_paths": same,
            "n_states": len(model.joint_means_), "n_allowed_transitions": int(np.isfinite(log_trans).sum())}


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    use_blas_threads(args.threads)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    from _discovery_data import paper_recording, sources_digest

    from hoap_actions.demonstration.datasets import load_demonstrations

    path = paper_recording(args.seed, args.data, args.rerecord_stale)
    demos = load_demonstrations(path)
    objects, hands = [e.O for e in demos], [e.H.reshape(e.T, -1) for e in demos]
    print(f"{path}: {len(demos)} demonstrations; BLAS threads {args.threads}; {os.cpu_count()} CPUs, "
          f"load average {os.getloadavg()[0]:.1f}")
    rows, comparison = [], None
    for scale in args.scales:
        data_o, data_h = replicate(objects, hands, scale, rotation_radius=0.05)
        row = time_fit(data_o, data_h, args.repeats if scale < 16 else 1)
        model = row.pop("model")
        if scale == 1:
            comparison = viterbi_comparison(model, data_o)
        row["scale"] = scale
        rows.append(row)
        print(f"\n{scale:>2}x: {row['n_demonstrations']} demonstrations, {row['n_frames']} frames -> "
              f"{row['n_joint_states']} joint states, {row['n_primitives']} primitives; fit {row['fit_seconds']:.2f} s "
              f"wall, {row['fit_cpu_seconds']:.2f} s CPU")
        for stage, fraction in row["stage_fraction"].items():
            print(f"      {stage:<32} {100 * fraction:5.1f} %  ({row['stage_seconds_profiled'][stage]:.2f} s profiled)")
    if comparison:
        print(f"\nViterbi at 1x on the joint HMM ({comparison['n_states']} states, "
              f"{comparison['n_allowed_transitions']} allowed transitions): dense {comparison['dense_seconds']:.2f} s, "
              f"sparse {comparison['sparse_seconds']:.2f} s, same paths: {comparison['same_paths']}")
    goal_met = rows[0]["scale"] == 1 and rows[0]["fit_seconds"] < GOAL_SECONDS
    print(f"goal: the paper preset in < {GOAL_SECONDS:.0f} s on 2 cores: {'met' if goal_met else 'NOT met'}")
    document = {
        "benchmark": "discovery_speed",
        "demonstrator_sources_sha256_16": sources_digest(),
        "dataset": str(path),
        "replica_noise": {"position_m": POSITION_NOISE, "rotation_arc_m": POSITION_NOISE},
        "goal_seconds": GOAL_SECONDS,
        "goal_met": goal_met,
        "scales": rows,
        "viterbi_1x": comparison,
        "environment": numeric_environment(args.threads),
    }
    write_json(args.output, document)
    return document


if __name__ == "__main__":
    main()
