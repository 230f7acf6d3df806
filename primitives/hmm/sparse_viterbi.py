"""Viterbi decoding for HMMs with sparse transition matrices, such as the discovery's joint HMM."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["sparse_viterbi"]


def sparse_viterbi(
    log_startprob: np.ndarray, log_transmat: np.ndarray, log_frameprob: np.ndarray, lengths: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hmm_math.viterbi` for a sparse transition matrix: ``(best log-probability (S,), states (N,))``.

    The joint HMM is a few hundred states in merged left-right chains, so each state has a handful
    of predecessors; a dense step costs ``K^2`` per frame, this one the number of allowed
    (finite) transitions. Sequences are sorted by length so the ones still running at time ``t``
    are a prefix, and the frames are never padded. Ties go to the lowest state index, as in
    :func:`hmm_math.viterbi`; an impossible sequence gets ``-inf`` and a meaningless path.
    """
    log_pi = np.asarray(log_startprob, float)
    log_a = np.asarray(log_transmat, float)
    logb = np.asarray(log_frameprob, float)
    lengths = np.asarray(lengths, dtype=np.int64)
    n_states = len(log_pi)
    if log_a.shape != (n_states, n_states) or logb.ndim != 2 or logb.shape[1] != n_states:
        raise InvalidInputError(
            f"shapes disagree: startprob {log_pi.shape}, transmat {log_a.shape}, frameprob {logb.shape}"
        )
    if lengths.ndim != 1 or len(lengths) == 0 or np.any(lengths < 1) or lengths.sum() != len(logb):
        raise InvalidInputError(f"lengths must be positive ints summing to the {len(logb)} frames; got {lengths}")
    # edges sorted by destination, then source: the first best edge of a group is the lowest source
    dst, src = np.nonzero(np.isfinite(log_a).T)
    weight = log_a[src, dst]
    group_start = np.flatnonzero(np.r_[True, dst[1:] != dst[:-1]]) if len(dst) else np.empty(0, int)
    group_dst, group_size = dst[group_start], np.diff(np.r_[group_start, len(dst)])
    edge_index = np.arange(len(dst))

    order = np.argsort(-lengths, kind="stable")
    starts = (np.cumsum(lengths) - lengths)[order]
    sorted_lengths = lengths[order]
    t_max = int(sorted_lengths[0])
    active = np.searchsorted(-sorted_lengths, -np.arange(t_max + 1), side="left")  # sequences with length > t
    back = np.zeros(logb.shape, dtype=np.int32)
    delta = log_pi + logb[starts]
    finals = np.empty((len(lengths), n_states))
    ending = slice(active[1], active[0])
    finals[ending] = delta[ending]
    for t in range(1, t_max):
        n = active[t]
        new = np.full((n, n_states), -np.inf)
        if len(dst):
            cand = delta[:n, src] + weight
            best = np.maximum.reduceat(cand, group_start, axis=1)
            is_best = cand == np.repeat(best, group_size, axis=1)
            first = np.minimum.reduceat(np.where(is_best, edge_index, len(dst)), group_start, axis=1)
            new[:, group_dst] = best
            back[(starts[:n] + t)[:, None], group_dst[None, :]] = src[first]
        delta[:n] = new + logb[starts[:n] + t]
        ending = slice(active[t + 1], n)
        finals[ending] = delta[ending]
    final_state = np.argmax(finals, axis=1)
    best_logprob = finals[np.arange(len(lengths)), final_state]
    path = np.empty(len(logb), dtype=np.intp)
    state = final_state.copy()
    for t in range(t_max - 1, -1, -1):
        n = active[t]
        ending = slice(active[t + 1], n)
        state[ending] = final_state[ending]
        frames = starts[:n] + t
        path[frames] = state[:n]
        if t:
            state[:n] = back[frames, state[:n]]
    result = np.empty(len(lengths))
    result[order] = best_logprob
    return result, path
