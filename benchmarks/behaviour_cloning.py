"""Behaviour cloning from the scripted expert's robot episodes, beside the PHMM policy, on the welded-legs robot.

Demonstrations: the scripted expert on ``hoap_actions/PegInsert-v0`` (``robot="fixed_legs"``,
``control_mode="ee_delta"``), collected as Minari datasets by ``hoap_actions.apps.collect.collect`` (what
``hoap-actions collect`` runs) in shards of 100 episodes, training layouts 80000 onwards: the 100-episode
set is seeds 80000-80099, the 1000-episode set 80000-80999. Shards already in ``--data`` are reused.
A :class:`~hoap_actions.policies.behaviour_cloning.BehaviourCloning` MLP is fitted on each set (its
training time measured), then every policy runs every evaluation layout, interleaved seed by seed
(:func:`~hoap_actions.apps.episodes.compare_policies`): the cloned policies, the scripted expert and the
PHMM policy. Per policy: success rate with its 95 % Wilson interval, falls, how episodes ended, mean
episode wall time; paired against each other on the same layouts (discordant layouts, exact McNemar
p, bootstrap interval of the difference).

Splits, declared in ``docs/experiments/behaviour_cloning.md`` before the first held-out run: held-out
layouts 66000-66199 (those of the PHMM policy's welded-robot figure), run once; validation layouts
79000-79049 for every choice (``--seeds 79000 79050 --baselines``); no seed below 79000 otherwise.

    pip install ".[bench]"
    python benchmarks/behaviour_cloning.py --workers 2

Writes ``results/behaviour_cloning.json`` (or ``--output``) and its figure (``--figure``); ``--figure-only
JSON`` redraws the figure from a JSON this script wrote.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from hoap_actions.apps.episodes import compare_policies, paired_outcomes, summarise

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import arguments, numeric_environment, write_json

ENV_ID = "hoap_actions/PegInsert-v0"
ROBOT = "fixed_legs"
HELD_OUT_SEEDS = (66000, 66200)  # [first, stop): the PHMM policy's welded-robot figure's layouts
VALIDATION_SEEDS = (79000, 79050)
TRAINING_SEED = 80000
SHARD = 100  # episodes per Minari dataset
NAMESPACE = "hoap_actions/PegInsert-welded"
FIGURE = Path(__file__).resolve().parents[1] / "docs" / "experiments" / "behaviour_cloning.png"
ROOT = Path(__file__).resolve().parents[1]


def shard_id(seed: int) -> str:
    """The Minari id of the shard whose first layout is ``seed``."""
    return f"{NAMESPACE}/scripted-s{seed}-v0"


def _no_setup() -> None:
    """Collection workers need nothing before their first shard."""


def _collect_shard(seed: int) -> float:
    """Collect the shard starting at ``seed`` (unless it is there); its wall time in s (0 if reused)."""
    import minari

    from hoap_actions.apps.collect import collect

    if minari.storage.get_dataset_path(shard_id(seed)).exists():
        return 0.0
    start = time.perf_counter()
    collect(ENV_ID, "scripted", SHARD, seed, shard_id(seed), robot=ROBOT)
    return time.perf_counter() - start


def collect_shards(seeds: list[int], workers: int) -> list[float]:
    """Each shard's collection time, collected on ``workers`` processes (the namespace made first, once)."""
    from minari.namespace import create_namespace, list_local_namespaces

    from hoap_actions.parallel import ordered_map

    if NAMESPACE not in list_local_namespaces():
        create_namespace(NAMESPACE)
    if workers == 1:
        return [_collect_shard(s) for s in seeds]
    return list(ordered_map(_collect_shard, seeds, _no_setup, (), workers))


LIFTED_M = 0.02  # the target peg's bottom this high over the table: it was grasped and lifted
OVER_HOLE_M = 0.01  # its bottom's horizontal distance from the target hole's centre while lifted


def progress(name: str, policy_kwargs: dict, seeds: list[int]) -> dict:
    """Validation only: the cloned policy's episodes on ``seeds`` [first, stop), recorded as a Minari
    dataset in a temporary folder (by ``collect``, the same episode loop as the evaluation) and read
    back: successes (with the Wilson interval), and two measures of how far the others got, from the
    target peg's bottom (``achieved_goal``): lifted :data:`LIFTED_M` over the table, and carried to
    within :data:`OVER_HOLE_M` of the target hole (``desired_goal``) while lifted."""
    import tempfile

    import minari

    from hoap_actions.apps.collect import collect
    from hoap_actions.apps.episodes import wilson_interval

    first, stop = seeds
    before = os.environ["MINARI_DATASETS_PATH"]
    with tempfile.TemporaryDirectory() as root:
        os.environ["MINARI_DATASETS_PATH"] = root
        try:
            dataset_id = f"{NAMESPACE}/validation-{name.replace('_', '')}-v0"
            collect(ENV_ID, "bc", stop - first, first, dataset_id, policy_kwargs, robot=ROBOT)
            rows = []
            for episode in minari.load_dataset(dataset_id).iterate_episodes():
                bottom, hole = episode.observations["achieved_goal"], episode.observations["desired_goal"]
                lifted = bottom[:, 2] > LIFTED_M
                near = np.linalg.norm(bottom[:, :2] - hole[:, :2], axis=1)[lifted]
                success = bool(episode.terminations[-1] and episode.rewards[-1] == 0)  # the sparse reward's success
                rows.append({"success": success, "steps": len(episode.actions),
                             "lifted": bool(lifted.any()), "over_hole": bool(near.size and near.min() < OVER_HOLE_M)})
        finally:
            os.environ["MINARI_DATASETS_PATH"] = before
    successes = sum(r["success"] for r in rows)
    summary = {"success_rate": successes / len(rows), "success_ci95": wilson_interval(successes, len(rows)),
               "lifted": sum(r["lifted"] for r in rows), "over_hole": sum(r["over_hole"] for r in rows),
               "episodes": rows}
    print(f"{name:>9}: success {successes} / {len(rows)}, lifted {summary['lifted']}, over the hole "
          f"{summary['over_hole']}")
    return summary


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def code_version() -> dict:
    """The checkout's commit, the last commit of the PHMM policy's and the expert's code, and any
    uncommitted change to the package's code (the figures are then of code no commit holds)."""
    folders = ["policies", "apps", "envs", "controllers", "primitives", "vision", "models", "src"]
    return {"commit": _git("rev-parse", "HEAD"),
            "policies_commit": _git("log", "-1", "--format=%H", "--", "policies"),
            "uncommitted": _git("status", "--porcelain", "--", *folders).splitlines()}


def figure(document: dict, path: Path) -> None:
    """Success rate against demonstration episodes, each with its Wilson interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes = [t["episodes"] for t in document["training"]]
    fig, ax = plt.subplots(figsize=(6.0, 3.6), constrained_layout=True)
    x = np.array([min(sizes) / 1.6, max(sizes) * 1.6])
    for name, colour, label in (("scripted", "tab:green", "scripted expert (true poses)"),
                                ("phmm", "tab:blue", "PHMM policy (camera, learned from the simulated human)")):
        if name in document:
            summary = document[name]
            ax.axhline(100 * summary["success_rate"], color=colour, lw=1.5, label=label)
            ax.fill_between(x, *(100 * np.array(summary["success_ci95"])[:, None].repeat(2, 1)), color=colour,
                            alpha=0.15, lw=0)
    rates = np.array([100 * document[f"bc_{n}"]["success_rate"] for n in sizes])
    bounds = np.array([100 * np.array(document[f"bc_{n}"]["success_ci95"]) for n in sizes])
    ax.errorbar(sizes, rates, yerr=[rates - bounds[:, 0], bounds[:, 1] - rates], fmt="o-", color="tab:red",
                capsize=4, label="behaviour cloning (MLP on the state)")
    ax.set_xscale("log")
    ax.set_xlim(*x)
    ax.set_ylim(-2, 102)
    ax.set_xlabel("demonstration episodes of the scripted expert")
    ax.set_ylabel("success (%)")
    first, stop = document["seeds"]
    ax.set_title(f"welded-legs robot, {stop - first} layouts ({first}-{stop - 1}); bars and bands: 95 % Wilson",
                 fontsize=9)
    ax.legend(fontsize=8, loc="best")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("behaviour_cloning.json", data=True)])
    parser.add_argument("--seeds", type=int, nargs=2, default=HELD_OUT_SEEDS, metavar=("FIRST", "STOP"))
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1000],
                        help="demonstration episodes per cloned policy (multiples of 100)")
    parser.add_argument("--baselines", nargs="*", choices=["scripted", "phmm"], default=["scripted", "phmm"])
    parser.add_argument("--workers", type=int, default=1, help="processes for collection and evaluation")
    parser.add_argument("--threads", type=int, default=1, help="PyTorch threads while fitting")
    # defaults: the settings chosen on the validation layouts (docs/experiments/behaviour_cloning.md)
    parser.add_argument("--hidden", type=int, nargs="+", default=[128, 128])
    parser.add_argument("--epochs", type=int, default=100)
    parser.add_argument("--batch-size", type=int, default=256)
    parser.add_argument("--learning-rate", type=float, default=1e-3)
    parser.add_argument("--weight-decay", type=float, default=0.0)
    parser.add_argument("--schedule", default="constant", choices=["constant", "cosine"])
    parser.add_argument("--no-normalise", dest="normalise", action="store_false")
    parser.add_argument("--chunk", type=int, default=1, help="actions predicted per observation (temporal ensembling)")
    parser.add_argument("--patience", type=int, default=30,
                        help="a cloned policy gives up after this many steps of a still observation")
    parser.add_argument("--random-state", type=int, default=0)
    parser.add_argument("--reuse-models", action="store_true",
                        help="load a model fitted before with the same data and hyper-parameters instead of fitting it")
    parser.add_argument("--progress", action="store_true",
                        help="validation: record the cloned policies' episodes, read how far each got (no baselines)")
    parser.add_argument("--figure", type=Path, default=None,
                        help=f"figure to write (default: {FIGURE} for the held-out layouts, none otherwise)")
    parser.add_argument("--figure-only", type=Path, metavar="JSON", help="only redraw the figure from this JSON")
    args = parser.parse_args()
    if args.figure_only:
        figure(json.loads(args.figure_only.read_text()), args.figure or FIGURE)
        return
    if args.seeds[0] < VALIDATION_SEEDS[0] and tuple(args.seeds) != HELD_OUT_SEEDS:
        parser.error(f"seeds below {VALIDATION_SEEDS[0]} are held out; the declared held-out layouts are "
                     f"{HELD_OUT_SEEDS[0]}-{HELD_OUT_SEEDS[1] - 1}")
    if args.progress and args.baselines:
        parser.error("--progress runs the cloned policies alone: give --baselines with no names")
    if any(n < 1 or n % SHARD for n in args.sizes):
        parser.error(f"--sizes must be positive multiples of {SHARD}")
    from hoap_actions.policies.behaviour_cloning import BehaviourCloning, minari_transitions

    os.environ["MINARI_DATASETS_PATH"] = str((args.data / "minari").resolve())
    start = time.perf_counter()
    shard_seeds = list(range(TRAINING_SEED, TRAINING_SEED + max(args.sizes), SHARD))
    shard_times = collect_shards(shard_seeds, args.workers)
    collected = time.perf_counter() - start
    print(f"demonstrations: {len(shard_seeds)} shards of {SHARD} episodes in {collected:.0f} s "
          f"({sum(t > 0 for t in shard_times)} collected now)")

    params = {"hidden": tuple(args.hidden), "epochs": args.epochs, "batch_size": args.batch_size,
              "learning_rate": args.learning_rate, "weight_decay": args.weight_decay,
              "schedule": args.schedule, "normalise": args.normalise,
              "chunk": args.chunk, "random_state": args.random_state, "threads": args.threads}
    models = args.data / "behaviour_cloning"
    training, policies = [], {}
    for n in sorted(args.sizes):
        X, Y, lengths = minari_transitions([shard_id(s) for s in shard_seeds[: n // SHARD]])
        tag = hashlib.sha1(json.dumps(params, sort_keys=True).encode()).hexdigest()[:10]
        path = models / f"bc_{n}_{tag}.pt"
        fit_start = time.perf_counter()
        if args.reuse_models and path.exists():
            model, fit_s = BehaviourCloning.load(path), None
        else:
            model = BehaviourCloning(**params).fit(X, Y, lengths)
            fit_s = time.perf_counter() - fit_start
            model.save(path, overwrite=True)
        training.append({"episodes": n, "seeds": [TRAINING_SEED, TRAINING_SEED + n], "episodes_held": len(lengths),
                         "transitions": len(X), "model": path.name,
                         "fit_s": fit_s, "final_loss": model.loss_curve_[-1], "loss_curve": model.loss_curve_})
        policies[f"bc_{n}"] = ("bc", {"model": str(path), "patience": args.patience})
        print(f"bc_{n}: {len(X)} pairs from {len(lengths)} episodes, fitted in {fit_s or 0:.0f} s, training loss "
              f"{model.loss_curve_[0]:.4f} -> {model.loss_curve_[-1]:.4f}")
    policies.update({name: (name, {}) for name in args.baselines})

    eval_start = time.perf_counter()
    if args.progress:
        document = {name: progress(name, kwargs, args.seeds) for name, (_, kwargs) in policies.items()}
        document |= {"seeds": list(args.seeds), "params": params, "patience": args.patience, "training": training,
                     "evaluate_s": time.perf_counter() - eval_start, "code": code_version(),
                     "environment": numeric_environment(None, torch=_version("torch"))}
        write_json(args.output, document)
        return
    results = compare_policies(ENV_ID, policies, range(*args.seeds), workers=args.workers, robot=ROBOT)
    evaluated = time.perf_counter() - eval_start
    document = {"seeds": list(args.seeds), "robot": ROBOT, "workers": args.workers, "params": params,
                "patience": args.patience,
                "collect_s": collected, "shard_collect_s": shard_times, "evaluate_s": evaluated,
                "wall_s": time.perf_counter() - start, "training": training, "code": code_version(),
                "environment": numeric_environment(None, torch=_version("torch"), minari=_version("minari"))}
    for name, episodes in results.items():
        summary = summarise(episodes)
        document[name] = summary
        low, high = summary["success_ci95"]
        print(f"{name:>9}: success {summary['success_rate']:.1%} [{low:.1%}, {high:.1%}] over {len(episodes)} layouts, "
              f"falls {summary['falls']}, mean episode {summary['mean_wall_s']:.1f} s, {summary['reasons']}")
    names = list(results)
    document["paired"] = {f"{a} - {b}": paired_outcomes(document[a]["episodes"], document[b]["episodes"])
                          for i, a in enumerate(names) for b in names[i + 1:]}
    for pair, p in document["paired"].items():
        print(f"{pair}: {100 * p['difference']:+.1f} points [{100 * p['difference_ci95'][0]:+.1f}, "
              f"{100 * p['difference_ci95'][1]:+.1f}], {p['only_first']} / {p['only_second']} layouts only one "
              f"solved, McNemar p {p['mcnemar_p']:.3g}")
    write_json(args.output, document)
    if args.figure or tuple(args.seeds) == HELD_OUT_SEEDS:
        figure(document, args.figure or FIGURE)


def _version(package: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return "not installed"


if __name__ == "__main__":
    main()
