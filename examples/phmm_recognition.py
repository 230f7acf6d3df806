"""Recognise discovered primitives and their effects in a demonstration the models never saw.

Discovers primitives on one ``paper`` recording (from the object trajectories alone), trains one
parametric HMM per discovered class on the arm markers with the effects the discovery measured, then
cuts a held-out episode the way the discovery would and recognises each piece: which primitive, and
where it started and ended; then lets the action grammar learned from the training demonstrations
pick the most probable sequence of classes for the whole episode (:meth:`ActionGrammar.decode`), which
separates look-alike pieces such as the first and second few centimetres of one push.

    python examples/phmm_recognition.py --train data/paper-s0.h5 --test data/paper-s1.h5 [--record] [--episode 0]

The full evaluation is ``benchmarks/phmm_recognition.py``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.datasets import load_demonstrations
from hoap_actions.primitives.discovery import MANIPULATION, UNKNOWN, PrimitiveDiscovery
from hoap_actions.primitives.grammar import ActionGrammar
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.parametric_hmm import ParametricHMM, recognize


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--train", type=Path, default=Path("data/paper-s0.h5"))
    parser.add_argument("--test", type=Path, default=Path("data/paper-s1.h5"))
    parser.add_argument("--record", action="store_true", help="record missing datasets (paper preset, seeds 0 / 1)")
    parser.add_argument("--episode", type=int, default=0, help="held-out episode to recognise")
    args = parser.parse_args()
    for path, seed in ((args.train, 0), (args.test, 1)):
        if args.record and not path.exists():
            from hoap_actions.envs.recording import record

            record("paper", path, seed=seed)
    train, test = load_demonstrations(args.train), load_demonstrations(args.test)

    hands = np.concatenate([e.H.reshape(e.T, -1) for e in train])      # (N, 18): 6 markers x 3
    lengths = [e.T for e in train]                                      # frames per demonstration
    discovery = PrimitiveDiscovery().fit(np.concatenate([e.O for e in train]), lengths, hands)
    models, frames = {}, {}
    for cls in discovery.classes_:
        # phi = (initial, final) location; keep only the directions it varies in (the block stays on the table)
        effects = cls.phis
        centre = effects.mean(axis=0)
        _, sv, vt = np.linalg.svd(effects - centre, full_matrices=False)
        basis = vt[: int(min(np.sum(sv / np.sqrt(len(effects)) > 0.01), max(len(effects) - 2, 0)))].T
        X, segment_lengths = cls.movements(hands, lengths)
        model = ParametricHMM(n_states=min(40, min(segment_lengths)), covariance_type="diag", reg_covar=1e-5,
                              random_state=0)
        models[cls.primitive_id] = model.fit(X, segment_lengths, (effects - centre) @ basis)
        frames[cls.primitive_id] = (centre, basis)
    # the strict grammar: only the class transitions seen in the training demonstrations
    grammar = ActionGrammar().fit([[pid for pid, *_ in seg] for seg in discovery.segmentations_])
    print(f"{len(models)} primitive classes discovered in {len(train)} demonstrations")

    episode = test[args.episode]
    labels = discovery.predict(episode.O, [episode.T])[0]              # cut by the discovery, not by ground truth
    print(f"held-out episode {args.episode} ({episode.ground_truth.action} {episode.ground_truth.direction}):")
    expected_classes, results = [], []
    for expected, start, end in runs(labels):
        if expected == UNKNOWN:
            continue
        result = recognize(episode.H[start:end].reshape(end - start, -1), models)
        centre, basis = frames[result.label]
        initial, final = np.split(centre + basis @ result.phi, 2)
        kind = discovery.primitive_kinds_[expected]
        track = episode.O[:, :3] if kind == MANIPULATION else episode.H[:, discovery.hand_marker]
        print(f"  frames {start:4d}-{end:4d}: discovery says {expected:3d} ({kind}), recognised {result.label:3d}; "
              f"from {initial.round(3)} (true {track[start].round(3)}) to {final.round(3)} "
              f"(true {track[end - 1].round(3)})")
        expected_classes.append(expected)
        results.append(result)
    print(f"  discovery's classes:       {expected_classes}")
    print(f"  recognised one by one:     {[r.label for r in results]}")
    try:
        # a piece shorter than some class's chain scores -inf there; the penalty keeps those classes
        # possible at a cost instead of ruling out every grammatical path through them
        decoded, _ = grammar.decode([r.log_likelihoods for r in results], unexplained_penalty=1000.0)
        print(f"  decoded with the grammar:  {decoded}")
    except InvalidInputError:  # no sequence of this length was seen in training
        print("  decoded with the grammar:  none of the training sequences' transitions fits this episode")


if __name__ == "__main__":
    main()
