"""The effects of many movements at once: :meth:`ParametricHMM.estimate_phi
<hoap_actions.primitives.hmm.parametric_hmm.ParametricHMM.estimate_phi>` for a batch of (left-right model,
movement) pairs, all their EMs run together.

Recognising a demonstration estimates phi for every piece under each candidate class's PHMM: hundreds of
small EMs, each a forward-backward whose python loop over frames costs far more than its arithmetic. Here
the chains of all pairs still running are laid end to end on one state axis (:class:`_Chains`), so a frame
costs a few numpy calls for the whole batch. The recursions run in log space: the sharp Gaussians of
wrong candidates make paths differ by more than a float's range, which scaled probabilities lose.
Emissions and phi updates are computed per model with the same functions as ``estimate_phi``, and each
pair stops when its own EM converges, so every phi is the one ``estimate_phi`` gives up to round-off.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.hmm import phmm_effects
from hoap_actions.primitives.hmm.hmm_math import log_gaussian_density_padded
from hoap_actions.primitives.hmm.phmm_batch import SequenceBatch, is_int

__all__ = ["estimate_phis"]

_LOG_POSTERIOR_FLOOR = np.log(1e-150)
"""Posteriors below exp of this are zeroed, as forward-backward does: no denormal number reaches the M-step."""
_RESCALE_FRAMES = 8
"""Frames between the rescalings of the log recursions: few enough that their values stay within a few
thousand nats of 0 (measured: as precise as rescaling every frame), many enough to cost little."""


@dataclass(frozen=True)
class _Chains:
    """Left-right chains laid end to end, longest sequence first: the chains of the ``rows[t]`` sequences
    longer than frame ``t`` are the first ``states[t]`` states. Each starts in its first state and ends in
    its last. Log space keeps its precision near 0: each frame's emissions are shifted so that a row's best
    state has 0, and every :data:`_RESCALE_FRAMES` frames the recursions are shifted so that a row's largest
    value is 0, as scaling does in probability space."""

    lengths: np.ndarray      # (R,) frames of each row's sequence, non-increasing
    first: np.ndarray        # (R,) each row's first state
    sizes: np.ndarray        # (R,) each row's states
    log_stay: np.ndarray     # (S,)
    log_advance: np.ndarray  # (S,) into the next state; -inf at a chain's last state
    rows: np.ndarray         # (T_max,)
    states: np.ndarray       # (T_max,)

    @classmethod
    def build(cls, lengths: np.ndarray, transitions: Sequence[tuple[np.ndarray, np.ndarray]]) -> _Chains:
        """From each row's length and its chain's (log stay, log advance) per state."""
        sizes = np.array([stay.size for stay, _ in transitions])
        ends = np.cumsum(sizes)
        longer = np.searchsorted(-lengths, -np.arange(lengths[0]), side="left")
        return cls(lengths, ends - sizes, sizes, np.concatenate([s for s, _ in transitions]),
                   np.concatenate([a for _, a in transitions]), longer, ends[longer - 1])

    @property
    def last(self) -> np.ndarray:
        return self.first + self.sizes - 1

    def posteriors(self, logb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Log-likelihood per row ``(R,)`` and state posteriors ``(T_max, S)`` (0 past a row's end) from the
        log-emissions ``logb`` ``(T_max, S)`` (read only within each row's frames)."""
        past_end = np.arange(len(logb))[:, None] >= self.lengths  # (T_max, R)
        shift = np.maximum.reduceat(logb, self.first, axis=1)
        shift[past_end] = 0.0
        logb = logb - shift.repeat(self.sizes, axis=1)
        la, rescaled = self._forward(logb)
        lb = self._backward(logb)
        ll = la[self.lengths - 1, self.last] + shift.sum(axis=0) + rescaled.sum(axis=0)
        gamma = la + lb
        top = np.maximum.reduceat(gamma, self.first, axis=1)
        top[past_end | ~np.isfinite(top)] = 0.0
        gamma -= top.repeat(self.sizes, axis=1)
        np.maximum(gamma, _LOG_POSTERIOR_FLOOR - 1.0, out=gamma)
        np.exp(gamma, out=gamma)
        total = np.add.reduceat(gamma, self.first, axis=1)
        total[past_end | (total == 0.0)] = np.inf  # 0 everywhere: past a row's end, or a row with no path
        gamma /= total.repeat(self.sizes, axis=1)
        gamma *= gamma >= np.exp(_LOG_POSTERIOR_FLOOR)
        gamma[:, np.repeat(~np.isfinite(ll), self.sizes)] = 0.0  # no path: no posteriors
        return ll, gamma

    def _forward(self, logb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Log forward values ``(T_max, S)``, each row's shifted by the sum of its rescalings ``(T_max, R)``."""
        la = np.full(logb.shape, -np.inf)
        la[0, self.first] = logb[0, self.first]
        rescaled = np.zeros((len(logb), self.first.size))
        move, stay = np.empty(logb.shape[1]), np.empty(logb.shape[1])
        move[0] = -np.inf
        log_stay, log_advance, states = self.log_stay, self.log_advance, self.states.tolist()
        for t in range(1, len(logb)):
            n = states[t]
            previous, now = la[t - 1, :n], la[t, :n]
            np.add(previous[:-1], log_advance[:n - 1], out=move[1:n])
            np.add(previous, log_stay[:n], out=stay[:n])
            np.logaddexp(stay[:n], move[:n], out=now)
            now += logb[t, :n]
            if t % _RESCALE_FRAMES == 0:
                r = self.rows[t]
                rescaled[t, :r] = np.maximum.reduceat(now, self.first[:r])
                now -= rescaled[t, :r].repeat(self.sizes[:r])
        return la, rescaled

    def _backward(self, logb: np.ndarray) -> np.ndarray:
        """Log backward values ``(T_max, S)``, each row's shifted by a constant per frame."""
        lb = np.full(logb.shape, -np.inf)
        lb[self.lengths - 1, self.last] = 0.0
        move, after = np.empty(logb.shape[1]), np.empty(logb.shape[1])
        log_stay, log_advance, states = self.log_stay, self.log_advance, self.states.tolist()
        for t in range(len(logb) - 2, -1, -1):
            n = states[t + 1]
            now, ahead = lb[t, :n], after[:n]
            np.add(logb[t + 1, :n], lb[t + 1, :n], out=ahead)
            np.add(ahead[1:], log_advance[:n - 1], out=move[:n - 1])
            move[n - 1] = -np.inf
            ahead += log_stay[:n]
            np.logaddexp(ahead, move[:n], out=now)
            if t % _RESCALE_FRAMES == 0:
                r = self.rows[t + 1]
                now -= np.maximum.reduceat(now, self.first[:r]).repeat(self.sizes[:r])
        return lb


class _ModelRows:
    """The rows of one model: their movements padded once, their effects, and where they sit in the chains."""

    def __init__(self, model: Any, rows: np.ndarray, movements: list[np.ndarray], phis: np.ndarray) -> None:
        self.model = model
        self.rows = rows
        lengths = np.array([len(x) for x in movements])
        self.batch = SequenceBatch.build(np.concatenate(movements), lengths, phis, model.mean_bar_.mean(axis=0),
                                         model.covariance_type)
        with np.errstate(divide="ignore"):
            log_a = np.log(model.transmat_)
        self.transitions = (np.diagonal(log_a).copy(), np.append(np.diagonal(log_a, offset=1), -np.inf))

    def running(self, running: np.ndarray) -> tuple[np.ndarray, SequenceBatch] | None:
        """This model's rows still running and their batch (frames trimmed to the longest), or None."""
        keep = running[self.rows]
        if not keep.any():
            return None
        b = self.batch
        t = int(b.lengths[keep].max())
        return self.rows[keep], SequenceBatch(b.X[keep, :t], b.moments[keep, :t], b.lengths[keep], b.offset,
                                              b.phi[keep])

    def log_emissions(self, batch: SequenceBatch) -> np.ndarray:
        """``(S, T, K)`` at the rows' current effects, as the model's E-step computes them."""
        m = self.model
        return log_gaussian_density_padded(batch.X, m._means_at(batch.phi, batch.offset), m.covars_,
                                           m.covariance_type, batch.moments)


def estimate_phis(jobs: Sequence[tuple[Any, np.ndarray]], n_restarts: int = 5, n_iter: int = 30,
                  tol: float = 1e-6) -> list[np.ndarray]:
    """The effect phi (p,) of each ``(model, X)`` pair, a fitted left-right :class:`ParametricHMM` and one
    movement ``(T, D)``: what ``model.estimate_phi(X, n_restarts, n_iter, tol)`` gives, up to round-off."""
    if not (is_int(n_restarts) and is_int(n_iter) and n_restarts >= 1 and n_iter >= 1):
        raise InvalidInputError(f"n_restarts and n_iter must be ints >= 1; got {n_restarts!r}, {n_iter!r}")
    results: list[np.ndarray | None] = [None] * len(jobs)
    job_of_row, movements, starts, models = [], [], [], []
    for j, (model, X) in enumerate(jobs):
        check_is_fitted(model)
        if model.topology != "left-right":
            raise InvalidInputError(f"estimate_phis runs left-right chains only; got a {model.topology!r} model")
        X = model._check_sequence(X)
        if model.phi_dim_ == 0:
            results[j] = np.zeros(0)
            continue
        phis = model._restart_phis(n_restarts)
        job_of_row += [j] * len(phis)
        movements += [X] * len(phis)
        starts += list(phis)
        models += [model] * len(phis)
    if job_of_row:
        for j, phi in _run_em(np.array(job_of_row), movements, starts, models, n_iter, tol).items():
            results[j] = phi
    return results


def _run_em(job_of_row: np.ndarray, movements: list[np.ndarray], starts: list[np.ndarray], models: list[Any],
            n_iter: int, tol: float) -> dict[int, np.ndarray]:
    """Each job's phi: its rows (restarts) iterate together until all gain less than ``tol``, then the
    row of highest likelihood wins, as in ``estimate_phi``."""
    order = np.argsort([-len(x) for x in movements], kind="stable")  # longest first, as _Chains needs
    lengths = np.array([len(movements[i]) for i in order])
    jobs = job_of_row[order]
    groups = _group_by_model(order, movements, starts, models)
    running = np.ones(order.size, dtype=bool)
    previous = np.full(order.size, -np.inf)
    for _ in range(n_iter):
        ll, posteriors = _e_step(groups, lengths, running)
        for group, batch, gamma in posteriors:
            group.batch.phi[running[group.rows]] = phmm_effects.phi_update(group.model, batch, gamma)
        gained = np.full(order.size, -np.inf)
        gained[running] = ll - previous[running]
        previous[running] = ll
        running &= np.isin(jobs, jobs[running & ~(gained < tol)])
        if not running.any():
            break
    phis: list = [None] * order.size
    for group in groups:
        for row, phi in zip(group.rows, group.batch.phi):
            phis[row] = phi
    restarted = np.bincount(jobs)[jobs] > 1
    final = np.zeros(order.size)
    if restarted.any():  # the likelihoods at the final effects pick among restarts
        final[restarted] = _e_step(groups, lengths, restarted)[0]
    best = {}
    for j in np.unique(jobs):
        rows = np.flatnonzero(jobs == j)  # in restart order (a stable sort of equal lengths)
        best[int(j)] = phis[rows[np.argmax(final[rows])]].copy()
    return best


def _group_by_model(order: np.ndarray, movements: list[np.ndarray], starts: list[np.ndarray],
                    models: list[Any]) -> list[_ModelRows]:
    """The rows (in ``order``'s positions) of each distinct model, in order of first appearance."""
    rows: dict[int, list[int]] = {}
    for position, row in enumerate(order):
        rows.setdefault(id(models[row]), []).append(position)
    return [_ModelRows(models[order[r[0]]], np.array(r), [movements[order[i]] for i in r],
                       np.array([starts[order[i]] for i in r])) for r in rows.values()]


def _e_step(groups: list[_ModelRows], lengths: np.ndarray, running: np.ndarray
            ) -> tuple[np.ndarray, list[tuple[_ModelRows, SequenceBatch, np.ndarray]]]:
    """Log-likelihoods of the running rows (in row order) and, per model, the batch of its running rows
    with their posteriors ``(S, T, K)``: all rows' forward-backward in one pass."""
    position = np.cumsum(running) - 1  # of each running row among them
    batches = [(group, *found) for group in groups if (found := group.running(running)) is not None]
    transitions: list = [None] * int(running.sum())
    for group, rows, _ in batches:
        for row in position[rows]:
            transitions[row] = group.transitions
    chains = _Chains.build(lengths[running], transitions)
    n_states = int(chains.last[-1]) + 1
    logb = np.zeros((int(chains.lengths[0]), n_states))
    located = []
    for group, rows, batch in batches:
        frames = _frames(batch.lengths)
        index = _flat_index(chains, position[rows], frames, n_states)
        logb.reshape(-1)[index] = group.log_emissions(batch)[frames]
        located.append((group, batch, frames, index))
    ll, gamma = chains.posteriors(logb)
    posteriors = []
    for group, batch, frames, index in located:
        padded = np.zeros(frames.shape + index.shape[1:])
        padded[frames] = gamma.reshape(-1)[index]
        posteriors.append((group, batch, padded))
    return ll, posteriors


def _frames(lengths: np.ndarray) -> np.ndarray:
    """``(S, T_max)``: which padded frames lie within their sequence."""
    return np.arange(lengths.max())[None, :] < lengths[:, None]


def _flat_index(chains: _Chains, rows: np.ndarray, frames: np.ndarray, n_states: int) -> np.ndarray:
    """``(frames, K)`` positions in the flattened ``(T_max, S)`` chain arrays of the rows' valid ``frames``
    ``(rows, T)``, in the order a padded ``(rows, T, K)`` array's valid frames come."""
    which, t = np.nonzero(frames)
    return (t * n_states + chains.first[rows[which]])[:, None] + np.arange(chains.sizes[rows[0]])
