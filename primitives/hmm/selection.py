"""Choosing a parametric HMM's hyper-parameters from its training data alone, by cross-validation.

Two rules: the number of states by held-out log-likelihood (:func:`select_n_states`), and the mean
model (linear or bending, and its smoothing) by the paper's criterion, "the accuracy of the trained
PHMM in resynthesizing the demonstrations" (:func:`select_mean_model`): each fold's demonstrations are
synthesised at their own effects by a model that never saw them.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.hmm.effect_features import effect_groups
from hoap_actions.primitives.hmm.hmm_math import validate_sequences
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.phmm_batch import check_train_phi
from hoap_actions.primitives.trajectory_metrics import warped_rms_error

__all__ = ["MeanModelSelection", "NStatesSelection", "select_mean_model", "select_n_states"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class NStatesSelection:
    """Result of :func:`select_n_states`: the chosen state count and the held-out log-likelihood per frame of each."""

    n_states: int
    scores: Mapping[int, float]


@dataclass(frozen=True)
class MeanModelSelection:
    """Result of :func:`select_mean_model`: the best candidate, each candidate's cross-validated
    resynthesis error (RMS over held-out demonstrations of eq. (5), data units), and the folds used."""

    best: dict
    errors: tuple[float, ...]
    candidates: tuple[dict, ...]
    n_folds: int


def _split(X: np.ndarray, lengths: np.ndarray) -> list[np.ndarray]:
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    return [X[a:a + n] for a, n in zip(starts, lengths)]


def select_n_states(X, lengths, phi, candidates: Sequence[int], n_folds: int = 3,
                    random_state: int | np.random.Generator | None = None,
                    **model_kwargs) -> NStatesSelection:
    """Choose ``n_states`` by cross-validation: mean held-out log-likelihood per frame (at the true effects).

    Sequences are split into ``n_folds`` folds at random; ``model_kwargs`` go to :class:`ParametricHMM`.
    Candidates that a fold cannot train (too few frames or effects) score ``-inf``.
    """
    X, lengths = validate_sequences(X, lengths)
    phi = check_train_phi(phi, lengths.size)
    cands = list(candidates)
    if not cands or not all(isinstance(c, (int, np.integer)) and not isinstance(c, bool) and c >= 1 for c in cands):
        raise InvalidInputError(f"candidates must be a non-empty list of ints >= 1; got {candidates!r}")
    if not isinstance(n_folds, (int, np.integer)) or not 2 <= n_folds <= lengths.size:
        raise InvalidInputError(f"n_folds must be an int in [2, n_sequences={lengths.size}]; got {n_folds!r}")
    rng = np.random.default_rng(random_state)
    folds = np.array_split(rng.permutation(lengths.size), int(n_folds))
    seqs = _split(X, lengths)
    scores: dict[int, float] = {}
    for k in map(int, cands):
        total, frames = 0.0, 0
        for held in folds:
            train = np.setdiff1d(np.arange(lengths.size), held)
            model = ParametricHMM(n_states=k, **model_kwargs)
            try:
                model.fit(np.concatenate([seqs[i] for i in train]), lengths[train], phi[train])
                total += sum(model.score(seqs[i], phi[i]) for i in held)
            except InvalidInputError as exc:
                logger.info("n_states=%d: fold not usable (%s)", k, exc)
                total = -math.inf
                break
            frames += int(lengths[held].sum())
        scores[k] = total / frames if frames else -math.inf
        logger.debug("n_states=%d: held-out log-likelihood per frame %.4f", k, scores[k])
    best = max(scores, key=scores.__getitem__)
    if not np.isfinite(scores[best]):
        raise InvalidInputError("no candidate n_states could be cross-validated (sequences too short or "
                                "too few effects per fold)")
    return NStatesSelection(n_states=best, scores=scores)


def select_mean_model(X, lengths, phi, candidates: Sequence[Mapping], n_folds: int = 5,
                      random_state: int | np.random.Generator | None = None, point_dim: int = 3,
                      estimator: type = ParametricHMM, **model_kwargs) -> MeanModelSelection:
    """Choose among ``candidates`` (keyword sets such as ``{"mean_model": "tps", "smoothing": 0.1}``) by
    cross-validated resynthesis error of held-out demonstrations.

    Demonstrations of one effect (repetitions at one location) stay in one fold, so every held-out
    effect is new to the model that synthesises it: the error measures interpolation between effects,
    the job a mean model does. Each held-out demonstration is compared with the synthesis at its own
    effect by eq. (5) (:func:`~hoap_actions.primitives.trajectory_metrics.warped_rms_error`, ``point_dim``
    coordinates per point); a candidate's score is the RMS over all held-out demonstrations. A candidate a
    fold cannot train scores ``inf``. ``model_kwargs`` (e.g. ``n_states``) go to every model. ``estimator``:
    the class chosen for; any with ``_check_params()``, ``fit(X, lengths, phi)`` and ``synthesize(phi)`` (the
    synthesis baselines of :mod:`hoap_actions.primitives.baselines`) is chosen by the same rule.
    """
    X, lengths = validate_sequences(X, lengths)
    phi = check_train_phi(phi, lengths.size)
    cands = [dict(c) for c in candidates]
    if not cands:
        raise InvalidInputError("candidates must hold at least one keyword set for ParametricHMM, e.g. "
                                "[{'mean_model': 'linear'}, {'mean_model': 'tps', 'smoothing': 0.1}]")
    groups = effect_groups(phi)
    n_groups = int(groups.max()) + 1
    if not isinstance(n_folds, (int, np.integer)) or isinstance(n_folds, bool) or not 2 <= n_folds <= n_groups:
        raise InvalidInputError(f"n_folds must be an int in [2, {n_groups}] (the number of distinct effects: "
                                f"repetitions of one effect stay in one fold); got {n_folds!r}")
    for candidate in cands:  # bad keywords fail here, before any training
        estimator(**{**model_kwargs, **candidate})._check_params()
    rng = np.random.default_rng(random_state)
    folds = np.array_split(rng.permutation(n_groups), int(n_folds))
    seqs = _split(X, lengths)
    errors: list[float] = []
    for candidate in cands:
        squared: list[float] = []
        for held_groups in folds:
            held = np.flatnonzero(np.isin(groups, held_groups))
            train = np.setdiff1d(np.arange(lengths.size), held)
            model = estimator(**{**model_kwargs, **candidate})
            try:
                model.fit(np.concatenate([seqs[i] for i in train]), lengths[train], phi[train])
            except InvalidInputError as exc:
                logger.info("%s: fold not usable (%s)", candidate, exc)
                squared = [math.inf]
                break
            for i in held:
                squared.append(warped_rms_error(model.synthesize(phi[i]), seqs[i], point_dim) ** 2)
        errors.append(float(np.sqrt(np.mean(squared))))
        logger.debug("%s: cross-validated resynthesis error %.4g", candidate, errors[-1])
    best = int(np.argmin(errors))
    if not np.isfinite(errors[best]):
        raise InvalidInputError("no candidate could be cross-validated (too few effects per fold for the mean "
                                "models: use fewer folds or a smaller feature set)")
    return MeanModelSelection(best=cands[best], errors=tuple(errors), candidates=tuple(cands), n_folds=int(n_folds))
