"""Fig. 8 against the robot-learning baselines: approach PHMMs (linear, thin-plate, thin-plate + posture
model) beside ProMP, DMP and GMR synthesising reaches to the 35 locations of the 5x7 test grid from the
2x2 and 3x3 training grids, on the same recordings, with the same error.

Protocol: :mod:`hoap_actions.primitives.evaluation.grid_synthesis` (the error e of eq. (5) against the
DTW average of the 4 real reaches at each test location; the demonstrator's own leave-one-out error).
Every method's hyper-parameters are chosen on the training grid alone by the PHMM's rule
(:func:`~hoap_actions.primitives.hmm.selection.select_mean_model`: resynthesis of the movements of one
left-out location at a time), among the candidates listed below; the chosen one is fitted to the whole
grid and scored. The PHMM rows are those of ``phmm_synthesis_error.py --posture`` (its constants and
candidates, imported); the baselines: :mod:`hoap_actions.primitives.baselines.movement_primitives` (ProMP,
DMP) and :mod:`hoap_actions.primitives.baselines.mixture_regression` (GMR). Each baseline is also scored
with the PHMM's posture model (its shoulder and elbow from its own hand), to tell the posture model's
share from the mean model's. Differences are paired by recording (same recording, same test locations).

    python benchmarks/synthesis_baselines.py [--seeds 5 6 7] [--jobs 2] [--data DIR] [--figure PNG]
    python benchmarks/synthesis_baselines.py --figure-only JSON [--figure PNG]

Seeds: ``approach-grid`` seed 0 is the validation recording (the candidate lists were set looking at
it); seeds 5, 6 and 7 were declared held-out before the first run (``docs/experiments/synthesis_baselines.md``).
Writes ``results/synthesis_baselines.json`` (or ``--output``) and the error maps of the first seed
(``--figure``; default ``docs/experiments/synthesis_baselines.png`` for the held-out seeds, else beside the JSON).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import phmm_synthesis_error as phmm
from _results import (
    arguments,
    ensure_recording,
    numeric_environment,
    spread,
    use_blas_threads,
    write_json,
)

HELD_OUT = (5, 6, 7)
TRAIN_GRIDS = phmm.TRAIN_GRIDS
ROOT = Path(__file__).resolve().parents[1]
FIGURE = ROOT / "docs" / "experiments" / "synthesis_baselines.png"
# Candidates of each baseline (module, class, keyword sets), chosen among on the training grid only.
BASELINES = {
    "ProMP": ("movement_primitives", "ProMPSynthesis",
              [{"n_weights_per_dim": n, "prior": p} for n in (10, 20, 30) for p in (1e-3, 1e-1, 1.0)]),
    "DMP": ("movement_primitives", "DMPSynthesis",
            [{"n_neighbours": k, "other_goals": g} for k in (1, 2, 3, 4) for g in ("neighbours", "affine")]),
    "GMR": ("mixture_regression", "GMRSynthesis", [{"n_components": k} for k in (5, 10, 15, 20)]),
}
PHMM_ROWS = ("PHMM linear", "PHMM chosen", "PHMM chosen + posture")
HEADLINE = "PHMM chosen + posture"
FIGURES = ("mean_cm", "max_cm", "locations_within_human_loo", "fit_s", "selection_s", "synthesis_ms_per_movement")


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     parents=[arguments("synthesis_baselines.json", data=True, threads=True)])
    parser.add_argument("--seeds", type=int, nargs="+", default=list(HELD_OUT),
                        help="approach-grid recordings (default: the held-out %(default)s; 0 is validation)")
    parser.add_argument("--figure", type=Path, default=None,
                        help=f"error maps to write (default: {FIGURE} for the held-out seeds, else beside the JSON)")
    parser.add_argument("--figure-only", type=Path, metavar="JSON", help="only redraw the figure from this JSON")
    parser.add_argument("--jobs", type=int, default=1,
                        help="processes, each scoring one (recording, training grid) at a time; the figures do not "
                             "depend on it")
    args = parser.parse_args(argv)
    if not 1 <= args.jobs <= (os.cpu_count() or 1):
        parser.error(f"--jobs must be in 1..{os.cpu_count() or 1} (this machine's CPUs); got {args.jobs}")
    return args


def baseline_class(name: str) -> type:
    import importlib

    module, cls, _ = BASELINES[name]
    return getattr(importlib.import_module(f"hoap_actions.primitives.baselines.{module}"), cls)


def choose(movements: list, n_locations: int, estimator: type, candidates: list[dict], **fixed) -> tuple:
    """The paper's rule on the training movements: (chosen keyword set, {candidate: cv error cm}, wall s)."""
    import numpy as np

    from hoap_actions.primitives.hmm.selection import select_mean_model

    started = time.perf_counter()
    choice = select_mean_model(np.concatenate([x for x, _ in movements]), [len(x) for x, _ in movements],
                               np.array([p for _, p in movements]), candidates, n_folds=n_locations,
                               estimator=estimator, **fixed)
    errors = {describe(c): round(e * 100, 4) for c, e in zip(choice.candidates, choice.errors)}
    return choice.best, errors, time.perf_counter() - started


def describe(params: dict) -> str:
    if "mean_model" in params:
        return phmm.label(params)
    return ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}" for k, v in params.items())


def evaluate_grid(data, grid: str) -> dict:
    """Every method's selection, fit and error map on one training grid of one recording."""
    import numpy as np

    from hoap_actions.primitives.evaluation.grid_synthesis import fit_grid_model, fit_grid_posture, synthesis_map
    from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM

    movements = [m for reps in data.cells[grid].values() for m in reps]
    n_locations = len(data.cells[grid])
    X, lengths = np.concatenate([x for x, _ in movements]), [len(x) for x, _ in movements]
    phi = np.array([p for _, p in movements])
    body, alpha_errors, body_fit_s = fit_grid_posture(data, grid)
    out: dict = {"posture": {"alpha": body.alpha, "cv_error_cm": {str(a): round(e * 100, 4) for a, e in
                                                                  alpha_errors.items()}, "fit_s": body_fit_s}}
    chosen, cv, selection_s = choose(movements, n_locations, ParametricHMM, phmm.candidates(),
                                     n_states=phmm.N_STATES, **phmm.MODEL)
    for name, params, completion in (("PHMM linear", {"mean_model": "linear"}, None), ("PHMM chosen", chosen, None),
                                     ("PHMM chosen + posture", chosen, body)):
        model, fit_s = fit_grid_model(data, grid, n_states=phmm.N_STATES, **phmm.MODEL, **params)
        scored = synthesis_map(model, data, completion)
        out[name] = {"model": describe(params), **scored.summary(data), "fit_s": fit_s,
                     "selection_s": selection_s if name != "PHMM linear" else 0.0, "cv_error_cm": cv}
    for name, (_, _, candidates) in BASELINES.items():
        estimator = baseline_class(name)
        chosen, cv, selection_s = choose(movements, n_locations, estimator, candidates)
        started = time.perf_counter()
        model = estimator(**chosen).fit(X, lengths, phi)
        fit_s = time.perf_counter() - started
        for row, completion in ((name, None), (f"{name} + posture", body)):
            scored = synthesis_map(model, data, completion)
            out[row] = {"model": describe(chosen), **scored.summary(data), "fit_s": fit_s,
                        "selection_s": selection_s, "cv_error_cm": cv}
    return out


def methods() -> list[str]:
    return [*PHMM_ROWS, *BASELINES, *(f"{name} + posture" for name in BASELINES)]


def summarise(per_recording: dict) -> dict:
    """Per grid and method: each figure's spread over the recordings, per marker too; the paired
    difference of every method to the headline PHMM; the best method and its margin."""
    import numpy as np

    summary: dict = {"human_leave_one_out_mean_cm": spread([r["human_cm"]["leave_one_out_mean"]
                                                            for r in per_recording.values()])}
    for grid in TRAIN_GRIDS:
        rows = {}
        for name in methods():
            runs = [r[grid][name] for r in per_recording.values()]
            rows[name] = {key: spread([run[key] for run in runs]) for key in FIGURES}
            rows[name]["per_marker_cm"] = {m: spread([run["per_marker_cm"][m] for run in runs])
                                           for m in runs[0]["per_marker_cm"]}
            rows[name]["minus_headline_cm"] = spread([run["mean_cm"] - r[grid][HEADLINE]["mean_cm"]
                                                      for run, r in zip(runs, per_recording.values())])
        ranked = sorted(rows, key=lambda n: rows[n]["mean_cm"]["mean"])
        best, second = ranked[0], ranked[1]
        baselines = list(BASELINES)
        best_baseline = min(baselines, key=lambda n: rows[n]["mean_cm"]["mean"])
        summary[grid] = {
            "methods": rows, "ranking": ranked, "best": best,
            "best_margin_cm": spread([r[grid][second]["mean_cm"] - r[grid][best]["mean_cm"]
                                      for r in per_recording.values()]),
            "runner_up": second, "best_baseline": best_baseline,
            "headline_at_or_below_every_baseline": bool(all(
                rows[HEADLINE]["mean_cm"]["mean"] <= rows[n]["mean_cm"]["mean"] for n in baselines)),
            "headline_below_best_baseline_in_every_recording": bool(np.all(
                np.array(rows[best_baseline]["minus_headline_cm"]["values"]) > 0)),
        }
    return summary


def figure(document: dict, path: Path) -> None:
    """Error maps (cm) of the first recording: a row per training grid, the demonstrator's own error
    and each method without the posture model's help (besides the PHMM's), one colour scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    seed = str(document["protocol"]["seeds"][0])
    run = document["per_recording"][seed]
    columns = ["demonstrator, leave-one-out", *PHMM_ROWS, *BASELINES]
    maps = {grid: {c: np.array(run["human_cm"]["leave_one_out_map"] if c.startswith("demonstrator")
                               else run[grid][c]["map_cm"]) for c in columns} for grid in TRAIN_GRIDS}
    every = np.concatenate([m.ravel() for grid in maps.values() for m in grid.values()])
    vmax = float(np.percentile(every, 95))
    rows_cm, cols_cm = document["grid_axes_cm"]
    fig, axs = plt.subplots(len(TRAIN_GRIDS), len(columns), figsize=(2.6 * len(columns), 2.6 * len(TRAIN_GRIDS) + 0.8),
                            constrained_layout=True, squeeze=False)
    for r, grid in enumerate(TRAIN_GRIDS):
        marked = run[grid]["training_cells"]
        for ax, name in zip(axs[r], columns):
            cm = maps[grid][name]
            image = ax.imshow(cm, cmap="viridis", vmin=0.0, vmax=vmax, origin="lower", aspect="auto")
            for (i, j), value in np.ndenumerate(cm):
                ax.text(j, i, f"{value:.1f}", ha="center", va="center", fontsize=6,
                        color="white" if value < 0.6 * vmax else "black")
            for i, j in marked:
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, edgecolor="red", linewidth=1.2))
            model = "" if name.startswith("demonstrator") else f" ({run[grid][name]['model']})"
            ax.set_title(f"{textwrap.fill(name + model, 30)}\n{grid}: mean {cm.mean():.2f} cm", fontsize=7)
            ax.set_xticks(range(len(cols_cm)), [str(c) for c in cols_cm], fontsize=6)
            ax.set_yticks(range(len(rows_cm)), [str(c) for c in rows_cm], fontsize=6)
            ax.set_xlabel("target y (cm)", fontsize=6)
            ax.set_ylabel("target x (cm)", fontsize=6)
    fig.colorbar(image, ax=axs, label="synthesis error e (cm)", shrink=0.8, extend="max")
    fig.suptitle(f"Synthesis error over the 5x7 test grid, approach-grid seed {seed}: a row per training grid "
                 "(red squares: its training locations); number in a cell: e there (cm); colours capped at the "
                 f"95th percentile of all cells ({vmax:.1f} cm)", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def figure_path(given: Path | None, seeds: list[int], output: Path) -> Path:
    """``--figure``, else the docs' figure for the held-out seeds, else a PNG beside the JSON."""
    return given or (FIGURE if set(seeds) <= set(HELD_OUT) else output.with_suffix(".png"))


def human_error(path: Path) -> dict:
    """The demonstrator's own leave-one-out error at each test location of one recording (cm)."""
    import numpy as np

    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.evaluation.grid_synthesis import grid_data

    loo = (data := grid_data(load_demonstrations(path))).as_map(data.human_loo)
    return {"leave_one_out_mean": float(loo.mean() * 100), "leave_one_out_map": np.round(loo * 100, 3).tolist()}


def evaluate_task(task: tuple[Path, str]) -> dict:
    """Every method on one training grid of one recording (a job of :func:`evaluate_recordings`)."""
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.evaluation.grid_synthesis import grid_data

    path, grid = task
    data = grid_data(load_demonstrations(path))
    out = evaluate_grid(data, grid)
    out["training_cells"] = [list(k) for k in phmm.train_locations(data, grid)]
    return out


def _worker_setup() -> None:
    """The workers import what they need with their first job."""


def evaluate_recordings(paths: dict[int, Path], jobs: int) -> dict:
    """Per recording: the demonstrator's error and every training grid's methods; the (recording, grid)
    jobs run on ``jobs`` processes (:func:`hoap_actions.parallel.ordered_map`) when ``jobs`` > 1. The 3x3
    grids go first: they take several times as long as the 2x2 ones."""
    tasks = [(seed, grid) for grid in sorted(TRAIN_GRIDS, key=lambda g: g != "3x3") for seed in paths]
    calls = [(paths[seed], grid) for seed, grid in tasks]
    if jobs > 1:
        from hoap_actions.parallel import ordered_map

        results = ordered_map(evaluate_task, calls, _worker_setup, workers=jobs)
    else:
        results = map(evaluate_task, calls)
    per_recording: dict = {str(seed): {"data": str(path), "human_cm": human_error(path)}
                           for seed, path in paths.items()}
    for (seed, grid), out in zip(tasks, results):
        per_recording[str(seed)][grid] = out
        print(f"  seed {seed} {grid}: " + "; ".join(f"{n} {out[n]['mean_cm']:.3f}" for n in methods()) + " cm",
              flush=True)
    return {seed: {key: run[key] for key in ("data", "human_cm", *TRAIN_GRIDS)} for seed, run in per_recording.items()}


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    use_blas_threads(args.threads)
    import json

    if args.figure_only:
        document = json.loads(args.figure_only.read_text())
        figure(document, figure_path(args.figure, document["protocol"]["seeds"], args.figure_only))
        return document
    started, cpu_started = time.perf_counter(), time.process_time()
    paths = {seed: ensure_recording("approach-grid", seed, args.data, workers=args.jobs) for seed in args.seeds}
    per_recording = evaluate_recordings(paths, args.jobs)
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.primitives.evaluation.grid_synthesis import grid_data

    data = grid_data(load_demonstrations(paths[args.seeds[0]]))
    import gmr
    import movement_primitives

    document = {
        "protocol": {
            "seeds": args.seeds, "held_out": [s for s in args.seeds if s in HELD_OUT],
            "selection": "select_mean_model on the training grid: one location left out per fold, resynthesis error",
            "phmm": {"n_states": phmm.N_STATES, **phmm.MODEL,
                     "mean_model_candidates": [phmm.label(c) for c in phmm.candidates()]},
            "baseline_candidates": {n: [describe(c) for c in cands] for n, (_, _, cands) in BASELINES.items()},
            "posture": "PostureModel (degree 3) on the training grid's frames, alpha by leaving out one location "
                       "at a time; replaces the shoulder and elbow of a synthesis",
            "phi": "object (x, y) at the end of the approach, m", "headline": HEADLINE,
        },
        "grid_axes_cm": [[round(100 * data.location((r, 0))[0]) for r in range(data.shape[0])],
                         [round(100 * data.location((0, c))[1]) for c in range(data.shape[1])]],
        "summary": summarise(per_recording),
        "per_recording": per_recording,
    }
    for grid in TRAIN_GRIDS:
        s = document["summary"][grid]
        for name in methods():
            m = s["methods"][name]["mean_cm"]
            print(f"{grid} {name:24s} {m['mean']:.3f} cm [{m['ci95'][0]:.3f}, {m['ci95'][1]:.3f}]")
        print(f"{grid}: best {s['best']}, by {s['best_margin_cm']['mean']:.3f} cm over {s['runner_up']}")
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    document["environment"] = {**numeric_environment(args.threads, movement_primitives=movement_primitives.__version__,
                                                     gmr=gmr.__version__),
                               "commit": commit or "unknown", "runtime_s": round(time.perf_counter() - started, 1),
                               "cpu_s": round(time.process_time() - cpu_started, 1),
                               "jobs": args.jobs}
    write_json(args.output, document)
    figure(document, figure_path(args.figure, args.seeds, args.output))
    return document


if __name__ == "__main__":
    main()
