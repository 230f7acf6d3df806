"""One hmmlearn ``GaussianHMM`` per discovered class, joined by the action grammar and decoded with the
project's connected Viterbi: the textbook recogniser a reader compares connected recognition with.

Each class's runs in the training labels train a left-right Gaussian HMM with hmmlearn's EM (diagonal
covariances; the chain starts in its first state; means and variances start from each run cut into
equal parts, so nothing is drawn at random). Features are standardised on the training frames first,
so that hmmlearn's ``min_covar`` is a fraction of each feature's spread. The chains are joined exactly as
connected recognition joins the PHMMs (:class:`~hoap_actions.primitives.models.connected_recognition.ChainedHMM`):
leaving a chain's last state (probability measured on the class's training runs aligned to its chain,
as :func:`~hoap_actions.primitives.models.connected_recognition.exit_probability` does) enters the first
state of a class the grammar allows next. What differs from the project's method is the emission model
alone: one fixed Gaussian per state, where a PHMM's state means move with the effect.

hmmlearn is an optional dependency (``pip install "hoap-actions[bench]"``), imported when a model is fitted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.baselines.frame_labels import (
    check_frames,
    check_labels,
    class_runs,
    decode_cuts,
    estimator_params,
    sequence_bounds,
    set_estimator_params,
)
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.models.connected_recognition import ChainedHMM

__all__ = ["TRANSITION_PSEUDO_COUNT", "ClassHMMs", "import_hmmlearn"]

TRANSITION_PSEUDO_COUNT = 1e-3
"""Dirichlet pseudo-count on each allowed transition (stay, advance) in EM: without it a last state that
every training run leaves after one frame gets a row of zeros, and EM's next step NaN parameters (seen
with 20 states on the ``paper`` classes)."""


def import_hmmlearn():
    """hmmlearn's ``hmm`` module, or an error saying how to install it."""
    try:
        from hmmlearn import hmm
    except ImportError:
        raise InvalidInputError('the per-class HMM baseline needs hmmlearn: '
                                'pip install "hoap-actions[bench]"') from None
    return hmm


class ClassHMMs:
    """Recognise classes frame by frame with one left-right ``GaussianHMM`` per class and the grammar.

    Parameters
    ----------
    n_states
        states per class (fewer for a class whose shortest training run has fewer frames).
    n_iter, tol
        hmmlearn's EM iterations and convergence threshold (log-likelihood gain).
    min_covar
        hmmlearn's floor on the variances, in units of the standardised features.
    stay_weight
        power on the self-transition probabilities when decoding, as connected recognition's.
    unexplained_penalty
        nats a class pays for a cut piece shorter than its chain (:meth:`predict_segments`; ``None``: ruled out).

    Attributes
    ----------
    class_ids_
        (C,) the classes, sorted.
    hmms_
        dict class id -> fitted ``hmmlearn.hmm.GaussianHMM`` (on standardised features).
    exit_probabilities_
        (C,) per-frame probability of leaving each chain's last state.
    grammar_
        :class:`ActionGrammar` of the class runs' order in the training sequences.
    chained_
        :class:`ChainedHMM`: the chains joined by the grammar (what :meth:`predict` decodes with).
    mean_, scale_
        (D,) the standardisation of the features.
    """

    _learned = ("class_ids_", "hmms_", "exit_probabilities_", "grammar_", "chained_", "mean_", "scale_")

    def __init__(self, n_states: int = 10, n_iter: int = 20, tol: float = 1e-2, min_covar: float = 1e-3,
                 stay_weight: float = 1.0, unexplained_penalty: float | None = 1000.0) -> None:
        self.n_states = n_states
        self.n_iter = n_iter
        self.tol = tol
        self.min_covar = min_covar
        self.stay_weight = stay_weight
        self.unexplained_penalty = unexplained_penalty

    def get_params(self) -> dict:
        """The hyper-parameters as given to ``__init__``."""
        return estimator_params(self)

    DECODING_PARAMS = ("stay_weight", "unexplained_penalty")
    """Hyper-parameters only recognition reads: a fitted model takes new values of these (:meth:`set_params`)."""

    def set_params(self, **params: object) -> ClassHMMs:
        """Set hyper-parameters (a fitted model: :data:`DECODING_PARAMS` only) and return ``self``."""
        set_estimator_params(self, params, self.DECODING_PARAMS)
        if hasattr(self, "chained_") and "stay_weight" in params:
            self.chained_ = self._chain()
        return self

    def _check_params(self) -> None:
        for name in ("n_states", "n_iter"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise InvalidInputError(f"{name} must be an int >= 1; got {value!r}")
        for name in ("tol", "min_covar", "stay_weight"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not (np.isfinite(value) and value > 0):
                raise InvalidInputError(f"{name} must be a positive number; got {value!r}")
        penalty = self.unexplained_penalty
        if penalty is not None and (isinstance(penalty, bool) or not isinstance(penalty, (int, float))
                                    or not (np.isfinite(penalty) and penalty >= 0)):
            raise InvalidInputError(f"unexplained_penalty must be a number of nats >= 0 or None; got {penalty!r}")

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None, labels: np.ndarray | None = None
            ) -> ClassHMMs:
        """Fit one chain per class on its runs of ``labels`` (N,) (class ids; -1: a frame of no class, left
        out) in the features ``X`` (N, D), ``lengths`` frames per sequence (``None``: one), and the grammar."""
        hmm = import_hmmlearn()
        self._check_params()
        X, bounds = check_frames(X, lengths)
        labels = check_labels(labels, len(X))
        self.mean_ = X.mean(axis=0)
        self.scale_ = np.maximum(X.std(axis=0), 1e-12)
        Z = (X - self.mean_) / self.scale_
        pieces, sequences = class_runs(labels, bounds)
        self.class_ids_ = np.array(sorted(pieces), dtype=np.int64)
        self.hmms_ = {c: self._fit_class(hmm, [Z[a:b] for a, b in pieces[c]]) for c in self.class_ids_.tolist()}
        self.exit_probabilities_ = np.array([self._exit_probability(c, [Z[a:b] for a, b in pieces[c]])
                                             for c in self.class_ids_.tolist()])
        self.grammar_ = ActionGrammar(0.0).fit(sequences)
        self.chained_ = self._chain()
        return self

    def _fit_class(self, hmm, runs: list[np.ndarray]):
        """A left-right GaussianHMM on one class's runs, started from the runs cut into equal parts."""
        n = int(min(self.n_states, min(len(r) for r in runs)))
        parts = [np.concatenate([r[k * len(r) // n:(k + 1) * len(r) // n] for r in runs]) for k in range(n)]
        mean_length = np.mean([len(r) for r in runs])
        stay = float(np.clip(1.0 - n / mean_length, 0.0, 0.99)) if n > 1 else 1.0
        allowed = np.eye(n) + np.eye(n, k=1)
        model = hmm.GaussianHMM(n_components=n, covariance_type="diag", min_covar=self.min_covar, n_iter=self.n_iter,
                                tol=self.tol, params="tmc", init_params="", implementation="log",
                                transmat_prior=1.0 + TRANSITION_PSEUDO_COUNT * allowed)
        model.startprob_ = np.eye(n)[0]
        model.transmat_ = np.eye(n) * stay + np.eye(n, k=1) * (1.0 - stay)
        model.transmat_[-1, -1] = 1.0
        model.means_ = np.array([p.mean(axis=0) for p in parts])
        model.covars_ = np.array([p.var(axis=0) for p in parts]) + self.min_covar
        return model.fit(np.concatenate(runs), [len(r) for r in runs])

    def _exit_probability(self, class_id: int, runs: list[np.ndarray]) -> float:
        """Runs / frames the class's chain aligns to its last state: the ML estimate of a geometric duration."""
        model = self.hmms_[class_id]
        states = model.predict(np.concatenate(runs), [len(r) for r in runs])
        return float(min(1.0, len(runs) / max(int(np.sum(states == model.n_components - 1)), 1)))

    def _chain(self) -> ChainedHMM:
        """The fitted chains joined by the grammar, as connected recognition joins the PHMMs."""
        models = [self.hmms_[c] for c in self.class_ids_.tolist()]
        sizes = np.array([m.n_components for m in models])
        first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        last = first + sizes - 1
        with np.errstate(divide="ignore"):
            log_stay = np.log(np.concatenate([np.diagonal(m.transmat_) for m in models]))
            log_stay[last] = np.log1p(-self.exit_probabilities_)
            log_next = np.log(np.concatenate([np.append(np.diagonal(m.transmat_, offset=1), 0.0) for m in models]))
            symbols = {int(s): i + 1 for i, s in enumerate(self.grammar_.symbols_)}
            index = np.array([symbols[int(c)] for c in self.class_ids_])
            log_a = np.log(self.grammar_.transmat_)
            return ChainedHMM(
                class_ids=self.class_ids_, state_class=np.repeat(np.arange(len(models)), sizes), first=first,
                last=last, log_stay=self.stay_weight * log_stay, log_next=log_next,
                log_exit=np.log(self.exit_probabilities_), log_start=log_a[0, index],
                log_end=log_a[index, len(log_a) - 1], log_grammar=log_a[np.ix_(index, index)],
                means=np.concatenate([m.means_ for m in models]),
                variances=np.concatenate([np.diagonal(m.covars_, axis1=1, axis2=2) for m in models]))

    def log_emissions(self, X: np.ndarray) -> np.ndarray:
        """Log-density of every frame of ``X`` (T, D) under every state of the joined chains, (T, S)."""
        check_is_fitted(self)
        X, _ = check_frames(X, None, self.mean_.size)
        return self.chained_.log_emissions((X - self.mean_) / self.scale_)

    def predict(self, X: np.ndarray, lengths: Sequence[int] | None = None) -> np.ndarray:
        """Each frame's class id (N,) by Viterbi over the joined chains, sequence by sequence; -1 over a
        sequence no grammatical path explains."""
        check_is_fitted(self)
        X, bounds = check_frames(X, lengths, self.mean_.size)
        out = np.full(len(X), -1, dtype=np.int64)
        for a, b in bounds:
            path, score = self.chained_.viterbi(self.log_emissions(X[a:b]))
            if np.isfinite(score):
                out[a:b] = self.class_ids_[path]
        return out

    def predict_segments(self, X: np.ndarray, cuts: Sequence[tuple[int, int]]) -> np.ndarray:
        """The class of each consecutive piece ``[start, end)`` of one sequence ``X`` (T, D) with its cuts
        given: each class's chain scores each piece on its own (best path from its first to its last
        state), then the grammar picks the sequence of classes (:meth:`ActionGrammar.decode`)."""
        check_is_fitted(self)
        logb = self.log_emissions(X)
        scores = [dict(zip(self.class_ids_.tolist(), self.chained_.class_scores(logb[a:b]).tolist()))
                  for a, b in sequence_bounds(cuts, len(logb))]
        return decode_cuts(self.grammar_, scores, self.unexplained_penalty)

