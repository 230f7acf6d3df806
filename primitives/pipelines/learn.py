"""The pipeline behind ``hoap-actions learn``: demonstrations in, a models directory out.

Discovery (or a fitted one from a ``discover`` folder) finds the primitive classes, then
:class:`~hoap_actions.primitives.models.action_models.ActionModels` fits one PHMM per class and the grammar.
The output directory is claimed before anything is read, so a bad path or an existing directory
fails in a second, not after the training.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hoap_actions.demonstration.datasets import Demonstrations, load_demonstrations
from hoap_actions.errors import InvalidInputError
from hoap_actions.outputs import claimed_directory
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.models.models_directory import foreign_entries
from hoap_actions.primitives.pipelines.mocap_cleaning import clean_demonstrations

logger = logging.getLogger(__name__)

__all__ = ["LearnSummary", "learn", "learn_to_dir", "load_training_demonstrations"]

DISCOVERY_MODEL_FILE = "model.json"  # the fitted discovery in a ``hoap-actions discover`` folder


@dataclass(frozen=True)
class LearnSummary:
    """What :func:`learn` made: the classes, their states, how well they fit, how long it took."""

    n_demonstrations: int
    n_frames: int
    n_classes: int
    n_states: int
    log_likelihood_per_frame: float
    discovery_s: float
    training_s: float

    def report(self) -> str:
        return (
            f"{self.n_classes} classes ({self.n_states} states in all) learned from {self.n_demonstrations} "
            f"demonstrations ({self.n_frames} frames): training log-likelihood {self.log_likelihood_per_frame:.1f} "
            f"nats per frame; discovery {self.discovery_s:.1f} s, PHMMs {self.training_s:.1f} s"
        )


def load_training_demonstrations(paths: Sequence[str | os.PathLike]) -> tuple[list, Demonstrations, list[dict]]:
    """The episodes of every file, in order (cleaned as their declared noise requires,
    :mod:`~hoap_actions.primitives.pipelines.mocap_cleaning`), and the first file's header; all files must share
    markers and frame rate (the models read one kind of recording); and who demonstrated in each file
    (:attr:`Demonstrations.demonstrator`)."""
    if not paths:
        raise InvalidInputError("give at least one demonstrations file (.h5, from `hoap-actions record`)")
    datasets = [clean_demonstrations(load_demonstrations(p)) for p in paths]
    first = datasets[0]
    for path, other in zip(paths[1:], datasets[1:]):
        if other.marker_names != first.marker_names or other.fps != first.fps:
            raise InvalidInputError(
                f"{path} has markers {list(other.marker_names)} at {other.fps} fps but {paths[0]} has "
                f"{list(first.marker_names)} at {first.fps} fps; learn from recordings of one kind"
            )
    return [episode for d in datasets for episode in d], first, [d.demonstrator for d in datasets]


def learn_to_dir(
    demos_paths: Sequence[str | os.PathLike],
    out_dir: str | os.PathLike,
    discovery_dir: str | os.PathLike | None = None,
    overwrite: bool = False,
    progress: bool = False,
    merging: str | None = None,
    **params: object,
) -> LearnSummary:
    """:func:`learn`, then write the models to the directory ``out_dir``, claimed before anything is read."""
    with claimed_directory(out_dir, overwrite, what="action models", foreign=foreign_entries) as staging:
        models, summary = learn(demos_paths, discovery_dir, progress, merging, **params)
        models.write_files(staging)
    logger.info("%s; wrote %s", summary.report(), out_dir)
    return summary


def learn(
    demos_paths: Sequence[str | os.PathLike],
    discovery_dir: str | os.PathLike | None = None,
    progress: bool = False,
    merging: str | None = None,
    **params: object,
) -> tuple[ActionModels, LearnSummary]:
    """Learn action models from the demonstrations in ``demos_paths``.

    ``discovery_dir``: a ``hoap-actions discover`` folder fitted on the same demonstrations (same
    files, same order), to skip discovery. ``merging``: :class:`PrimitiveDiscovery`'s (its default
    when ``None``); a ``discovery_dir`` fitted with another one is refused. ``params`` go to
    :class:`ActionModels`, checked before anything is read.
    """
    estimator = ActionModels(**params, progress=progress)
    estimator._check_params()  # a wrong hyper-parameter fails now, not after discovery's minutes
    episodes, header, demonstrators = load_training_demonstrations(list(demos_paths))
    lengths = [e.T for e in episodes]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in episodes])
    O = np.concatenate([e.O for e in episodes])
    started = time.perf_counter()
    if discovery_dir is None:
        discovery = PrimitiveDiscovery(**({} if merging is None else {"merging": merging})).fit(O, lengths, H)
    else:
        discovery = _matching_discovery(Path(discovery_dir), lengths)
        if merging is not None and discovery.merging != merging:
            raise InvalidInputError(f"the discovery in {discovery_dir} merged with {discovery.merging!r}, not the "
                                    f"{merging!r} asked for; give one of them, or a discovery made with {merging!r}")
    discovered = time.perf_counter()
    models = estimator.fit(H, lengths, discovery, header.fps, header.marker_names, O=O, demonstrators=demonstrators)
    trained = time.perf_counter()
    phmms = [m.phmm for m in models.classes_.values()]
    frames = sum(s.end - s.start for c in discovery.classes_ for s in c.segments)
    summary = LearnSummary(
        n_demonstrations=len(episodes),
        n_frames=int(sum(lengths)),
        n_classes=len(phmms),
        n_states=sum(p.n_states for p in phmms),
        log_likelihood_per_frame=float(sum(p.log_likelihood_history_[-1] for p in phmms) / frames),
        discovery_s=discovered - started,
        training_s=trained - discovered,
    )
    return models, summary


def _matching_discovery(folder: Path, lengths: list[int]) -> PrimitiveDiscovery:
    """The fitted discovery of a ``discover`` folder, checked to be of these demonstrations."""
    discovery = PrimitiveDiscovery.load(folder / DISCOVERY_MODEL_FILE if folder.is_dir() else folder)
    n = len(discovery.segmentations_)
    last_frames = [max((end for _, _, end in seg), default=0) for seg in discovery.segmentations_]
    if n != len(lengths) or any(end > length for end, length in zip(last_frames, lengths)):
        raise InvalidInputError(
            f"the discovery in {folder} was fitted on {n} demonstrations, not on these {len(lengths)}: "
            "give --discovery the folder `hoap-actions discover` wrote for the same --demos files, in the same order"
        )
    return discovery
