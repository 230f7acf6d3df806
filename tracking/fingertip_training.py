"""Training windows for the fingertip detector, cut from rendered demonstrations whose markers give the truth.

Each sampled frame is rendered from every camera; its window is centred on the true index tip moved by a random
3-D offset (the tracker's estimate is about that far off, ``spread_m``), and labelled with the true tip's pixel
offset from the window's centre. The detector ships trained on recordings the tracker is never scored on again
(:data:`TRAINING_SEEDS`); rebuild it, recording what is missing under ``--data``::

    python -m hoap_actions.tracking.fingertip_training --data data --out vision/fingertip_detector.npz --overwrite

``fingertip_detector.json`` beside it records the recordings, the settings and the file's SHA-256.
"""

from __future__ import annotations

import argparse
import hashlib
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hoap_actions.demonstration.datasets import Demonstrations
from hoap_actions.demonstration.scene import DEMONSTRATOR_CAMERA, DEMONSTRATOR_SIDE_CAMERA
from hoap_actions.envs.camera import Camera
from hoap_actions.errors import DataExistsError, InvalidInputError
from hoap_actions.outputs import check_output_path, claimed_file
from hoap_actions.tracking.episode import render_frames
from hoap_actions.vision.fingertip import FingertipDetector, windows

__all__ = ["TRAINING_SEEDS", "TRAINING_VIEWS", "build_fingertip_detector", "fingertip_windows"]

TRAINING_PRESET = "paper"
TRAINING_SEEDS = (388, 389, 390, 391)  # recordings of earlier held-out tracking runs, never a held-out one again
WINDOW_SETTINGS = {"every": 10, "spread_m": 0.02}
DETECTOR_SETTINGS = {"hidden": (256, 128), "alpha": 1e-3, "epochs": 30, "batch": 256, "learning_rate": 1e-3,
                     "random_state": 0}

TRAINING_VIEWS = (DEMONSTRATOR_CAMERA, DEMONSTRATOR_SIDE_CAMERA)
INDEX_TIP = "index_tip"


def fingertip_windows(demos: Demonstrations, every: int = 10, spread_m: float = 0.02, seed: int = 0,
                      views: Sequence[Camera] = TRAINING_VIEWS) -> tuple[np.ndarray, np.ndarray]:
    """Windows ``(n, 48, 48, 3)`` and the true fingertip's offsets ``(n, 2)`` (px) from their centres: every
    ``every``-th frame of every episode of ``demos``, each view, the window's centre the true tip moved by a
    Gaussian offset of ``spread_m`` (m) per axis (drawn from ``seed``); views that do not show the centre are
    left out."""
    if not (isinstance(every, int) and every >= 1 and np.isfinite(spread_m) and spread_m >= 0):
        raise InvalidInputError(f"every takes a whole number >= 1 and spread_m a spread >= 0 (m); got {every!r}, "
                                f"{spread_m!r}")
    if INDEX_TIP not in demos.marker_names:
        raise InvalidInputError(f"the recording has no {INDEX_TIP!r} marker (its markers: {list(demos.marker_names)})")
    tip_row = demos.marker_names.index(INDEX_TIP)
    rng = np.random.default_rng(seed)
    crops, offsets = [], []
    for episode in range(len(demos)):
        frames = range(0, demos[episode].T, every)
        rendered = render_frames(demos, episode, frames, camera=views[0], more_cameras=tuple(views[1:]))
        for images, t in zip(rendered.images, frames):
            truth = demos[episode].H[t][tip_row]
            guess = truth + rng.normal(0.0, spread_m, 3)
            for camera, image in zip(views, images):
                centre = camera.pixels(guess[None])[0]
                if not (0 <= centre[0] < camera.width and 0 <= centre[1] < camera.height):
                    continue
                crops.append(windows(image, centre[None])[0])
                offsets.append(camera.pixels(truth[None])[0] - np.rint(centre))
    return np.array(crops, dtype=np.float32), np.array(offsets)


def build_fingertip_detector(data: Path, out: Path, overwrite: bool = False) -> FingertipDetector:
    """Train the shipped detector on the :data:`TRAINING_SEEDS` recordings under ``data`` (recorded first where
    missing) and write it to ``out`` with its provenance (``<out>.json``)."""
    from hoap_actions.demonstration.datasets import load_demonstrations
    from hoap_actions.demonstration.recording import record

    out = Path(out)
    for target in (out, out.with_suffix(".json")):  # before the quarter of an hour of rendering and training
        check_output_path(target, "fingertip detector file")
        if target.exists() and not overwrite:
            raise DataExistsError(f"{target} exists; give another --out or --overwrite to replace it")
    crops, offsets = [], []
    for seed in TRAINING_SEEDS:
        path = Path(data) / f"{TRAINING_PRESET}-s{seed}.h5"
        if not path.exists():
            record(TRAINING_PRESET, path, seed=seed)
        windows_, offsets_ = fingertip_windows(load_demonstrations(path), seed=seed, **WINDOW_SETTINGS)
        crops.append(windows_)
        offsets.append(offsets_)
    detector = FingertipDetector(**DETECTOR_SETTINGS).fit(np.concatenate(crops), np.concatenate(offsets))
    detector.save(out, overwrite=overwrite)
    provenance = {"preset": TRAINING_PRESET, "seeds": list(TRAINING_SEEDS), "windows": WINDOW_SETTINGS,
                  "detector": {**DETECTOR_SETTINGS, "hidden": list(DETECTOR_SETTINGS["hidden"])},
                  "samples": int(sum(len(c) for c in crops)),
                  "sha256": hashlib.sha256(out.read_bytes()).hexdigest()}
    with claimed_file(out.with_suffix(".json"), overwrite, what="fingertip detector provenance") as partial:
        partial.write_text(json.dumps(provenance, indent=2) + "\n")
    return detector


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="train the fingertip detector the package ships")
    parser.add_argument("--data", type=Path, default=Path("data"), help="where the training recordings are (or go)")
    parser.add_argument("--out", type=Path, required=True, help="the detector file (.npz)")
    parser.add_argument("--overwrite", action="store_true")
    args = parser.parse_args(argv)
    build_fingertip_detector(args.data, args.out, args.overwrite)


if __name__ == "__main__":
    main()
