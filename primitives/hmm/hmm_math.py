"""HMM maths shared by discovery and the parametric HMMs: Gaussian densities, forward-backward, Viterbi.

Batches of sequences follow hmmlearn: one concatenated ``X`` of shape ``(N, D)`` with ``lengths``
(``S`` positive ints summing to ``N``).  Internally the ragged batch is padded to ``(S, T_max, ...)``
so each recursion is one python loop over time, vectorised over sequences and states.

forward-backward uses per-frame scaling in probability space (one small matmul per step, several
times faster than log-sum-exp); a sequence whose scaled recursion underflows (all reachable states
have vanishing probability, possible with ``-inf`` transitions) is recomputed exactly in log space.
Probabilities that would become denormal numbers (100x slower arithmetic) are flushed to zero;
flushing a forward probability is only safe while its path stays negligible, so every sequence whose
scaled posteriors do not sum to one on each frame (the sign that a flushed path won later, possible
when emissions differ by hundreds of nats per frame) is also recomputed in log space.
Viterbi works in log space throughout.  ``-inf`` entries (forbidden transitions) are allowed
everywhere.  An optional ``log_endprob`` constrains the state the sequence ends in (left-right
models that must traverse the whole chain use ``log(e_{K-1})``); without it every end is allowed,
as in hmmlearn.  Gaussian log-densities expand the quadratic form so that all states cost one GEMM.
"""

from __future__ import annotations

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = [
    "forward_backward",
    "forward_backward_padded",
    "inverse_deviations",
    "left_right_transmat",
    "log_gaussian_density",
    "log_gaussian_density_padded",
    "pad_sequences",
    "precision_cholesky",
    "second_moments",
    "unpack_second_moments",
    "unpad_sequences",
    "validate_sequences",
    "viterbi",
]

_LOG_2PI = np.log(2.0 * np.pi)
# A scaled forward step whose normaliser falls below this is treated as underflow and the sequence
# is redone in log space; far above the denormal range so no precision is silently lost.
_SCALE_FLOOR = 1e-250
# Probabilities below _FLUSH of a frame's total are dropped inside the recursions (they could only
# matter if that path later became 1e290 times likelier than all others); posteriors and transition
# counts below _FLUSH_STATS are zeroed, an absolute error far below anything the M-step can see.
_FLUSH = 1e-290
_LOG_FLUSH = np.log(_FLUSH)
_FLUSH_STATS = 1e-150
# Posteriors of a frame must sum to 1; a scaled pass off by more than this (a flushed path that
# later dominates, seen with sharp 18-D Gaussians) is redone exactly in log space.
_POSTERIOR_TOL = 1e-6
# Flushing alpha_hat below _FLUSH_STATS drops transition counts of at most _FLUSH_STATS * max(v);
# a sequence whose v exceeds this (so more than 1e-20 could be lost) is redone in log space.
_V_CEILING = 1e130


# ----------------------------------------------------------------------------------- input checks
def validate_sequences(X, lengths=None) -> tuple[np.ndarray, np.ndarray]:
    """Check a concatenated batch and return ``(X, lengths)`` as float64 ``(N, D)`` and int64 ``(S,)``.

    ``X`` must be 2-D, non-empty and finite; ``lengths`` (default: one sequence of all rows) must be
    positive integers summing to ``N``.
    """
    try:
        X = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"X must be a numeric array of shape (n_samples, n_features); got {exc}") from exc
    if X.ndim != 2:
        raise InvalidInputError(
            f"X must be 2-D (n_samples, n_features); got shape {X.shape}. "
            "Reshape a single feature with X.reshape(-1, 1)."
        )
    if X.shape[0] == 0 or X.shape[1] == 0:
        raise InvalidInputError(f"X must have at least one sample and one feature; got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        bad = np.argwhere(~np.isfinite(X))[0]
        raise InvalidInputError(
            f"X must be finite; found {X[bad[0], bad[1]]} at row {bad[0]}, column {bad[1]} (NaN/inf not accepted)"
        )
    n = X.shape[0]
    if lengths is None:
        return X, np.array([n], dtype=np.int64)
    raw = np.asarray(lengths)
    if raw.ndim != 1 or raw.size == 0:
        raise InvalidInputError(f"lengths must be a non-empty 1-D sequence of ints; got shape {raw.shape}")
    if not (np.issubdtype(raw.dtype, np.integer) or (np.issubdtype(raw.dtype, np.floating)
                                                     and np.all(np.isfinite(raw)) and np.all(raw == np.round(raw)))):
        raise InvalidInputError(f"lengths must be integers; got {raw.dtype} values {raw[:5]}")
    lengths = raw.astype(np.int64)
    if np.any(lengths < 1):
        raise InvalidInputError(f"every length must be >= 1; got {lengths[lengths < 1][:5]}")
    if lengths.sum() != n:
        raise InvalidInputError(f"lengths must sum to the number of rows of X ({n}); they sum to {lengths.sum()}")
    return X, lengths


def _as_lengths(lengths, n: int) -> np.ndarray:
    if lengths is None:
        return np.array([n], dtype=np.int64)
    _, lengths = validate_sequences(np.zeros((n, 1)), lengths)
    return lengths


def _check_hmm(log_startprob, log_transmat, log_frameprob, log_endprob=None):
    """Return float arrays ``(pi, A, B, end)`` after checking their shapes agree on ``K``."""
    log_startprob = np.asarray(log_startprob, dtype=np.float64)
    log_transmat = np.asarray(log_transmat, dtype=np.float64)
    log_frameprob = np.asarray(log_frameprob, dtype=np.float64)
    k = log_startprob.shape[-1] if log_startprob.ndim == 1 else -1
    if log_startprob.ndim != 1 or log_transmat.shape != (k, k) or log_frameprob.shape[-1] != k:
        raise InvalidInputError(
            "expected log_startprob (K,), log_transmat (K, K) and log_frameprob (..., K); got shapes "
            f"{log_startprob.shape}, {log_transmat.shape}, {log_frameprob.shape}"
        )
    for name, arr in (("log_startprob", log_startprob), ("log_transmat", log_transmat),
                      ("log_frameprob", log_frameprob)):
        if np.any(np.isnan(arr)) or np.any(arr == np.inf):
            raise InvalidInputError(f"{name} must be finite or -inf (a log-probability); found NaN or +inf")
    if log_endprob is not None:
        log_endprob = np.asarray(log_endprob, dtype=np.float64)
        if log_endprob.shape != (k,) or np.any(np.isnan(log_endprob)) or np.any(log_endprob == np.inf):
            raise InvalidInputError(f"log_endprob must be (K,) = ({k},) log-probabilities; got {log_endprob.shape}")
    return log_startprob, log_transmat, log_frameprob, log_endprob


# ------------------------------------------------------------------------------------------ padding
def pad_sequences(values: np.ndarray, lengths: np.ndarray, fill: float = 0.0) -> np.ndarray:
    """Scatter concatenated rows ``(N, ...)`` into ``(S, T_max, ...)``; frames past a sequence's end get ``fill``."""
    values = np.asarray(values)
    lengths = np.asarray(lengths, dtype=np.int64)
    if lengths.ndim != 1 or lengths.size == 0 or np.any(lengths < 1) or lengths.sum() != values.shape[0]:
        raise InvalidInputError(f"lengths must be positive ints summing to the {values.shape[0]} rows; got {lengths}")
    t_max = int(lengths.max())
    out = np.full((lengths.size, t_max) + values.shape[1:], fill, dtype=values.dtype)
    out[_valid_mask(lengths, t_max)] = values
    return out


def unpad_sequences(padded: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Inverse of :func:`pad_sequences`: the valid frames of ``(S, T_max, ...)`` concatenated to ``(N, ...)``."""
    padded = np.asarray(padded)
    return padded[_valid_mask(np.asarray(lengths), padded.shape[1])]


def _valid_mask(lengths: np.ndarray, t_max: int) -> np.ndarray:
    return np.arange(t_max)[None, :] < np.asarray(lengths)[:, None]


# ------------------------------------------------------------------------------ Gaussian densities
def precision_cholesky(covars, covariance_type: str = "full") -> tuple[np.ndarray, np.ndarray]:
    """Whitening matrices ``P_k`` with ``P_k^T P_k = Sigma_k^{-1}`` and ``log det P_k``, by batched Cholesky.

    ``covars`` is ``(K, D, D)`` for ``"full"`` or ``(K, D)`` variances for ``"diag"``; returns
    ``P`` of shape ``(K, D, D)`` (lower triangular, diagonal for ``"diag"``) and ``(K,)`` log-determinants.
    """
    covars = np.asarray(covars, dtype=np.float64)
    if covariance_type == "diag":
        inv_sd = inverse_deviations(covars)
        prec = np.zeros(covars.shape + covars.shape[-1:])
        idx = np.arange(covars.shape[1])
        prec[:, idx, idx] = inv_sd
        return prec, np.log(inv_sd).sum(axis=1)
    if covariance_type != "full":
        raise InvalidInputError(f"covariance_type must be 'full' or 'diag'; got {covariance_type!r}")
    if covars.ndim != 3 or covars.shape[1] != covars.shape[2]:
        raise InvalidInputError(f"full covars must be (K, D, D); got shape {covars.shape}")
    if not np.all(np.isfinite(covars)):
        raise InvalidInputError("full covars must be finite")
    try:
        chol = np.linalg.cholesky(covars)
    except np.linalg.LinAlgError as exc:
        raise InvalidInputError("every covariance matrix must be symmetric positive definite") from exc
    d = covars.shape[1]
    # inv(L) for all K at once; L is lower triangular so so is its inverse.
    prec = np.linalg.solve(chol, np.broadcast_to(np.eye(d), chol.shape))
    return prec, -np.log(np.diagonal(chol, axis1=1, axis2=2)).sum(axis=1)


def inverse_deviations(covars) -> np.ndarray:
    """``1 / sqrt(variances)`` ``(K, D)`` of checked diag covariances: the diagonal of :func:`precision_cholesky`'s P,
    for callers that apply it elementwise instead of as ``(K, D, D)`` matrices (the same numbers, far fewer)."""
    covars = np.asarray(covars, dtype=np.float64)
    if covars.ndim != 2:
        raise InvalidInputError(f"diag covars must be (K, D) variances; got shape {covars.shape}")
    if not np.all(np.isfinite(covars)) or np.any(covars <= 0):
        raise InvalidInputError("diag covars must be finite and > 0")
    return 1.0 / np.sqrt(covars)


def second_moments(X, covariance_type: str = "full") -> np.ndarray:
    """Per-frame packed second moments of ``X`` (..., D): the ``D(D+1)/2`` products ``x_i x_j``, ``i <= j``
    (row-major upper triangle) for ``"full"``, or ``x_i**2`` for ``"diag"``; shape ``(..., M)``.

    They make every Gaussian quadratic form one GEMM, and are the M-step's scatter statistics.
    """
    X = np.asarray(X, dtype=np.float64)
    if covariance_type == "diag":
        return X * X
    d = X.shape[-1]
    # Built feature-major (M, N) so that every product writes one contiguous row (4x faster);
    # returned as its transpose, which BLAS reads as efficiently.
    cols = np.ascontiguousarray(X.reshape(-1, d).T)
    out = np.empty((d * (d + 1) // 2, cols.shape[1]))
    row = 0
    for i in range(d):
        np.multiply(cols[i:], cols[i], out=out[row:row + d - i])
        row += d - i
    return out.T.reshape(X.shape[:-1] + (out.shape[0],))


def unpack_second_moments(packed: np.ndarray, covariance_type: str = "full") -> np.ndarray:
    """Undo the packing of :func:`second_moments`: ``(..., M)`` to symmetric ``(..., D, D)``; diag is unchanged."""
    if covariance_type == "diag":
        return packed
    m = packed.shape[-1]
    d = int(round((np.sqrt(8 * m + 1) - 1) / 2))
    iu = np.triu_indices(d)
    out = np.empty(packed.shape[:-1] + (d, d))
    out[..., iu[0], iu[1]] = packed
    out[..., iu[1], iu[0]] = packed
    return out


def log_gaussian_density(X, means, covars, covariance_type: str = "full") -> np.ndarray:
    """``(N, K)`` matrix of ``log N(x_n | mu_k, Sigma_k)``; covars ``(K, D, D)`` ("full") or ``(K, D)`` ("diag")."""
    X = np.asarray(X, dtype=np.float64)
    means = np.asarray(means, dtype=np.float64)
    if X.ndim != 2 or means.ndim != 2 or means.shape[1] != X.shape[1]:
        raise InvalidInputError(f"expected X (N, D) and means (K, D) with the same D; got {X.shape}, {means.shape}")
    return log_gaussian_density_padded(X[None], means, covars, covariance_type)[0]


def log_gaussian_density_padded(X_pad, means, covars, covariance_type: str = "full",
                                moments: np.ndarray | None = None) -> np.ndarray:
    """``(S, T, K)`` log-densities of padded frames ``(S, T, D)``; means ``(K, D)`` or per sequence ``(S, K, D)``.

    Per-sequence means serve parametric HMMs, whose state means depend on each sequence's effect.
    The Mahalanobis term is expanded, ``x'Lx - 2 x'L mu + mu'L mu`` with ``L = P'P`` from the
    Cholesky factor, so all states cost one GEMM on :func:`second_moments` (3-5x faster than
    whitening each frame per state).  Without ``moments`` the frames are first centred on the
    mean of the means, which bounds the cancellation to ~1e-16 of (data spread / state sd)^2;
    a caller passing ``moments = second_moments(X_pad)`` should centre ``X_pad`` and ``means`` itself.
    """
    X_pad = np.asarray(X_pad, dtype=np.float64)
    means = np.asarray(means, dtype=np.float64)
    if X_pad.ndim != 3:
        raise InvalidInputError(f"padded frames must be (S, T, D); got shape {X_pad.shape}")
    s, t, d = X_pad.shape
    if covariance_type == "diag":  # L is diagonal: its products below are elementwise, the same numbers
        inv_sd = inverse_deviations(covars)
        lam, log_det = inv_sd * inv_sd, np.log(inv_sd).sum(axis=1)    # (K, D) precisions
    else:
        prec, log_det = precision_cholesky(covars, covariance_type)
        lam = np.matmul(prec.transpose(0, 2, 1), prec)                    # (K, D, D) precisions
    k = lam.shape[0]
    if lam.shape[1] != d or means.shape[-2:] != (k, d) or means.ndim not in (2, 3) \
            or (means.ndim == 3 and means.shape[0] != s):
        raise InvalidInputError(
            f"shapes disagree: frames {X_pad.shape}, means {means.shape}, covariances for K={k}, D={lam.shape[1]}"
        )
    if moments is None:
        centre = means.reshape(-1, d).mean(axis=0)
        X_pad = X_pad - centre
        means = means - centre
        moments = second_moments(X_pad, covariance_type)
    # log N = c_k - x'Lx / 2 + x'L mu - mu'L mu / 2, with c_k = log det P_k - D log(2 pi) / 2.
    if covariance_type == "diag":
        weights = -0.5 * lam.T                                             # (D, K)
        lam_mu = lam * means                                               # (K, D) or (S, K, D)
    else:
        iu = np.triu_indices(d)
        weights = -(1.0 - 0.5 * (iu[0] == iu[1]))[:, None] * lam[:, iu[0], iu[1]].T  # (M, K)
        lam_mu = np.einsum("kde,...ke->...kd", lam, means)
    out = (moments.reshape(s * t, -1) @ weights).reshape(s, t, k)
    if means.ndim == 2:
        out += (X_pad.reshape(s * t, d) @ lam_mu.T).reshape(s, t, k)
    else:
        out += np.matmul(X_pad, lam_mu.transpose(0, 2, 1))
    const = log_det - 0.5 * d * _LOG_2PI                                  # (K,): the density at the mean
    out += (const - 0.5 * np.einsum("...kd,...kd->...k", means, lam_mu))[..., None, :] if means.ndim == 3 \
        else const - 0.5 * np.einsum("kd,kd->k", means, lam_mu)
    # A Mahalanobis distance is >= 0; rounding in the expansion must not push a density above its peak.
    np.minimum(out, const, out=out)
    return out


# ---------------------------------------------------------------------------------- forward-backward
def forward_backward(log_startprob, log_transmat, log_frameprob, lengths,
                     log_endprob=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Posteriors of an HMM over a concatenated batch.

    Returns ``(log_likelihood (S,), gamma (N, K), xi (K, K))``: per-sequence log-likelihoods, state
    posteriors per frame, and expected transition counts summed over sequences and time (they add
    up to ``N - S``).  A sequence of zero probability gets ``-inf`` and zero posteriors.
    """
    log_frameprob = np.asarray(log_frameprob, dtype=np.float64)
    if log_frameprob.ndim != 2:
        raise InvalidInputError(f"log_frameprob must be (N, K); got shape {log_frameprob.shape}")
    lengths = _as_lengths(lengths, log_frameprob.shape[0])
    ll, gamma, xi = forward_backward_padded(log_startprob, log_transmat, pad_sequences(log_frameprob, lengths),
                                            lengths, log_endprob)
    return ll, unpad_sequences(gamma, lengths), xi


def forward_backward_padded(log_startprob, log_transmat, log_frameprob, lengths,
                            log_endprob=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`forward_backward` on padded frames ``(S, T_max, K)``; gamma comes back padded (zeros past each end).

    Frames past a sequence's end are ignored but must not hold NaN or ``+inf``.
    """
    log_pi, log_a, logb, log_end = _check_hmm(log_startprob, log_transmat, log_frameprob, log_endprob)
    if logb.ndim != 3:
        raise InvalidInputError(f"padded log_frameprob must be (S, T_max, K); got shape {logb.shape}")
    lengths = np.asarray(lengths, dtype=np.int64)
    s, t_max, k = logb.shape
    if lengths.shape != (s,) or np.any(lengths < 1) or np.any(lengths > t_max):
        raise InvalidInputError(f"lengths must be (S,) = ({s},) ints in [1, {t_max}]; got {lengths}")
    valid = _valid_mask(lengths, t_max)
    # Time-major (T, S, K) so that every step reads and writes contiguous (S, K) slices.
    step = np.arange(t_max)[:, None] < lengths[None, :] - 1              # (T, S): frame t has a successor

    # Per-frame scaling: b_hat = exp(log b - max_k log b), so the largest emission is exactly 1.
    # Clipping first keeps exp out of its (very slow) underflow path; the flush zeroes what was clipped.
    shift = logb.max(axis=2)
    shift[~valid | ~np.isfinite(shift)] = 0.0
    bhat = np.empty((t_max, s, k))
    with np.errstate(invalid="ignore"):
        np.subtract(logb.transpose(1, 0, 2), shift.T[:, :, None], out=bhat)
    np.maximum(bhat, _LOG_FLUSH - 1.0, out=bhat)
    np.exp(bhat, out=bhat)
    _flush(bhat, _FLUSH)
    bhat[~valid.T] = 1.0
    a = np.exp(log_a)
    ones = np.ones(k)
    end = ones if log_end is None else np.exp(log_end)

    alpha = np.empty((t_max, s, k))
    scale = np.empty((t_max, s))
    with np.errstate(divide="ignore", invalid="ignore", under="ignore"):
        np.multiply(np.exp(log_pi), bhat[0], out=alpha[0])
        for t in range(t_max):
            cur = alpha[t]
            if t:
                np.matmul(alpha[t - 1], a, out=cur)
                cur *= bhat[t]
            np.matmul(cur, ones, out=scale[t])
            cur /= scale[t, :, None]
            _flush(cur, _FLUSH)
        z_end = alpha[lengths - 1, np.arange(s)] @ end
        ll = np.where(valid.T, np.log(scale) + shift.T, 0.0).sum(axis=0) + np.log(z_end)
    bad = np.any(valid.T & ~(scale > _SCALE_FLOOR), axis=0) | ~(z_end > _SCALE_FLOOR)

    # beta_hat, so that gamma = alpha_hat * beta_hat; it is end / z_end on each sequence's last frame.
    # v_t = b_hat_{t+1} beta_hat_{t+1} / c_{t+1} is kept: beta_t = A v_t, and xi = A * sum_t alpha_t^T v_t.
    beta = np.empty((t_max, s, k))
    v = np.empty((t_max - 1, s, k))
    with np.errstate(divide="ignore", invalid="ignore", under="ignore", over="ignore"):
        term = np.where(bad[:, None], 0.0, end / z_end[:, None])
        beta[t_max - 1] = term
        for t in range(t_max - 2, -1, -1):
            np.multiply(bhat[t + 1], beta[t + 1], out=v[t])
            v[t] /= scale[t + 1, :, None]
            _flush(v[t], _FLUSH)
            np.matmul(v[t], a.T, out=beta[t])
            np.copyto(beta[t], term, where=~step[t, :, None])
        gamma = alpha * beta
        # Exactly, sum_k alpha_hat beta_hat = 1 on every frame.  A flushed forward entry breaks this
        # only if its path would have won later (at t = 0 the sum is P_all / P_kept); beta_hat then
        # often overflows too.  Such sequences are redone in log space, like underflowing ones.
        total = gamma.sum(axis=2)
    bad |= np.any(valid.T & ~(np.abs(total - 1.0) <= _POSTERIOR_TOL), axis=0)
    # xi multiplies alpha_hat (<= 1) by v, which is unbounded on states alpha barely reaches: the
    # flush of alpha_hat below _FLUSH_STATS is exact only while v stays below _V_CEILING.
    with np.errstate(invalid="ignore"):
        bad |= np.any(step[:-1] & ~(v.max(axis=2, initial=0.0) <= _V_CEILING), axis=0)
    live = step[:-1] & ~bad                                                # (T-1, S): pairs (t, t+1) that count
    # Posterior statistics: zero what does not count and flush what cannot matter, so the GEMMs
    # below (and the caller's M-step) never touch NaN from skipped sequences or denormal numbers.
    np.copyto(gamma, 0.0, where=~(valid & ~bad[:, None]).T[:, :, None])
    _flush(gamma, _FLUSH_STATS)
    u = alpha[:-1]
    for stat in (u, v):
        np.copyto(stat, 0.0, where=~live[:, :, None])
        _flush(stat, _FLUSH_STATS)
    xi = a * (u.reshape(-1, k).T @ v.reshape(-1, k))
    gamma = np.ascontiguousarray(gamma.transpose(1, 0, 2))

    if np.any(bad):
        idx = np.flatnonzero(bad)
        ll[idx], gamma[idx], xi_bad = _forward_backward_log(log_pi, log_a, logb[idx], lengths[idx], log_end)
        xi += xi_bad
    return ll, gamma, xi


def _flush(x: np.ndarray, floor: float) -> None:
    """Zero entries below ``floor`` in place, so no denormal number (100x slower arithmetic) survives."""
    np.multiply(x, x >= floor, out=x)


def _logsumexp(x: np.ndarray, axis: int) -> np.ndarray:
    m = np.max(x, axis=axis, keepdims=True)
    m[~np.isfinite(m)] = 0.0
    with np.errstate(divide="ignore", under="ignore"):
        return np.log(np.sum(np.exp(x - m), axis=axis)) + np.squeeze(m, axis=axis)


def _forward_backward_log(log_pi, log_a, logb, lengths, log_end):
    """Exact log-space forward-backward, for the few sequences the scaled pass cannot represent."""
    s, t_max, k = logb.shape
    valid = _valid_mask(lengths, t_max)
    logb = np.where(valid[:, :, None], logb, 0.0)
    end = np.zeros(k) if log_end is None else log_end
    la = np.empty((s, t_max, k))
    lb = np.empty((s, t_max, k))
    la[:, 0] = log_pi + logb[:, 0]
    for t in range(1, t_max):
        la[:, t] = _logsumexp(la[:, t - 1, :, None] + log_a, axis=1) + logb[:, t]
    ll = _logsumexp(la[np.arange(s), lengths - 1] + end, axis=1)
    lb[:, t_max - 1] = end
    for t in range(t_max - 2, -1, -1):
        stepped = _logsumexp(log_a + (logb[:, t + 1] + lb[:, t + 1])[:, None, :], axis=2)
        lb[:, t] = np.where((t < lengths - 1)[:, None], stepped, end)
    possible = np.isfinite(ll)
    norm = np.where(possible, ll, 0.0)
    # Frames past a sequence's end (padding) may overflow here; they are zeroed just below.
    with np.errstate(under="ignore", invalid="ignore", over="ignore"):
        gamma = np.exp(la + lb - norm[:, None, None])
        gamma[~valid | ~possible[:, None]] = 0.0
        xi = np.zeros((k, k))
        for t in range(t_max - 1):
            live = (t < lengths - 1) & possible
            if np.any(live):
                w = la[live, t, :, None] + log_a + (logb[live, t + 1] + lb[live, t + 1])[:, None, :]
                xi += np.exp(w - norm[live, None, None]).sum(axis=0)
    return ll, gamma, xi


# -------------------------------------------------------------------------------------------- Viterbi
def viterbi(log_startprob, log_transmat, log_frameprob, lengths,
            log_endprob=None) -> tuple[np.ndarray, np.ndarray]:
    """Most likely state paths: ``(best-path log-probability per sequence (S,), states (N,) int)``.

    Ties go to the lowest state index.  An impossible sequence gets ``-inf`` (its path is meaningless).
    """
    log_pi, log_a, logb, log_end = _check_hmm(log_startprob, log_transmat, log_frameprob, log_endprob)
    if logb.ndim != 2:
        raise InvalidInputError(f"log_frameprob must be (N, K); got shape {logb.shape}")
    lengths = _as_lengths(lengths, logb.shape[0])
    logb = pad_sequences(logb, lengths)
    s, t_max, k = logb.shape
    delta = log_pi + logb[:, 0]
    back = np.zeros((s, t_max, k), dtype=np.intp)
    finals = np.empty((s, k))
    ends = lengths - 1
    # cand[s, to, from]: the reduction runs over the contiguous last axis, 4x faster than over the middle.
    log_a_t = np.ascontiguousarray(log_a.T)
    cand = np.empty((s, k, k))
    flat = np.arange(s * k) * k
    with np.errstate(invalid="ignore"):
        for t in range(t_max):
            if t:
                np.add(delta[:, None, :], log_a_t, out=cand)
                best_from = cand.argmax(axis=2)
                back[:, t] = best_from
                delta = cand.ravel()[flat + best_from.ravel()].reshape(s, k) + logb[:, t]
            done = ends == t
            finals[done] = delta[done]
    if log_end is not None:
        finals = finals + log_end
    rows = np.arange(s)
    final_state = np.argmax(finals, axis=1)
    best = finals[rows, final_state]
    path = np.empty((s, t_max), dtype=np.intp)
    state = final_state
    for t in range(t_max - 1, -1, -1):
        state = np.where(ends == t, final_state, state)
        path[:, t] = state
        if t:
            state = np.where(t <= ends, back[rows, t, state], state)
    return best, unpad_sequences(path, lengths)


# ------------------------------------------------------------------------------------------ topology
def left_right_transmat(n_states: int, stay_prob: float = 0.5) -> np.ndarray:
    """``(K, K)`` Bakis transition matrix: stay with ``stay_prob``, else move one state right; last state absorbs."""
    if int(n_states) != n_states or n_states < 1:
        raise InvalidInputError(f"n_states must be a positive int; got {n_states!r}")
    if not 0.0 <= stay_prob < 1.0:
        raise InvalidInputError(f"stay_prob must be in [0, 1); got {stay_prob!r}")
    n = int(n_states)
    a = np.zeros((n, n))
    idx = np.arange(n - 1)
    a[idx, idx] = stay_prob
    a[idx, idx + 1] = 1.0 - stay_prob
    a[n - 1, n - 1] = 1.0
    return a
