"""The action models shipped in the package: where they are, how they were made, how to make them again.

``paper``: learned (``hoap-actions learn`` defaults, plus the pose classes the tracker poses approach and
remove with and the hand modes it poses the arm by: :data:`LEARN_PARAMS`) from the ``paper`` preset recorded
with the seeds in :data:`TRAINING_SEEDS`. Rebuild from scratch (records what is missing under ``--data``)::

    python -m hoap_actions.models.shipped --data data --out models/paper --overwrite

``PROVENANCE.json`` beside the models records the preset, the seeds, the package version, the
SHA-256 of every training recording and of every model file, so a test can tell that what ships is
what this command made.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
from importlib.resources import files
from pathlib import Path

from hoap_actions import __version__
from hoap_actions.errors import DataFileError, HoapActionsError

__all__ = ["LEARN_PARAMS", "PROVENANCE", "TRAINING_PRESET", "TRAINING_SEEDS", "build_default_models",
           "default_models_path", "load_default_models"]

TRAINING_PRESET = "paper"
TRAINING_SEEDS = tuple(range(10))  # never 101-103, the held-out recordings of benchmarks/phmm_recognition.py
LEARN_PARAMS = {"pose_mean_model": "tps", "smoothing": 0.1, "pose_hand_modes": 4}
"""Beyond ``learn``'s defaults: approach and remove refitted with a thin-plate mean for the tracker (its
smoothing chosen on the tracker's validation recording), and every pose class refitted per way of holding the
hand (four modes; ``docs/experiments/tracking.md``)."""
PROVENANCE = "PROVENANCE.json"


def default_models_path() -> Path:
    """The shipped models directory."""
    return Path(str(files("hoap_actions.models").joinpath(TRAINING_PRESET)))


def load_default_models():
    """The shipped :class:`~hoap_actions.primitives.models.action_models.ActionModels`."""
    from hoap_actions.primitives.models.action_models import ActionModels

    path = default_models_path()
    if not (path / PROVENANCE).is_file():
        raise DataFileError(f"the package holds no default models at {path}; reinstall hoap-actions, or give --models")
    return ActionModels.load(path)


def sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def build_default_models(out: str | os.PathLike, data: str | os.PathLike, overwrite: bool = False,
                         pose_hand_modes: int | None = None) -> Path:
    """Record the training recordings missing under ``data``, learn the models, write them and their
    provenance to ``out`` (claimed before anything is recorded). ``pose_hand_modes``: how many hand modes to
    learn (None: as shipped, :data:`LEARN_PARAMS`; 0: none, the models before them)."""
    from hoap_actions.demonstration.recording import record
    from hoap_actions.outputs import claimed_directory
    from hoap_actions.primitives.models.action_models import ActionModels
    from hoap_actions.primitives.pipelines.learn import learn

    params = {**LEARN_PARAMS, **({} if pose_hand_modes is None else {"pose_hand_modes": pose_hand_modes})}
    ActionModels(**params)._check_params()  # a wrong count fails now, not after the recordings
    out = Path(out)
    with claimed_directory(out, overwrite, what="default models") as staging:
        recordings = []
        for seed in TRAINING_SEEDS:
            path = Path(data) / f"{TRAINING_PRESET}-s{seed}.h5"
            if not path.exists():
                record(TRAINING_PRESET, path, seed=seed)
            recordings.append(path)
        models, summary = learn(recordings, progress=True, **params)
        models.write_files(staging)
        provenance = {
            "preset": TRAINING_PRESET,
            "seeds": list(TRAINING_SEEDS),
            "learn_params": params,
            "hoap_actions_version": __version__,
            "command": "python -m hoap_actions.models.shipped --data DATA --out OUT",
            "recordings_sha256": {p.name: sha256(p) for p in recordings},
            "files_sha256": {p.name: sha256(p) for p in sorted(staging.iterdir())},
            "classes": summary.n_classes,
            "states": summary.n_states,
        }
        (staging / PROVENANCE).write_text(json.dumps(provenance, indent=1) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hoap_actions.models.shipped", description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=Path("data"), help="where the training recordings are (or go)")
    parser.add_argument("--out", type=Path, required=True, help="models directory to write (e.g. models/paper)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing directory at --out")
    parser.add_argument("--pose-hand-modes", type=int, default=None,
                        help=f"how many hand modes to learn for the tracker (default, as shipped: "
                             f"{LEARN_PARAMS['pose_hand_modes']}; 0: none)")
    args = parser.parse_args(argv)
    try:
        print(f"wrote {build_default_models(args.out, args.data, args.overwrite, args.pose_hand_modes)}")
    except HoapActionsError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
