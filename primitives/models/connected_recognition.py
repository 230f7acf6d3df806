"""Connected recognition: cut and classify a whole movement at once, as speech recognisers chain phoneme models.

Every class's left-right chain becomes a run of states in one large HMM; leaving a class's last state
enters the first state of a class the grammar allows next, with the grammar's probability. Viterbi
over that HMM gives, for every frame, the class performing it: the segmentation and the
classification together, from the arm markers alone.

A class's PHMM needs its effect phi, which is unknown while the movement is being cut. Each state's
Gaussian is therefore taken over the class's training effects: mean ``mean_bar_j + W_j mean(phi)``,
variance ``var_j + diag(W_j cov(phi) W_j^T)`` (the exact marginal's diagonal), on the features a
caller selects (``features``). Phi is estimated afterwards, per segment, with the class's PHMM
(:meth:`ActionModels.decode`).

``stay_weight`` raises every self-transition probability to that power: a left-right chain's
geometric state durations are heavy-tailed, and a piece of a push stretched over two pieces' frames
then costs too little against the two pieces (the last piece of a 15 cm push was merged into the
one before it).

Leaving a chain: a left-right PHMM's last state keeps its frames for good, so the probability of
leaving it is measured on the class's training segments (frames aligned to the last state per
segment, a geometric duration), see :func:`exit_probability`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM

__all__ = ["ChainedHMM", "chain_classes", "exit_probability"]

STAY, ADVANCE, ENTER = 0, 1, 2  # how Viterbi reached a state at a frame


def exit_probability(phmm: ParametricHMM, movements: Sequence[np.ndarray], phis: np.ndarray) -> float:
    """Per-frame probability of leaving the chain's last state, from training movements aligned at their phi.

    The last state's frames per movement are geometric with this success probability (its maximum
    likelihood estimate: movements / frames in the last state).
    """
    frames = sum(int(np.sum(phmm.predict(X, phi) == phmm.n_states - 1)) for X, phi in zip(movements, phis))
    return float(min(1.0, len(movements) / max(frames, 1)))


@dataclass(frozen=True)
class ChainedHMM:
    """The classes' chains joined by the grammar: ``S`` states, ``C`` classes, ``D`` features.

    ``state_class`` (S,) is each state's class index; ``first``/``last`` (C,) each class's first and
    last state; ``log_stay``/``log_next`` (S,) the chain's self and forward transitions (``log_next``
    is -inf at a class's last state); ``log_exit`` (C,) leaving the last state; ``log_start``,
    ``log_end`` (C,) and ``log_grammar`` (C, C) the grammar; ``means``/``variances`` (S, D) the
    states' Gaussians over the training effects.
    """

    class_ids: np.ndarray
    state_class: np.ndarray
    first: np.ndarray
    last: np.ndarray
    log_stay: np.ndarray
    log_next: np.ndarray
    log_exit: np.ndarray
    log_start: np.ndarray
    log_end: np.ndarray
    log_grammar: np.ndarray
    means: np.ndarray
    variances: np.ndarray

    def log_emissions(self, X: np.ndarray) -> np.ndarray:
        """Log-density of every frame of ``X`` (T, D) under every state, ``(T, S)``; three BLAS products."""
        precision = 1.0 / self.variances
        const = -0.5 * (np.log(2.0 * np.pi * self.variances).sum(axis=1)
                        + np.einsum("sd,sd,sd->s", self.means, self.means, precision))
        return -0.5 * (X * X) @ precision.T + X @ (self.means * precision).T + const

    def class_scores(self, log_emissions: np.ndarray) -> np.ndarray:
        """Each class's best-path log-probability for the whole movement on its own ``(C,)``: its chain
        from first to last state, no grammar (``-inf`` where the movement is shorter than the chain)."""
        logb = self._checked(log_emissions)
        delta = np.full(self.state_class.size, -np.inf)
        delta[self.first] = 0.0
        delta += logb[0]
        shifted = np.empty_like(delta)
        for t in range(1, len(logb)):
            shifted[0] = -np.inf
            np.add(delta[:-1], self.log_next[:-1], out=shifted[1:])
            np.maximum(delta + self.log_stay, shifted, out=delta)
            delta += logb[t]
        return delta[self.last]

    def _checked(self, log_emissions: np.ndarray) -> np.ndarray:
        logb = np.asarray(log_emissions, dtype=float)
        if logb.ndim != 2 or logb.shape[1] != self.state_class.size or len(logb) < 1:
            raise InvalidInputError(f"log_emissions must be (T >= 1, {self.state_class.size}); got {logb.shape}")
        return logb

    def viterbi(self, log_emissions: np.ndarray) -> tuple[np.ndarray, float]:
        """The most likely class index of every frame ``(T,)`` and the path's log-probability.

        Paths start in a class the grammar allows first, move along chains or from a class's last
        state into a class the grammar allows next, and end in the last state of a class the grammar
        allows last. ``-inf`` (and every frame -1) when no path explains the movement.
        """
        logb = self._checked(log_emissions)
        T, S = logb.shape
        n_classes = self.first.size
        how = np.empty((T, S), dtype=np.int8)
        came_from = np.empty((T, n_classes), dtype=np.int32)  # predecessor class of each class's first state
        delta = np.full(S, -np.inf)
        delta[self.first] = self.log_start
        delta += logb[0]
        how[0] = ENTER
        came_from[0] = -1
        shifted = np.empty(S)
        for t in range(1, T):
            leave = delta[self.last] + self.log_exit                        # (C,)
            entries = leave[:, None] + self.log_grammar                     # (from, to)
            best_prev = entries.argmax(axis=0)
            best_entry = entries[best_prev, np.arange(n_classes)]
            stay = delta + self.log_stay
            shifted[0] = -np.inf
            np.add(delta[:-1], self.log_next[:-1], out=shifted[1:])
            advance = shifted > stay
            new = np.where(advance, shifted, stay)
            how_t = advance.astype(np.int8)
            enter = best_entry > new[self.first]
            firsts = self.first[enter]
            new[firsts] = best_entry[enter]
            how_t[firsts] = ENTER
            came_from[t] = np.where(enter, best_prev, -1)
            how[t] = how_t
            delta = new + logb[t]
        finals = delta[self.last] + self.log_exit + self.log_end
        end_class = int(np.argmax(finals))
        score = float(finals[end_class])
        if not np.isfinite(score):
            return np.full(T, -1), -np.inf
        labels = np.empty(T, dtype=np.int64)
        state = int(self.last[end_class])
        for t in range(T - 1, -1, -1):
            cls = int(self.state_class[state])
            labels[t] = cls
            step = how[t, state]
            if step == STAY:
                continue
            if step == ADVANCE:
                state -= 1
                continue
            if t:  # entered this class's first state from the previous class's last state
                state = int(self.last[came_from[t, cls]])
        return labels, score


def chain_classes(phmms: Sequence[ParametricHMM], class_ids: Sequence[int], exit_probabilities: Sequence[float],
                  grammar: ActionGrammar, features: Sequence[int] | None = None,
                  stay_weight: float = 1.0) -> ChainedHMM:
    """Join the classes' left-right chains (in ``class_ids`` order) with ``grammar``'s transitions.

    ``features``: indices of the PHMMs' features the states keep (default all); ``stay_weight``: the
    power on self-transition probabilities (module docstring).
    """
    if not (isinstance(stay_weight, (int, float)) and np.isfinite(stay_weight) and stay_weight > 0):
        raise InvalidInputError(f"stay_weight must be a positive number; got {stay_weight!r}")
    if not (len(phmms) == len(class_ids) == len(exit_probabilities)) or not phmms:
        raise InvalidInputError("give one PHMM and one exit probability per class id, at least one class")
    if any(p.topology != "left-right" for p in phmms):
        raise InvalidInputError("connected recognition chains left-right PHMMs (topology='left-right') only")
    sizes = np.array([p.n_states for p in phmms])
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    last = first + sizes - 1
    log_stay, log_next, means, variances = [], [], [], []
    with np.errstate(divide="ignore"):
        for phmm in phmms:
            a = phmm.transmat_
            k = phmm.n_states
            log_stay.append(np.log(np.diagonal(a)))
            forward = np.append(np.diagonal(a, offset=1), 0.0) if k > 1 else np.zeros(1)
            log_next.append(np.log(forward))
            mean_phi = phmm.train_phi_.mean(axis=0)
            cov_phi = np.atleast_2d(np.cov(phmm.train_phi_, rowvar=False)) if len(phmm.train_phi_) > 1 \
                else np.zeros((mean_phi.size, mean_phi.size))
            means.append(phmm.mean_bar_ + phmm.W_ @ mean_phi)
            state_vars = phmm.covars_ if phmm.covariance_type == "diag" else np.diagonal(phmm.covars_, axis1=1, axis2=2)
            spread = np.einsum("kdp,pq,kdq->kd", phmm.W_, cov_phi.reshape(mean_phi.size, mean_phi.size), phmm.W_) \
                if mean_phi.size else 0.0
            variances.append(state_vars + spread)
        log_stay = np.concatenate(log_stay)
        log_stay[last] = np.log1p(-np.clip(exit_probabilities, 0.0, 1.0))
        log_stay = float(stay_weight) * log_stay
        keep = slice(None) if features is None else np.asarray(features, dtype=np.intp)
        symbols = {int(s): i + 1 for i, s in enumerate(grammar.symbols_)}
        index = [symbols.get(int(c)) for c in class_ids]
        if None in index:
            raise InvalidInputError(f"the grammar does not know classes "
                                    f"{[c for c, i in zip(class_ids, index) if i is None]}")
        log_a = np.log(grammar.transmat_)
        index = np.array(index)
        end = log_a.shape[0] - 1
        return ChainedHMM(
            class_ids=np.asarray(class_ids, dtype=np.int64),
            state_class=np.repeat(np.arange(len(phmms)), sizes),
            first=first,
            last=last,
            log_stay=log_stay,
            log_next=np.concatenate(log_next),
            log_exit=np.log(np.asarray(exit_probabilities, dtype=float)),
            log_start=log_a[0, index],
            log_end=log_a[index, end],
            log_grammar=log_a[np.ix_(index, index)],
            means=np.ascontiguousarray(np.concatenate(means)[:, keep]),
            variances=np.ascontiguousarray(np.concatenate(variances)[:, keep]),
        )
