"""Merging the pieces of all demonstrations into joint HMM states at once, closest pair first.

The paper folds the demonstrations' chains into the joint HMM one after the other, so what a state
becomes depends on which demonstration came first: shuffling a recording changed the number of action
groups found. Here every piece starts as its own cluster and the two closest clusters (symmetric KL,
eq. (1)) merge, again and again, while the closest pair is below the threshold. A cluster's Gaussian
is the merge of eqs. (2)-(3) over all its members with equal weights (the mean of their precisions,
and their precision-weighted mean), so it depends on which pieces it holds, not on the order in
which they joined.

Which pieces may share a state is the caller's ``allowed`` matrix, applied to every pair of members
(complete linkage): e.g. not two pieces of one demonstration, not rest with motion.
"""

from __future__ import annotations

import numpy as np

from hoap_actions.primitives.hmm.gaussians import spd_inverse

__all__ = ["cluster_pieces"]

_ROWS_PER_BLOCK = 64  # rows of the distance matrix computed at once: bounds the memory (~20 MB per 1000 pieces)


def cluster_pieces(means: np.ndarray, covs: np.ndarray, allowed: np.ndarray,
                   threshold: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cluster the pieces' Gaussians (module docstring).

    ``means`` ``(n, d)`` and ``covs`` ``(n, d, d)`` are the pieces' Gaussians, ``allowed`` ``(n, n)``
    symmetric bool which pairs may share a cluster; clusters merge while their symmetric KL divergence
    is below ``threshold`` (nats), ties to the lower indices. Returns the cluster of every piece ``(n,)``
    (numbered by their first piece) and the clusters' means ``(k, d)`` and covariances ``(k, d, d)``.
    """
    clusters = _Clusters(np.array(means, float), np.array(covs, float), np.array(allowed, bool))
    best_value, best_index = clusters.initial_best()
    label = np.arange(len(clusters.means))
    while True:
        i = int(np.argmin(best_value))
        if not best_value[i] < threshold:
            break
        i, j = sorted((i, int(best_index[i])))  # the lower index survives
        label[label == j] = i
        clusters.merge(i, j)
        best_value[j], best_index[j] = np.inf, -1
        row = clusters.rows(np.array([i]))[0]
        best_index[i] = int(np.argmin(row))
        best_value[i] = row[best_index[i]]
        stale = np.flatnonzero((best_index == i) | (best_index == j))
        for k in stale[stale != i]:
            other = clusters.rows(np.array([k]))[0]
            best_index[k] = int(np.argmin(other))
            best_value[k] = other[best_index[k]]
        closer = np.flatnonzero(row < best_value)
        best_value[closer], best_index[closer] = row[closer], i
    survivors, renumbered = np.unique(label, return_inverse=True)
    return renumbered, clusters.means[survivors], clusters.covs[survivors]


class _Clusters:
    """The live clusters' Gaussians (with their members' summed precisions and informations), and
    which clusters may still merge."""

    def __init__(self, means: np.ndarray, covs: np.ndarray, allowed: np.ndarray) -> None:
        self.means, self.covs = means, covs
        self.precisions = spd_inverse(covs)
        self.sum_precision = self.precisions.copy()
        self.sum_information = np.einsum("nij,nj->ni", self.precisions, means)
        self.count = np.ones(len(means))
        self.allowed = allowed.copy()
        np.fill_diagonal(self.allowed, False)
        self.alive = np.ones(len(means), dtype=bool)

    def merge(self, i: int, j: int) -> None:
        """Cluster ``j`` joins ``i``: the equal-weight merge of all their members."""
        self.sum_precision[i] += self.sum_precision[j]
        self.sum_information[i] += self.sum_information[j]
        self.count[i] += self.count[j]
        self.precisions[i] = self.sum_precision[i] / self.count[i]
        self.covs[i] = spd_inverse(self.precisions[i])
        self.means[i] = self.covs[i] @ (self.sum_information[i] / self.count[i])
        self.allowed[i] &= self.allowed[j]
        self.allowed[:, i] &= self.allowed[:, j]
        self.alive[j] = False
        self.allowed[j] = self.allowed[:, j] = False

    def initial_best(self) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.means)
        value, index = np.full(n, np.inf), np.zeros(n, dtype=int)
        for start in range(0, n, _ROWS_PER_BLOCK):
            rows = np.arange(start, min(n, start + _ROWS_PER_BLOCK))
            block = self.rows(rows)
            index[rows] = np.argmin(block, axis=1)
            value[rows] = block[np.arange(len(rows)), index[rows]]
        return value, index

    def rows(self, rows: np.ndarray) -> np.ndarray:
        """Symmetric KL of the clusters ``rows`` to every cluster; inf where they may not merge."""
        d = self.means.shape[1]
        traces = (np.einsum("mij,kji->km", self.precisions, self.covs[rows])
                  + np.einsum("kij,mji->km", self.precisions[rows], self.covs))
        diff = self.means[rows][:, None, :] - self.means[None, :, :]
        mahalanobis = (np.einsum("kmi,kij,kmj->km", diff, self.precisions[rows], diff)
                       + np.einsum("kmi,mij,kmj->km", diff, self.precisions, diff))
        return np.where(self.allowed[rows], 0.25 * (traces + mahalanobis) - 0.5 * d, np.inf)
