"""The action grammar: a probabilistic finite-state automaton over primitive classes.

Learned from the primitive-class sequences of the demonstrations (e.g. approach -> {push, move,
rotate} -> remove). The automaton's states are the classes plus ``<start>`` and ``<end>``; being in
state ``c`` means class ``c`` was performed last, so the transition probabilities are the relative
counts of class bigrams in the demonstrations (first-order Markov), with optional additive smoothing.

The *language* of the grammar is fixed by the transitions seen in training: :meth:`is_grammatical`
and :meth:`sample` use only those. Smoothing changes probabilities only (:meth:`log_probability`,
:meth:`next_distribution`), so a tracker can still follow an action it never saw after another.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.errors import DataFileError, InvalidInputError
from hoap_actions.primitives.base import Estimator, check_is_fitted
from hoap_actions.primitives.json_files import JsonModelFile, write_json_model

FORMAT_VERSION = 1
START, END = "<start>", "<end>"

Symbol = int | str  # a primitive class: an int id or a str name


class ActionGrammar(JsonModelFile, Estimator):
    """First-order probabilistic finite-state automaton over primitive classes.

    Parameters
    ----------
    smoothing:
        Additive (Lidstone) pseudo-count given to every possible transition (any class or
        ``<end>`` after a class, any class after ``<start>``); 0 gives maximum likelihood.

    Attributes (after ``fit`` or ``load``)
    --------------------------------------
    symbols_:
        The classes in order of first appearance; automaton state ``k + 1`` is ``symbols_[k]``.
    counts_, transmat_:
        ``(n + 2, n + 2)`` bigram counts and transition probabilities, ``<start>`` first, ``<end>`` last.
    n_sequences_:
        How many sequences it was fitted on.

    Saved as JSON (:meth:`save`, ``kind`` "ActionGrammar", ``format_version`` :data:`FORMAT_VERSION`):
    ``smoothing``, ``symbols``, ``counts`` and ``n_sequences``.
    """

    _learned = ("symbols_", "counts_", "n_sequences_", "transmat_")
    _file_kind = "ActionGrammar"
    _format_version = FORMAT_VERSION
    _readable_versions = (FORMAT_VERSION,)

    def __init__(self, smoothing: float = 0.0) -> None:
        self.smoothing = smoothing

    # -- fit

    def _check_params(self) -> None:
        if not (isinstance(self.smoothing, (int, float)) and np.isfinite(self.smoothing) and self.smoothing >= 0):
            raise InvalidInputError(f"smoothing must be a finite number >= 0, got {self.smoothing!r}")

    def fit(self, X: Sequence, lengths: Sequence[int] | None = None) -> ActionGrammar:
        """Count class bigrams (with ``<start>`` and ``<end>``) in the demonstrations' class sequences.

        ``X`` holds the sequences' classes concatenated, with ``lengths`` classes each; with ``lengths``
        ``None`` it is the list of sequences itself. Classes are ints or strs (numpy ints are taken as
        ints); each sequence needs >= 1 class.
        """
        self._check_params()
        cleaned = _check_sequences(X if lengths is None else _split_symbols(X, lengths))
        self.symbols_ = list(dict.fromkeys(s for seq in cleaned for s in seq))
        index = self._index()
        n = len(self.symbols_)
        counts = np.zeros((n + 2, n + 2))
        for seq in cleaned:
            path = [0, *(index[s] for s in seq), n + 1]
            np.add.at(counts, (path[:-1], path[1:]), 1.0)
        self.counts_ = counts
        self.n_sequences_ = len(cleaned)
        self.transmat_ = self._probabilities(counts)
        return self

    def _index(self) -> dict[Symbol, int]:
        """Automaton state of each class: 0 is ``<start>``, 1..n the classes, n + 1 ``<end>``."""
        return {s: k + 1 for k, s in enumerate(self.symbols_)}

    def _allowed(self, n: int) -> np.ndarray:
        """Transitions that can exist: from start or a class, to a class or end; not start -> end."""
        allowed = np.zeros((n + 2, n + 2), dtype=bool)
        allowed[: n + 1, 1:] = True
        allowed[0, n + 1] = False
        return allowed

    def _probabilities(self, counts: np.ndarray) -> np.ndarray:
        """Row-normalised counts plus ``smoothing`` on every possible transition (end row stays zero)."""
        smoothed = counts + self.smoothing * self._allowed(len(counts) - 2)
        totals = smoothed.sum(axis=1, keepdims=True)
        return np.divide(smoothed, totals, out=np.zeros_like(smoothed), where=totals > 0)

    # -- queries

    def _path(self, sequence: Sequence[Symbol]) -> list[int] | None:
        """Automaton states visited by ``sequence`` (start and end included); None if a class is unknown."""
        index = self._index()
        symbols = [_clean_symbol(s) for s in sequence]
        if any(s not in index for s in symbols):
            return None
        return [0, *(index[s] for s in symbols), len(self.symbols_) + 1]

    def is_grammatical(self, sequence: Sequence[Symbol]) -> bool:
        """True when every transition of ``<start> sequence <end>`` was seen in training."""
        check_is_fitted(self)
        path = self._path(sequence)
        return path is not None and len(path) > 2 and bool(np.all(self.counts_[path[:-1], path[1:]] > 0))

    def log_probability(self, sequence: Sequence[Symbol]) -> float:
        """Natural log of the (smoothed) probability of the whole sequence, end included; -inf if impossible."""
        check_is_fitted(self)
        path = self._path(sequence)
        if path is None or len(path) <= 2:
            return float("-inf")
        with np.errstate(divide="ignore"):
            return float(np.log(self.transmat_[path[:-1], path[1:]]).sum())

    def next_distribution(self, prefix: Sequence[Symbol] = ()) -> dict[Symbol, float]:
        """Probability of each class (and of ``END``, the sequence being over) after ``prefix``.

        Only the last class matters (first-order). Zero-probability entries are left out.
        """
        check_is_fitted(self)
        prefix = list(prefix)
        index = self._index()
        if prefix:
            last = _clean_symbol(prefix[-1])
            if last not in index:
                raise InvalidInputError(f"unknown class {last!r} in prefix; known classes: {self.symbols_}")
            row = self.transmat_[index[last]]
        else:
            row = self.transmat_[0]
        targets = [*self.symbols_, END]
        return {t: float(p) for t, p in zip(targets, row[1:]) if p > 0}

    def decode(self, segment_scores: Sequence[Mapping[Symbol, float]],
               unexplained_penalty: float | None = None,
               pair_scores: Sequence[Mapping[tuple[Symbol, Symbol], float]] | None = None,
               bonus: Sequence[Mapping[Symbol, float]] | None = None,
               ) -> tuple[list[Symbol], float]:
        """Most probable class sequence for consecutive segments, given each segment's class log-likelihoods.

        Maximises ``log P(sequence | grammar) + sum_i segment_scores[i][class_i]`` by Viterbi over the
        automaton (start and end transitions included), so a segment that fits several classes about
        equally well (e.g. the first and second piece of one push) gets the one the grammar allows
        after its neighbours.  Classes missing from a mapping score ``-inf``; classes the grammar does
        not know are ignored.  Returns ``(classes, total log-score)``.

        ``unexplained_penalty`` (nats, >= 0) keeps a segment that some classes cannot explain at all
        (``-inf``: e.g. a held-out piece shorter than a left-right chain) from ruling out every path
        through those classes: each such class scores the segment's best finite score minus the
        penalty instead, and a segment no class explains leaves the choice to the grammar.  Without
        it, one unexplainable segment forces its neighbours onto whatever other path stays finite.

        ``pair_scores`` (one mapping per pair of neighbouring segments, ``len(segment_scores) - 1`` of
        them) adds evidence that depends on both classes of a pair: ``pair_scores[i][(a, b)]`` (nats,
        finite or -inf; missing pairs add 0) is added when segment ``i`` is ``a`` and segment ``i + 1``
        is ``b``, e.g. whether the effects the two classes estimate for the two segments join up
        (:func:`hoap_actions.primitives.models.effect_continuity.effect_gap_scores`).

        ``bonus`` (one mapping per segment, finite nats) is evidence that does not come from a class's
        model explaining the segment, e.g. the class the object's path gives it: it is added after
        the unexplained penalty, so it also reaches a class whose model cannot explain the segment.
        """
        check_is_fitted(self)
        if isinstance(segment_scores, Mapping) or not len(segment_scores):
            raise InvalidInputError("segment_scores must be a non-empty list with one {class: log-likelihood} "
                                    "mapping per segment")
        n = len(self.symbols_)
        log_frame = np.full((len(segment_scores), n), -np.inf)
        for i, scores in enumerate(segment_scores):
            if not isinstance(scores, Mapping):
                raise InvalidInputError(f"segment_scores[{i}] must map classes to log-likelihoods, got {scores!r}")
            for k, symbol in enumerate(self.symbols_):
                value = float(scores.get(symbol, -np.inf))
                if np.isnan(value) or value == np.inf:
                    raise InvalidInputError(f"segment_scores[{i}][{symbol!r}] is {value}; log-likelihoods must be "
                                            "finite or -inf")
                log_frame[i, k] = value
        if unexplained_penalty is not None:
            penalty = float(unexplained_penalty)
            if not penalty >= 0.0 or penalty == np.inf:
                raise InvalidInputError(f"unexplained_penalty must be a finite number of nats >= 0 or None; got "
                                        f"{unexplained_penalty!r}")
            best = log_frame.max(axis=1)  # scores are finite or -inf (checked above)
            floor = np.where(np.isfinite(best), best, 0.0) - penalty
            log_frame = np.where(np.isfinite(log_frame), log_frame, floor[:, None])
        if bonus is not None:
            log_frame = log_frame + self._bonus_matrix(bonus, len(log_frame))
        with np.errstate(divide="ignore"):
            log_t = np.log(self.transmat_)
        steps = np.broadcast_to(log_t[1 : n + 1, 1 : n + 1], (len(log_frame) - 1, n, n))
        if pair_scores is not None:
            steps = steps + self._pair_matrices(pair_scores, len(log_frame))
        best, path = _viterbi_steps(log_t[0, 1 : n + 1], steps, log_frame, log_t[1 : n + 1, n + 1])
        if not np.isfinite(best):
            raise InvalidInputError(f"no class sequence of length {len(log_frame)} is both grammatical and has "
                                    "finite segment scores; fit the grammar with smoothing > 0 to allow unseen "
                                    "transitions")
        return [self.symbols_[k] for k in path], best

    def _bonus_matrix(self, bonus: Sequence[Mapping[Symbol, float]], n_segments: int) -> np.ndarray:
        if isinstance(bonus, Mapping) or len(bonus) != n_segments:
            raise InvalidInputError(f"bonus must be a list of {n_segments} {{class: nats}} mappings, one per segment")
        index = {symbol: k for k, symbol in enumerate(self.symbols_)}
        matrix = np.zeros((n_segments, len(self.symbols_)))
        for i, extra in enumerate(bonus):
            for symbol, value in extra.items():
                try:
                    nats = float(value)
                except (TypeError, ValueError):
                    nats = math.nan
                if not math.isfinite(nats):
                    raise InvalidInputError(f"bonus[{i}][{symbol!r}] is {value!r}; a bonus must be a finite number of "
                                            "nats")
                if symbol in index:
                    matrix[i, index[symbol]] += nats
        return matrix

    def _pair_matrices(self, pair_scores: Sequence[Mapping[tuple[Symbol, Symbol], float]], n_segments: int
                       ) -> np.ndarray:
        """``pair_scores`` as (n_segments - 1, n, n) log-scores in the order of ``symbols_``, checked."""
        if isinstance(pair_scores, Mapping) or len(pair_scores) != n_segments - 1:
            raise InvalidInputError(f"pair_scores must be a list with one {{(class, class): log-score}} mapping per "
                                    f"pair of neighbouring segments ({n_segments - 1}); got {pair_scores!r:.80}")
        index = self._index()
        out = np.zeros((n_segments - 1, len(self.symbols_), len(self.symbols_)))
        for i, scores in enumerate(pair_scores):
            if not isinstance(scores, Mapping):
                raise InvalidInputError(f"pair_scores[{i}] must map (class, class) pairs to log-scores, got "
                                        f"{scores!r:.80}")
            for pair, value in scores.items():
                if not (isinstance(pair, tuple) and len(pair) == 2):
                    raise InvalidInputError(f"pair_scores[{i}] keys must be (class, class) tuples; got {pair!r}")
                value = float(value)
                if np.isnan(value) or value == np.inf:
                    raise InvalidInputError(f"pair_scores[{i}][{pair!r}] is {value}; log-scores must be finite or -inf")
                a, b = pair
                if a in index and b in index:  # classes the grammar does not know are ignored, as in segment_scores
                    out[i, index[a] - 1, index[b] - 1] = value
        return out

    def sample(self, random_state: int | np.random.Generator | None = None) -> list[Symbol]:
        """Draw one grammatical class sequence: walk the seen transitions with their (smoothed) probabilities.

        Every class seen in training was followed by ``<end>`` at some point, so a walk ends with
        probability 1.
        """
        check_is_fitted(self)
        rng = np.random.default_rng(random_state)
        weights = np.where(self.counts_ > 0, self.transmat_, 0.0)
        end = len(self.symbols_) + 1
        state, out = 0, []
        while True:
            row = weights[state]
            state = int(rng.choice(len(row), p=row / row.sum()))
            if state == end:
                return out
            out.append(self.symbols_[state - 1])

    # -- text

    def _rules(self) -> list[tuple[str, list[tuple[str, float]]]]:
        names = [START, *(str(s) for s in self.symbols_), END]
        rules = []
        for i in range(len(names) - 1):
            targets = [(names[j], float(self.transmat_[i, j])) for j in np.flatnonzero(self.counts_[i] > 0)]
            if targets:
                rules.append((names[i], sorted(targets, key=lambda t: -t[1])))
        return rules

    def __str__(self) -> str:
        """One rule per state, the successors seen in training with their probabilities."""
        if not hasattr(self, "transmat_"):
            return f"ActionGrammar(smoothing={self.smoothing}) (not fitted)"
        lines = [f"ActionGrammar over {len(self.symbols_)} classes from {self.n_sequences_} sequences:"]
        for source, targets in self._rules():
            lines.append(f"  {source} -> " + " | ".join(f"{t} ({p:.2f})" for t, p in targets))
        return "\n".join(lines)

    def to_dot(self) -> str:
        """Graphviz DOT text of the automaton (seen transitions, labelled with probabilities)."""
        check_is_fitted(self)
        lines = [
            "digraph ActionGrammar {",
            "  rankdir=LR;",
            f"  {_dot_id(START)} [shape=point];",
            f"  {_dot_id(END)} [shape=doublecircle, label=\"end\"];",
        ]
        lines += [f"  {_dot_id(str(s))} [shape=box];" for s in self.symbols_]
        for source, targets in self._rules():
            lines += [f"  {_dot_id(source)} -> {_dot_id(t)} [label=\"{p:.2f}\"];" for t, p in targets]
        lines.append("}")
        return "\n".join(lines) + "\n"

    # -- persistence

    def _write(self, path: Path, overwrite: bool) -> None:
        body = {
            "smoothing": self.smoothing,
            "symbols": self.symbols_,
            "counts": self.counts_.tolist(),
            "n_sequences": self.n_sequences_,
        }
        write_json_model(path, self._file_kind, self._format_version, body, overwrite)

    @classmethod
    def _from_file(cls, path: Path, document: dict[str, Any], version: int) -> ActionGrammar:
        try:
            grammar = cls(smoothing=float(document["smoothing"]))
            grammar.symbols_ = [_clean_symbol(s) for s in document["symbols"]]
            n = len(grammar.symbols_)
            grammar.counts_ = np.array(document["counts"], dtype=float).reshape(n + 2, n + 2)
            grammar.n_sequences_ = int(document["n_sequences"])
        except (KeyError, TypeError, ValueError, InvalidInputError) as exc:
            raise DataFileError(f"{path} is a corrupt ActionGrammar file: {exc}") from exc
        grammar.transmat_ = grammar._probabilities(grammar.counts_)
        return grammar


def _clean_symbol(symbol: object) -> Symbol:
    """A class as a JSON-safe int or str (numpy ints become ints; bools and others are refused)."""
    if isinstance(symbol, (bool, np.bool_)) or not isinstance(symbol, (int, np.integer, str)):
        raise InvalidInputError(f"a primitive class must be an int id or a str name, got {symbol!r}")
    if isinstance(symbol, str) and symbol in (START, END):
        raise InvalidInputError(f"{symbol!r} is reserved for the automaton's start/end state")
    return int(symbol) if isinstance(symbol, (int, np.integer)) else symbol


def _check_sequences(sequences: Sequence[Sequence[Symbol]]) -> list[list[Symbol]]:
    """Validate a non-empty list of non-empty class sequences."""
    if isinstance(sequences, (str, bytes)):
        raise InvalidInputError("sequences must be a list of class sequences, got a string")
    try:
        items = [list(seq) if not isinstance(seq, (str, bytes)) else None for seq in sequences]
    except TypeError as exc:
        raise InvalidInputError(f"sequences must be a list of class sequences: {exc}") from exc
    if not items:
        raise InvalidInputError("sequences is empty: at least one demonstration's class sequence is needed")
    for i, seq in enumerate(items):
        if seq is None:
            raise InvalidInputError(f"sequences[{i}] is a string; give a list of classes, e.g. ['approach', 'push']")
        if not seq:
            raise InvalidInputError(f"sequences[{i}] is empty; every demonstration has at least one class")
    return [[_clean_symbol(s) for s in seq] for seq in items]  # type: ignore[union-attr]


def _dot_id(name: str) -> str:
    """A quoted DOT identifier."""
    return '"' + name.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _viterbi_steps(log_start: np.ndarray, log_steps: np.ndarray, log_frame: np.ndarray, log_end: np.ndarray
                   ) -> tuple[float, list[int]]:
    """Best path and its log-score through ``len(log_frame)`` segments with a transition matrix per step
    (``log_steps``, (T - 1, n, n)): the grammar's, plus any pair scores.  :func:`hmm_math.viterbi` shares one
    transition matrix across steps (the batched HMM hot path); a demonstration has a handful of segments."""
    delta = log_start + log_frame[0]
    back = []
    for step, frame in zip(log_steps, log_frame[1:]):
        candidates = delta[:, None] + step
        back.append(candidates.argmax(axis=0))
        delta = candidates.max(axis=0) + frame
    delta = delta + log_end
    state = int(delta.argmax())
    path = [state]
    for pointers in reversed(back):
        state = int(pointers[state])
        path.append(state)
    return float(delta.max()), path[::-1]


def _split_symbols(X: Sequence, lengths: Sequence[int]) -> list[list]:
    """Concatenated classes ``X`` cut into sequences of ``lengths`` classes each."""
    counts = np.asarray(lengths)
    if counts.ndim != 1 or counts.dtype.kind not in "iu" or np.any(counts < 1) or counts.sum() != len(X):
        raise InvalidInputError(f"lengths must be counts >= 1 that sum to the {len(X)} classes of X; got {lengths!r}")
    bounds = np.concatenate([[0], np.cumsum(counts)])
    return [list(X[a:b]) for a, b in zip(bounds[:-1], bounds[1:])]
