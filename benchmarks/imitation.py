"""Imitation on ``Imitate-v0``: the robot reading the demonstration's recorded markers and block path with
its action models (``"imitation-markers"``, the oracle of vision), the robot told the true action and
effect (``"imitation-oracle"``, the execution ceiling) and the robot doing nothing (``"nothing"``), on the
same episodes, in one run.

Held-out episodes, declared in ``docs/experiments/imitation.md`` before the first run: seeds 91000-91199
(the execution ceiling, ``level="mapped"``, once per robot), 93000-93199 (from markers). Choices were made
on the validation seeds 90000-90099.

    python benchmarks/imitation.py [--robot fixed_legs|full] [--seeds 91000 91200] [--policies oracle nothing]

Per policy: success rate with its 95 % Wilson interval, per demonstrated action too, falls, how episodes
ended, the mean wall time per episode (on a shared, loaded machine); how well the overhead camera locates the
block on the same resets; and, for the policies that read the demonstration, how often the action they
recognised is the demonstrated one. Writes
``results/imitation_<robot>.json`` (or ``--output``).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import gymnasium
import numpy as np
from scipy.spatial.transform import Rotation

from hoap_actions.apps.episodes import compare_policies, summarise, wilson_interval
from hoap_actions.demonstration.bodies import DEMONSTRATORS
from hoap_actions.envs.hoap_env import HoapEnv
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.imitation.imitate_env import BLOCK_SIZE
from hoap_actions.policies.block_skills import wrap_quarter
from hoap_actions.policies.imitation_policy import ACTIONS, Intent, frequent_intent
from hoap_actions.vision.block import locate_block

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import RESULTS, arguments, numeric_environment, write_json

ENV_ID = "hoap_actions/Imitate-v0"
CONTROL_FPS = float(HoapEnv.metadata["render_fps"])  # env steps per second
HELD_OUT_SEEDS = (91000, 91200)  # [first, stop): declared in docs/experiments/imitation.md, run once per robot
VALIDATION_SEEDS = (90000, 90100)  # [first, stop): every choice, and the frequent-action baseline's fit
POLICIES = {"camera": ("imitation-camera", {}), "markers": ("imitation-markers", {}),
            "oracle": ("imitation-oracle", {}), "frequent": ("imitation-frequent", {}), "nothing": ("nothing", {})}


def fit_frequent(seeds: range, robot: str, env_kwargs: dict) -> Intent:
    """The frequent-action baseline's intent (:func:`frequent_intent`) from the true demonstrations of
    ``seeds`` (the validation seeds: the baseline sees none of the evaluation's)."""
    env = gymnasium.make(ENV_ID, robot=robot, control_mode="ee_delta", **env_kwargs)
    shown = []
    try:
        for seed in seeds:
            env.reset(seed=seed)
            truth = env.get_wrapper_attr("true_demonstration")()
            shown.append((truth.action, truth.object_start, truth.object_end))
    finally:
        env.close()
    return frequent_intent(shown)


def reset_pass(seeds: range, robot: str, env_kwargs: dict) -> tuple[dict[int, dict], dict]:
    """What each seed's demonstration was (the env's oracle, read after a reset: its ``action``, its
    ``seconds`` and its ``demonstrator``) and how well the overhead camera locates the block there
    (:func:`~hoap_actions.vision.block.locate_block` at 320 x 240 against the simulator's pose: centre
    error in mm, turn error in degrees modulo a quarter turn)."""
    env = gymnasium.make(ENV_ID, robot=robot, control_mode="ee_delta", **env_kwargs)
    parse, capture = env.get_wrapper_attr("parse_observation"), env.get_wrapper_attr("capture")
    shown, centre_mm, turn_deg = {}, [], []
    try:
        for seed in seeds:
            obs, _ = env.reset(seed=seed)
            truth = env.get_wrapper_attr("true_demonstration")()
            shown[seed] = {"action": truth.action, "seconds": len(truth.H) / truth.fps,
                           "demonstrator": truth.demonstrator}
            view, truth = capture("overhead", 320, 240), parse(obs)
            found = locate_block(view.rgb, view.depth, view.camera, BLOCK_SIZE)
            if found is None:
                continue
            centre_mm.append(1e3 * float(np.linalg.norm(found.position_m - truth["block_position"])))
            yaw = Rotation.from_quat(truth["block_quaternion"]).as_euler("zyx")[0]
            turn_deg.append(abs(np.degrees(wrap_quarter(found.yaw_rad - yaw))))
    finally:
        env.close()
    location = {"located": len(centre_mm), "of": len(seeds),
                "centre_error_mm": {"median": float(np.median(centre_mm)), "p95": float(np.percentile(centre_mm, 95)),
                                    "max": float(np.max(centre_mm))},
                "turn_error_deg": {"median": float(np.median(turn_deg)), "p95": float(np.percentile(turn_deg, 95)),
                                   "max": float(np.max(turn_deg))}}
    return shown, location


def by_group(episodes: list, groups: dict[int, str], names: list[str]) -> dict[str, dict]:
    """Successes, episodes and the Wilson interval per group (a demonstrated action, a demonstrator) of the
    episodes' seeds; ``episodes`` are results or their summaries' dictionaries."""
    table = {}
    for name in names:
        mine = [e for e in episodes if groups[_seed(e)] == name]
        successes = sum(_success(e) for e in mine)
        table[name] = {"successes": successes, "episodes": len(mine),
                         "success_rate": successes / len(mine) if mine else None,
                         "success_ci95": wilson_interval(successes, len(mine))}
    return table


def _seed(episode) -> int:
    return episode["seed"] if isinstance(episode, dict) else episode.seed


def _success(episode) -> bool:
    return episode["success"] if isinstance(episode, dict) else episode.success


def breakdown(path: Path, shown: dict[int, dict]) -> dict:
    """Per policy of an earlier run's JSON on the same seeds: its success per demonstrator, the
    demonstrators read from this run's resets."""
    import json

    other = json.loads(Path(path).read_text())
    if list(other["seeds"]) != [min(shown), max(shown) + 1]:
        raise SystemExit(f"--breakdown {path} ran seeds {other['seeds']}, not these")
    demonstrators = {seed: row["demonstrator"] for seed, row in shown.items()}
    names = sorted(set(demonstrators.values()))
    return {name: by_group(other[name]["episodes"], demonstrators, names)
            for name in POLICIES if name in other and "episodes" in other[name]}


def timing(episodes: list, shown: dict[int, dict], control_fps: float) -> dict:
    """Per episode of a policy that reads its demonstration: the reading's and the execution's wall time
    (the episode without the env's reset, its filming of the demonstration, and the reading) and how fast
    the loop runs against the real time it stands for (the demonstration's length plus the robot's
    episode's, over reading plus execution)."""
    reading = np.array([e.reading_s for e in episodes])
    filming = np.array([e.filming_s or 0.0 for e in episodes])
    execution = np.array([e.wall_s - e.reset_s - e.reading_s - f for e, f in zip(episodes, filming)])
    real = np.array([shown[e.seed]["seconds"] + e.steps / control_fps for e in episodes])
    factor = real / (reading + execution)
    return {"reading_s": float(reading.mean()), "execution_s": float(execution.mean()),
            "filming_s": float(filming.mean()),
            "demonstration_s": float(np.mean([shown[e.seed]["seconds"] for e in episodes])),
            "real_time_factor": {"median": float(np.median(factor)), "min": float(factor.min()),
                                 "overall": float(real.sum() / (reading + execution).sum())}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[arguments("imitation.json")])
    parser.add_argument("--seeds", type=int, nargs=2, default=HELD_OUT_SEEDS, metavar=("FIRST", "STOP"))
    parser.add_argument("--robot", default="fixed_legs", choices=list(ROBOT_MODELS))
    parser.add_argument("--level", default="mapped", choices=["mapped", "shifted"])
    parser.add_argument("--demonstrator", choices=sorted(DEMONSTRATORS), help="who demonstrates (default: drawn)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--policies", nargs="+", choices=list(POLICIES), default=list(POLICIES))
    parser.add_argument("--breakdown", type=Path, metavar="JSON",
                        help="also break an earlier run's policies on the same seeds down by demonstrator")
    parser.add_argument("--fit-seeds", type=int, nargs=2, default=VALIDATION_SEEDS, metavar=("FIRST", "STOP"),
                        help="the demonstrations the frequent-action baseline is fitted on (default: validation)")
    parser.add_argument("--ik-period", type=int, help="physics ticks per hand IK step (default: the robot's own)")
    args = parser.parse_args()
    if args.output == RESULTS / "imitation.json":
        args.output = RESULTS / f"imitation_{args.robot}.json"
    seeds = range(*args.seeds)
    if "frequent" in args.policies and set(seeds) & set(range(*args.fit_seeds)):
        parser.error("--fit-seeds overlap --seeds: the frequent-action baseline would see the demonstrations it is "
                     "scored on")
    env_kwargs = {"level": args.level, "demonstrator": args.demonstrator}
    if args.ik_period is not None:
        env_kwargs["ik_period"] = args.ik_period
    policies = {name: POLICIES[name] for name in args.policies}
    start = time.perf_counter()
    if "frequent" in policies:
        intent = fit_frequent(range(*args.fit_seeds), args.robot, env_kwargs)
        policies["frequent"] = ("imitation-frequent", {"intent": intent})
        print(f"frequent-action baseline: {intent.action}, displacement {np.round(intent.displacement * 100, 2)} cm, "
              f"turn {np.degrees(intent.turn):.1f} deg")
    results = compare_policies(ENV_ID, policies, seeds, workers=args.workers, robot=args.robot, env_kwargs=env_kwargs)
    wall = time.perf_counter() - start
    shown, location = reset_pass(seeds, args.robot, env_kwargs)
    actions = {seed: row["action"] for seed, row in shown.items()}
    demonstrators = {seed: row["demonstrator"] for seed, row in shown.items()}
    document = {"env": ENV_ID, "level": args.level, "demonstrator": args.demonstrator or "drawn",
                "ik_period": args.ik_period, "seeds": list(args.seeds), "robot": args.robot, "workers": args.workers,
                "wall_s": wall,
                "environment": numeric_environment(None), "block_location": location}
    if "frequent" in policies:
        intent = policies["frequent"][1]["intent"]
        document["frequent_intent"] = {"fit_seeds": list(args.fit_seeds), "action": intent.action,
                                       "displacement_m": intent.displacement.tolist(), "turn_rad": intent.turn}
    print(f"block located on {location['located']} of {location['of']} resets: centre error median "
          f"{location['centre_error_mm']['median']:.2f} mm (max {location['centre_error_mm']['max']:.2f}), turn "
          f"{location['turn_error_deg']['median']:.1f} deg (max {location['turn_error_deg']['max']:.1f})")
    for name, episodes in results.items():
        summary = summarise(episodes)
        summary["by_action"] = by_group(episodes, actions, list(ACTIONS))
        summary["by_demonstrator"] = by_group(episodes, demonstrators, sorted(set(demonstrators.values())))
        for episode in summary["episodes"]:
            episode["action"], episode["demonstrator"] = actions[episode["seed"]], demonstrators[episode["seed"]]
        readings = [e for e in summary["episodes"] if e["recognised"] is not None]
        if readings:
            right = sum(e["recognised"] == e["action"] for e in readings)
            confusion = Counter(f"{e['action']} as {e['recognised']}" for e in readings
                                if e["recognised"] != e["action"])
            summary["recognised"] = {"right": right, "of": len(readings), "rate": right / len(readings),
                                     "ci95": wilson_interval(right, len(readings)), "confusion": dict(confusion)}
            print(f"{name}: action recognised in {right} of {len(readings)}; confusions {dict(confusion)}")
        if episodes[0].reading_s is not None:
            summary["timing"] = timing(episodes, shown, CONTROL_FPS)
            t = summary["timing"]
            print(f"{name}: reading {t['reading_s']:.1f} s, execution {t['execution_s']:.1f} s per episode; the loop "
                  f"runs at {t['real_time_factor']['overall']:.2f}x real time (demonstrations of "
                  f"{t['demonstration_s']:.1f} s)")
        document[name] = summary
        low, high = summary["success_ci95"]
        print(f"{name:>8} ({args.robot}): success {summary['success_rate']:.1%} [{low:.1%}, {high:.1%}] over "
              f"{len(episodes)} episodes, falls {summary['falls']}, mean episode {summary['mean_wall_s']:.1f} s, "
              f"{summary['reasons']}")
        for group in ("by_action", "by_demonstrator"):
            for key, row in summary[group].items():
                a, b = row["success_ci95"]
                print(f"{'':>10}{key:>9}: {row['successes']}/{row['episodes']} [{a:.1%}, {b:.1%}]")
    if args.breakdown:
        document["breakdown"] = {"of": str(args.breakdown), "by_demonstrator": breakdown(args.breakdown, shown)}
        for name, table in document["breakdown"]["by_demonstrator"].items():
            print(f"{args.breakdown.name}, {name}: " + ", ".join(f"{who} {row['successes']}/{row['episodes']}"
                                                                 for who, row in table.items()))
    names = list(results)
    document["paired"] = {f"{a} - {b}": {f"{a}_only": sum(x.success and not y.success
                                                           for x, y in zip(results[a], results[b])),
                                         f"{b}_only": sum(y.success and not x.success
                                                          for x, y in zip(results[a], results[b]))}
                          for i, a in enumerate(names) for b in names[i + 1:]}
    write_json(args.output, document)


if __name__ == "__main__":
    main()
