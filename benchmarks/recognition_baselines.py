"""Connected recognition against two recognition baselines on the same held-out recordings, in one run.

Protocol (``docs/experiments/recognition_baselines.md``, declared before the first held-out run): every
method learns from the ``paper`` recordings ``--train-seeds`` (0-9) and discovery's classes of them, the
classes the shipped models ``--models`` were learned with. The project's method is those models
(:func:`hoap_actions.primitives.pipelines.recognize.recognize_recording`, as ``phmm_recognition.py``);
the baselines are one hmmlearn ``GaussianHMM`` per class joined by the same grammar and decoded with
the same Viterbi (:class:`~hoap_actions.primitives.baselines.class_hmms.ClassHMMs`), and gradient boosting
on windowed marker features with temporal smoothing
(:class:`~hoap_actions.primitives.baselines.frame_classifier.FrameClassifier`). On each held-out recording
(``--test-seeds``): frame accuracy, segment accuracy, edit score, segment accuracy with the cuts given,
effect error (the project's method only: the baselines estimate no effect), recognition and fit time;
mean and 95 % interval over the recordings, and paired differences (per recording and per episode).

    python benchmarks/recognition_baselines.py [--test-seeds 120 121 122]
    python benchmarks/recognition_baselines.py --validate   # the baselines' choices, on paper 20 and 21

``--validate`` fits every candidate setting of each baseline on the training recordings and scores it on
``--validation-seeds`` (the project's method beside them, from the markers alone); the best by edit
score (then frame accuracy) are the defaults of the held-out run. Recordings are ``data/paper-s<seed>.h5``,
recorded when missing. Writes ``results/recognition_baselines.json`` and the timeline
``results/recognition_baselines.png`` (``--validate``: ``results/recognition_baselines_validation.json``).
"""

from __future__ import annotations

import argparse
import functools
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _results import RESULTS, arguments, ensure_recording, numeric_environment, spread, write_json

FIGURES = ("frame_accuracy", "segment_accuracy", "edit_score", "oracle_cut_accuracy")
PROJECT = "connected recognition (PHMMs)"
NO_VOTE = "connected recognition, no object vote"  # PHMM chains and grammar alone: only the emissions differ from HMMS
HMMS = "per-class GaussianHMMs"
CLASSIFIER = "gradient boosting + smoothing"
# the validation grid: what each fit takes, then what only recognition reads
HMM_FITS = ([{"features": "displacements", "n_states": n} for n in (5, 10, 20, 40)]
            + [{"features": "positions+displacements", "n_states": n} for n in (5, 10, 20)])
HMM_DECODING = [{"stay_weight": w} for w in (1.0, 2.0)]
CLASSIFIER_FITS = [{"offsets": offsets} for offsets in ((-20, -10, 0, 10, 20), (-40, -20, -10, 0, 10, 20, 40),
                                                        (-80, -40, -20, -10, 0, 10, 20, 40, 80),
                                                        (-160, -80, -40, -20, 0, 20, 40, 80, 160))]
CLASSIFIER_DECODING = ([{"smoothing": "none"}]
                       + [{"smoothing": "majority", "smoothing_window": w} for w in (11, 25, 51)]
                       + [{"smoothing": "grammar", "emission_weight": w} for w in (0.1, 0.25, 0.5, 1.0)])


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     parents=[arguments("recognition_baselines.json", data=True)])
    parser.add_argument("--train-seeds", type=int, nargs="+", default=list(range(10)))
    parser.add_argument("--test-seeds", type=int, nargs="+", default=[120, 121, 122])
    parser.add_argument("--validation-seeds", type=int, nargs="+", default=[20, 21])
    parser.add_argument("--validate", action="store_true", help="score the baselines' candidate settings on the "
                        "validation recordings instead (writes results/recognition_baselines_validation.json)")
    parser.add_argument("--models", type=Path, help="the project's models (default: the shipped ones)")
    parser.add_argument("--jobs", type=int, default=1,
                        help="processes recording missing demonstrations and running the project's recognition, and "
                             "the classifier's threads (the figures do not depend on it)")
    hmms = parser.add_argument_group("per-class HMMs (defaults chosen on validation)")
    hmms.add_argument("--hmm-features", default="positions+displacements",
                      choices=("displacements", "positions+displacements"))
    hmms.add_argument("--hmm-states", type=int, default=10)
    hmms.add_argument("--hmm-stay-weight", type=float, default=2.0)
    hmms.add_argument("--hmm-iter", type=int, default=20, help="EM iterations")
    clf = parser.add_argument_group("frame classifier (defaults chosen on validation)")
    clf.add_argument("--clf-offsets", type=int, nargs="+", default=list(CLASSIFIER_FITS[2]["offsets"]))
    clf.add_argument("--clf-iter", type=int, default=100, help="boosting rounds")
    clf.add_argument("--clf-stride", type=int, default=8, help="fit on every this-many-th training frame")
    clf.add_argument("--clf-smoothing", default="grammar", choices=("none", "majority", "grammar"))
    clf.add_argument("--clf-window", type=int, default=25, help="majority window (frames)")
    clf.add_argument("--clf-weight", type=float, default=0.25, help="weight of the classifier's log-evidence (grammar)")
    parser.add_argument("--timeline-episodes", type=int, nargs="+", default=list(range(0, 104, 13)),
                        help="episodes of the first test recording drawn in the timeline (default: one of each "
                             "action of the preset)")
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> dict:
    args = parse_args(argv)
    logging.getLogger("hmmlearn").setLevel(logging.ERROR)  # EM's per-class convergence notes: hundreds of lines
    import numpy as np

    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.models.shipped import default_models_path
    from hoap_actions.primitives.baselines import recognition_comparison as rc
    from hoap_actions.primitives.models.action_models import ActionModels
    from hoap_actions.primitives.pipelines.learn import load_training_demonstrations
    from hoap_actions.primitives.pipelines.mocap_cleaning import clean_demonstrations

    models_path = args.models or default_models_path()
    models = ActionModels.load(models_path)
    fps = models.fps_
    train = [ensure_recording("paper", seed, args.data, workers=args.jobs) for seed in args.train_seeds]
    seeds = args.validation_seeds if args.validate else args.test_seeds
    tests = [ensure_recording("paper", seed, args.data, workers=args.jobs) for seed in seeds]
    episodes, _, _ = load_training_demonstrations(train)
    lengths = [e.T for e in episodes]
    labels = rc.discovery_labels(models.discovery_, lengths)
    H_train = [e.H for e in episodes]
    print(f"training: {len(episodes)} episodes, {sum(lengths)} frames, {len(set(labels.tolist()))} classes")

    held_out = {}
    for seed, path in zip(seeds, tests):
        demos = clean_demonstrations(load_demonstrations(path))
        truth = models.discovery_.predict(np.concatenate([e.O for e in demos]), [e.T for e in demos])
        held_out[seed] = (demos, [e.H for e in demos], truth)

    def fit_hmms(features: str, n_states: int, stay_weight: float):
        from hoap_actions.primitives.baselines.class_hmms import ClassHMMs

        X = np.concatenate([rc.hmm_features(H, fps, features) for H in H_train])
        started = time.perf_counter()
        model = ClassHMMs(n_states=n_states, n_iter=args.hmm_iter, stay_weight=stay_weight).fit(X, lengths, labels)
        return model, time.perf_counter() - started

    def fit_classifier(offsets: tuple[int, ...], **decoding):
        from hoap_actions.primitives.baselines.frame_classifier import FrameClassifier

        X = np.concatenate([rc.classifier_features(H, fps) for H in H_train])
        started = time.perf_counter()
        model = FrameClassifier(offsets=offsets, max_iter=args.clf_iter, train_stride=args.clf_stride,
                                n_threads=args.jobs, **decoding).fit(X, lengths, labels)
        return model, time.perf_counter() - started

    if args.validate:
        document = validate(args, models, held_out, fit_hmms, fit_classifier, fps)
        write_json(args.output if args.output != RESULTS / "recognition_baselines.json"
                   else RESULTS / "recognition_baselines_validation.json", document)
        return document

    hmms, hmm_fit_s = fit_hmms(args.hmm_features, args.hmm_states, args.hmm_stay_weight)
    print(f"{HMMS}: fitted in {hmm_fit_s:.0f} s")
    decoding = {"smoothing": args.clf_smoothing, "smoothing_window": args.clf_window,
                "emission_weight": args.clf_weight}
    classifier, clf_fit_s = fit_classifier(tuple(args.clf_offsets), **decoding)
    print(f"{CLASSIFIER}: fitted in {clf_fit_s:.0f} s")

    from hoap_actions.primitives.baselines.frame_labels import recording_scores
    from hoap_actions.primitives.pipelines.recognize import recognize_recording

    per_recording: dict = {PROJECT: {}, NO_VOTE: {}, HMMS: {}, CLASSIFIER: {}}
    per_episode: dict = {name: {} for name in per_recording}
    timeline_labels = {}
    for seed, (demos, movements, truth) in held_out.items():
        official = recognize_recording(models, demos, jobs=args.jobs, oracle=True, progress=True)
        project = rc.project_labels(models, movements, truth)
        figures = recording_scores(project["scores"])
        for name in ("frame_accuracy", "segment_accuracy", "edit_score"):  # the same labels, scored twice
            assert abs(figures[name] - official[name]) < 1e-12, (name, figures[name], official[name])
        per_recording[PROJECT][seed] = {**{k: official[k] for k in FIGURES},
                                        "phi_error_median_m": official["phi_error_median_m"],
                                        "oracle_cut_phi_error_median_m": official["oracle_cut_phi_error_median_m"],
                                        "recognise_s": project["recognise_s"], "wall_s": official["wall_s"],
                                        "movement_s": official["movement_s"]}
        runs = {PROJECT: project, NO_VOTE: without_vote(models, movements, truth),
                HMMS: rc.run_baseline(hmms, functools.partial(rc.hmm_features, fps=fps, features=args.hmm_features),
                                      movements, truth),
                CLASSIFIER: rc.run_baseline(classifier, functools.partial(rc.classifier_features, fps=fps), movements,
                                            truth)}
        for name in (NO_VOTE, HMMS, CLASSIFIER):
            per_recording[name][seed] = {"oracle_cut_accuracy": None, **recording_scores(runs[name]["scores"]),
                                         "phi_error_median_m": None, "recognise_s": runs[name]["recognise_s"],
                                         "cuts_s": runs[name].get("cuts_s"), "movement_s": official["movement_s"]}
        for name, run in runs.items():
            per_episode[name][seed] = [{"frame_accuracy": s["frames_right"] / max(s["frames"], 1), "edit": s["edit"]}
                                       for s in run["scores"]]
            print(f"seed {seed} {name}: " + ", ".join(f"{k} {per_recording[name][seed][k]:.4f}" for k in FIGURES
                                                      if per_recording[name][seed][k] is not None))
        if not timeline_labels:
            shown = args.timeline_episodes
            timeline_labels = {"seed": seed, "truth": [truth[i] for i in shown],
                               **{name: [run["labels"][i] for i in shown] for name, run in runs.items()}}

    summary = {name: {k: spread([r[k] for r in recordings.values()])
                      for k in (*FIGURES, "recognise_s", "phi_error_median_m")
                      if all(r[k] is not None for r in recordings.values())}
               for name, recordings in per_recording.items()}
    paired = {f"{a} - {b}": paired_differences(per_recording, per_episode, a, b)
              for a, b in ((PROJECT, HMMS), (PROJECT, CLASSIFIER), (NO_VOTE, HMMS))}
    best = {k: max((PROJECT, HMMS, CLASSIFIER), key=lambda name: summary[name][k]["mean"]) for k in FIGURES}
    for name, s in summary.items():
        print(f"{name:>38}: " + ", ".join(f"{k} {s[k]['mean']:.4f} [{s[k]['ci95'][0]:.4f}, {s[k]['ci95'][1]:.4f}]"
                                          for k in FIGURES if k in s))
    print("best: " + ", ".join(f"{k} {name}" for k, name in best.items()))

    timeline = {
        "title": f"paper recording {timeline_labels['seed']}, episodes {args.timeline_episodes} (held out)",
        "fps": fps, "kinds": {str(c.primitive_id): c.kind for c in models.discovery_.classes_},
        "episode_starts": np.cumsum([0] + [len(t) for t in timeline_labels["truth"]])[:-1].tolist(),
        "rows": {"true (discovery, from the object)": rc.timeline_runs(timeline_labels["truth"]),
                 **{name: rc.timeline_runs(timeline_labels[name]) for name in per_recording}},
    }
    figure = args.output.with_suffix(".png")
    rc.plot_timeline(timeline, figure)
    print(f"wrote {figure}")
    import hmmlearn
    import sklearn

    document = {
        "protocol": {"train_seeds": args.train_seeds, "test_seeds": args.test_seeds, "preset": "paper",
                     "validation_seeds": args.validation_seeds, "models": str(models_path),
                     "labels": "discovery's classes of the training recordings (the models' discovery_)",
                     "effect_error": "the project's method only: the baselines estimate no effect"},
        "params": {PROJECT: models.get_params(), HMMS: {**hmms.get_params(), "features": args.hmm_features},
                   CLASSIFIER: {**classifier.get_params(), "features": "marker_frame_features (shoulder-relative)"}},
        "fit_s": {PROJECT: "shipped models (learned once, not timed here)", HMMS: hmm_fit_s, CLASSIFIER: clf_fit_s},
        "per_recording": per_recording,
        "summary": summary,
        "paired_differences": paired,
        "best": best,
        "timeline": timeline,
        "environment": numeric_environment(blas_threads=None, hmmlearn=hmmlearn.__version__,
                                           sklearn=sklearn.__version__),
    }
    write_json(args.output, document)
    return document


def without_vote(models, movements: list, truth: list) -> dict:
    """Connected recognition of the movements with the object's vote off (the models' own vote restored)."""
    from hoap_actions.primitives.baselines import recognition_comparison as rc

    vote = models.object_vote
    models.set_params(object_vote=0.0)
    try:
        return rc.project_labels(models, movements, truth)
    finally:
        models.set_params(object_vote=vote)


def paired_differences(per_recording: dict, per_episode: dict, first: str, second: str) -> dict:
    """Method ``first``'s figures minus ``second``'s: per recording (mean and 95 % interval over the
    recordings) and, for frame accuracy and edit score, per episode (over every held-out episode)."""
    recordings = per_recording[first]
    shared = [k for k in FIGURES
              if all(per_recording[m][s][k] is not None for m in (first, second) for s in recordings)]
    out = {k: spread([recordings[s][k] - per_recording[second][s][k] for s in recordings]) for k in shared}
    for k in ("frame_accuracy", "edit"):
        diffs = [a[k] - b[k] for s in recordings for a, b in zip(per_episode[first][s], per_episode[second][s])]
        out[f"per_episode_{k}"] = {key: value for key, value in spread(diffs).items() if key != "values"}
    return out


def validate(args: argparse.Namespace, models, held_out: dict, fit_hmms, fit_classifier, fps: float) -> dict:
    """Every candidate setting of each baseline on the validation recordings, the project's method beside them."""
    import numpy as np

    from hoap_actions.primitives.baselines import recognition_comparison as rc
    from hoap_actions.primitives.baselines.frame_labels import episode_scores, recording_scores

    def scored(method=None, features=None, vote: bool = True) -> dict:
        """The project's method (``method`` None; ``vote``: with the object's) or a fitted baseline reading
        ``features`` of the markers."""
        figures = {}
        for seed, (_, movements, truth) in held_out.items():
            run = ((rc.project_labels if vote else without_vote)(models, movements, truth) if method is None
                   else rc.run_baseline(method, features, movements, truth, cuts=False))
            figures[seed] = recording_scores(run["scores"])
        return {"per_recording": figures, **{k: float(sum(f[k] for f in figures.values()) / len(figures))
                                             for k in ("frame_accuracy", "segment_accuracy", "edit_score")}}

    results = {PROJECT: scored(), NO_VOTE: scored(vote=False), HMMS: [], CLASSIFIER: []}
    for name in (PROJECT, NO_VOTE):
        print(f"{name}: edit {results[name]['edit_score']:.4f}, frames {results[name]['frame_accuracy']:.4f}")
    for fit in HMM_FITS:
        model, fit_s = fit_hmms(fit["features"], fit["n_states"], 1.0)
        for decoding in HMM_DECODING:
            model.set_params(**decoding)
            setting = {**fit, **decoding}
            row = {"setting": setting, "fit_s": fit_s,
                   **scored(model, functools.partial(rc.hmm_features, fps=fps, features=fit["features"]))}
            results[HMMS].append(row)
            print(f"{HMMS} {setting}: edit {row['edit_score']:.4f}, frames {row['frame_accuracy']:.4f}, "
                  f"fit {fit_s:.0f} s")
    for fit in CLASSIFIER_FITS:
        model, fit_s = fit_classifier(fit["offsets"])
        probabilities = {seed: [model.predict_proba(rc.classifier_features(H, fps)) for H in movements]
                         for seed, (_, movements, _) in held_out.items()}  # classified once, smoothed each way
        for decoding in CLASSIFIER_DECODING:
            model.set_params(**decoding)
            setting = {"offsets": list(fit["offsets"]), **decoding}
            figures = {seed: recording_scores([episode_scores(model.smooth(p), t) for p, t in
                                               zip(probabilities[seed], held_out[seed][2])]) for seed in held_out}
            row = {"setting": setting, "fit_s": fit_s, "per_recording": figures,
                   **{k: float(np.mean([f[k] for f in figures.values()])) for k in ("frame_accuracy",
                                                                                   "segment_accuracy", "edit_score")}}
            results[CLASSIFIER].append(row)
            print(f"{CLASSIFIER} {setting}: edit {row['edit_score']:.4f}, frames {row['frame_accuracy']:.4f}, "
                  f"fit {fit_s:.0f} s")
    chosen = {name: max(results[name], key=lambda r: (r["edit_score"], r["frame_accuracy"]))["setting"]
              for name in (HMMS, CLASSIFIER)}
    print(f"chosen: {chosen}")
    return {"protocol": {"train_seeds": args.train_seeds, "validation_seeds": args.validation_seeds,
                         "criterion": "mean edit score over the validation recordings, then frame accuracy",
                         "hmm_iter": args.hmm_iter, "clf_iter": args.clf_iter, "clf_stride": args.clf_stride},
            "results": results, "chosen": chosen, "environment": numeric_environment(blas_threads=None)}


if __name__ == "__main__":
    main()
