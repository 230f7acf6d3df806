"""Parametric HMMs (Wilson & Bobick 1999) for action primitives whose shape depends on their effect phi.

Each state's Gaussian mean depends on the effect, linearly, ``mu_j(phi) = mean_bar_j + W_j phi``
(``mean_model="linear"``, the paper's model), or with a smooth bend added,
``mu_j(phi) = mean_bar_j + W_j phi + V_j g(phi)`` with fixed thin-plate-spline features ``g``
(``mean_model="tps"``, :mod:`~hoap_actions.primitives.hmm.effect_features`) and a ridge on ``V_j``; covariances
and transitions are shared by all effects.  One model is trained per primitive class from its
demonstrations and their effects; it then synthesises a prototype movement for a desired effect
(left-right models, as in the paper), scores a movement, estimates the effect that best explains a
movement, and recognises which class a movement belongs to.

The file format of :meth:`ParametricHMM.save` is documented in :mod:`~hoap_actions.primitives.hmm.phmm_file`;
recognition with several models is :func:`~hoap_actions.primitives.hmm.phmm_recognition.recognize`.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.errors import ExtrapolationWarning, IdentifiabilityError, InvalidInputError
from hoap_actions.primitives.base import Estimator, check_is_fitted
from hoap_actions.primitives.hmm import phmm_effects, phmm_file
from hoap_actions.primitives.hmm.effect_features import ThinPlateFeatures, effect_groups
from hoap_actions.primitives.hmm.hmm_math import (
    forward_backward_padded,
    log_gaussian_density_padded,
    unpack_second_moments,
    validate_sequences,
    viterbi,
)
from hoap_actions.primitives.hmm.phmm_batch import SequenceBatch, check_train_phi, equal_parts, is_int, is_real

__all__ = ["EMReport", "ParametricHMM"]

logger = logging.getLogger(__name__)

EM_FALL_WARNING = 1e-3  # fraction of the objective by which an EM iteration may fall before it warns

_TOPOLOGIES = ("left-right", "left-right-skip", "ergodic")
_MEAN_MODELS = ("linear", "tps")
# Share of a left-right-skip chain's initial moves that skip a state: EM only rescales transitions it
# starts with, so skips must start non-zero; the training data then decide how often they are taken.
_SKIP_SHARE = 1.0 / 3.0
_COVARIANCE_TYPES = ("full", "diag")
# synthesize warns (ExtrapolationWarning) when a component of phi lies beyond the training effects'
# range widened by this fraction of its span at each end: the mean model is only checked
# against data inside the range, and a little beyond it is routine (a grid's edge, a held-out effect).
EXTRAPOLATION_MARGIN = 0.5
# Relative ridge on the effect block of each state's regression: only matters when a state's
# weighted effects are degenerate (possible in ergodic models), and then picks the small-norm W.
_RIDGE = 1e-10


@dataclass(frozen=True)
class EMReport:
    """How training went: log-likelihood before each M-step, whether ``tol`` stopped it, iterations run."""

    history: tuple[float, ...]
    converged: bool
    n_iter: int


class ParametricHMM(Estimator):
    """Gaussian HMM whose state means depend on an effect parameter phi (linearly, or with a smooth bend).

    Parameters
    ----------
    n_states:
        Number of hidden states ``K``.
    topology:
        ``"left-right"``: a Bakis chain (stay or move one state right) that starts in the first state
        and must end in the last, so every demonstration traverses the whole movement (needed by
        :meth:`synthesize`); ``"left-right-skip"``: the same chain that may also jump over one state,
        so a faster performance with about half as many frames as states still traverses it (a
        held-out piece shorter than the shortest training piece can be explained); ``"ergodic"``: any
        transition, learned start distribution.
    covariance_type:
        ``"full"`` or ``"diag"`` state covariances.
    n_iter, tol:
        At most ``n_iter`` EM iterations; stop when the total training log-likelihood gains less than ``tol``.
    reg_covar:
        Added to every covariance diagonal, keeping covariances positive definite.
    covars_prior, covars_weight:
        Optional conjugate prior on the state covariances: prior variances ``(D,)`` worth
        ``covars_weight`` frames of every state.  Each M-step then takes the MAP covariance
        ``(scatter_j + w diag(prior)) / (occupancy_j + w)``, so a state seen in a handful of frames (a
        class with few demonstrations) borrows the prior's spread instead of collapsing onto
        ``reg_covar`` and ruling out every movement that differs from its few examples.  EM then
        climbs the log-likelihood plus the prior's log-density, which is what
        ``log_likelihood_history_`` records.
    random_state:
        Seed or Generator for the random restarts of :meth:`estimate_phi`.
    mean_model:
        ``"linear"``: ``mu_j(phi) = mean_bar_j + W_j phi`` (Wilson & Bobick's linear PHMM);
        ``"tps"``: plus ``V_j g(phi)``, a thin-plate spline in phi with centres at the distinct
        training effects, for movements whose shape is not affine in the effect (an arm reaching
        over a wide region changes its elbow strategy across it). The M-step stays closed form.
    smoothing:
        ``lambda >= 0``: the penalty ``lambda/2 sum_j tr(V_j^T Sigma_j^-1 V_j)`` added to the EM
        objective (a ridge on the bend, in each state's own metric; lambda is worth that many frames
        pulling V towards 0). 0 interpolates the training effects exactly, which needs at least
        ``p + 1 + m`` distinct effects for m centres. Choose it (and the mean model) by
        :func:`~hoap_actions.primitives.hmm.selection.select_mean_model`.
    max_centres:
        Most thin-plate centres (``"tps"``); more distinct training effects are thinned to an even cover.

    Attributes (after ``fit`` or ``load``)
    --------------------------------------
    startprob_, transmat_, mean_bar_, W_, V_, covars_:
        The learned HMM (module docstring); ``mu_j(phi) = mean_bar_[j] + W_[j] @ phi + V_[j] @ g(phi)``.
    effect_features_:
        ``g``, a :class:`~hoap_actions.primitives.hmm.effect_features.ThinPlateFeatures` (no features for "linear").
    train_phi_:
        ``(S, p)``: the effects of the training sequences.
    n_features_in_, phi_dim_:
        ``D`` and ``p``, the frame and effect dimensions.
    log_likelihood_history_, monitor_:
        Training log-likelihood per EM iteration, and an :class:`EMReport`.
    """

    _learned = ("startprob_", "transmat_", "mean_bar_", "W_", "V_", "effect_features_", "covars_", "train_phi_",
                "n_features_in_", "phi_dim_")
    _file_kind = "ParametricHMM"
    _format_version = phmm_file.FORMAT_VERSION
    _readable_versions = phmm_file.READABLE_VERSIONS
    _refit_free_params = ("random_state",)  # estimate_phi draws its restarts with it

    def __init__(self, n_states: int = 10, topology: str = "left-right", covariance_type: str = "full",
                 n_iter: int = 50, tol: float = 1e-4, reg_covar: float = 1e-6,
                 random_state: int | np.random.Generator | None = None, covars_prior=None,
                 covars_weight: float = 1.0, mean_model: str = "linear", smoothing: float = 1.0,
                 max_centres: int = 64) -> None:
        self.n_states = n_states
        self.topology = topology
        self.covariance_type = covariance_type
        self.n_iter = n_iter
        self.tol = tol
        self.reg_covar = reg_covar
        self.random_state = random_state
        self.covars_prior = covars_prior
        self.covars_weight = covars_weight
        self.mean_model = mean_model
        self.smoothing = smoothing
        self.max_centres = max_centres

    # ------------------------------------------------------------------------------- checks
    def _check_params(self) -> None:
        if not is_int(self.n_states) or self.n_states < 1:
            raise InvalidInputError(f"n_states must be a positive int; got {self.n_states!r}")
        if self.topology not in _TOPOLOGIES:
            raise InvalidInputError(f"topology must be one of {_TOPOLOGIES}; got {self.topology!r}")
        if self.covariance_type not in _COVARIANCE_TYPES:
            raise InvalidInputError(f"covariance_type must be one of {_COVARIANCE_TYPES}; got {self.covariance_type!r}")
        if not is_int(self.n_iter) or self.n_iter < 1:
            raise InvalidInputError(f"n_iter must be an int >= 1; got {self.n_iter!r}")
        if not (is_real(self.tol) and self.tol >= 0):
            raise InvalidInputError(f"tol must be a finite float >= 0; got {self.tol!r}")
        if not (is_real(self.reg_covar) and self.reg_covar >= 0):
            raise InvalidInputError(f"reg_covar must be a finite float >= 0; got {self.reg_covar!r}")
        if not (is_real(self.covars_weight) and self.covars_weight >= 0):
            raise InvalidInputError(f"covars_weight must be a finite float >= 0; got {self.covars_weight!r}")
        if self.mean_model not in _MEAN_MODELS:
            raise InvalidInputError(f"mean_model must be one of {_MEAN_MODELS}; got {self.mean_model!r}")
        if not (is_real(self.smoothing) and self.smoothing >= 0):
            raise InvalidInputError(f"smoothing must be a finite float >= 0; got {self.smoothing!r}")
        if not is_int(self.max_centres) or self.max_centres < 1:
            raise InvalidInputError(f"max_centres must be an int >= 1; got {self.max_centres!r}")

    def _prior_variances(self, n_features: int) -> np.ndarray | None:
        """``covars_prior`` as a checked (D,) float array, or None without a prior."""
        if self.covars_prior is None:
            return None
        prior = np.asarray(self.covars_prior, dtype=float)
        if prior.shape != (n_features,) or not np.all(np.isfinite(prior)) or np.any(prior <= 0):
            raise InvalidInputError(f"covars_prior must be {n_features} finite prior variances > 0 (one per "
                                    f"feature) or None; got shape {prior.shape}")
        return prior

    @property
    def _left_right(self) -> bool:
        """A chain from the first state to the last (with or without skips)."""
        return self.topology in ("left-right", "left-right-skip")

    @property
    def min_frames(self) -> int:
        """Fewest frames a sequence needs to be possible under this model: a chain must reach its last state."""
        k = int(self.n_states)
        if self.topology == "left-right":
            return k
        if self.topology == "left-right-skip":
            return k // 2 + 1  # ceil((k - 1) / 2) moves of at most two states, plus the first frame
        return 1

    def _check_phi(self, phi) -> np.ndarray:
        p = self.phi_dim_
        try:
            arr = np.asarray(phi, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise InvalidInputError(f"phi must be a numeric array of shape ({p},); got {phi!r}") from exc
        if arr.ndim == 0 and p == 1:
            arr = arr.reshape(1)
        if arr.shape != (p,):
            raise InvalidInputError(f"phi must have shape ({p},) (this model's effect dimension p = {p}); "
                                    f"got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InvalidInputError(f"phi must be finite; got {arr}")
        return arr

    def _check_sequence(self, X) -> np.ndarray:
        X, _ = validate_sequences(X)
        if X.shape[1] != self.n_features_in_:
            raise InvalidInputError(f"X has {X.shape[1]} features per frame; this model was trained on "
                                    f"{self.n_features_in_}")
        if X.shape[0] < self.min_frames:
            raise InvalidInputError(f"the sequence has {X.shape[0]} frames; this {self.n_states}-state "
                                    f"{self.topology} chain must reach its last state, which takes >= "
                                    f"{self.min_frames} frames")
        return X

    # ---------------------------------------------------------------------------- model maths
    def _log_end(self) -> np.ndarray | None:
        if not self._left_right:
            return None
        end = np.full(self.n_states, -np.inf)
        end[-1] = 0.0
        return end

    def _means_at(self, phi: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """State means for each effect: ``(S, K, D)`` from ``phi`` of shape ``(S, p)``, minus ``offset``."""
        means = (self.mean_bar_ - offset)[None] + np.einsum("kdp,sp->skd", self.W_, phi)
        if self.V_.shape[2]:  # the E-step's hot path: a linear model adds nothing
            means = means + np.einsum("kdm,sm->skd", self.V_, self.effect_features_.transform(phi))
        return means

    def _e_step(self, batch: SequenceBatch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-sequence log-likelihoods, padded posteriors (S, T, K) and expected transition counts (K, K)."""
        logb = log_gaussian_density_padded(batch.X, self._means_at(batch.phi, batch.offset), self.covars_,
                                           self.covariance_type, batch.moments)
        with np.errstate(divide="ignore"):
            return forward_backward_padded(np.log(self.startprob_), np.log(self.transmat_), logb,
                                           batch.lengths, self._log_end())

    def _m_step(self, batch: SequenceBatch, gamma: np.ndarray, xi: np.ndarray) -> None:
        """Closed-form maximisation: per-state weighted regression of frames on [phi; g(phi); 1] (a ridge
        ``smoothing`` on the g block), then covariances.

        Effects and features are centred for conditioning (W and V are unchanged by it); frames are
        centred on ``batch.offset``. The penalty's minimiser Z does not depend on the covariance, so
        ``Z`` and then ``Sigma = (scatter + lambda V V^T) / N`` maximise the penalised objective jointly.
        """
        k, d = self.n_states, batch.X.shape[2]
        p, m = batch.phi.shape[1], self.effect_features_.n_features
        g = self.effect_features_.transform(batch.phi)
        phi_centre, g_centre = batch.phi.mean(axis=0), g.mean(axis=0)
        omega = np.hstack([batch.phi - phi_centre, g - g_centre, np.ones((batch.phi.shape[0], 1))])
        q = omega.shape[1]
        occ = gamma.sum(axis=1)                                        # (S, K)
        occ_x = np.matmul(gamma.transpose(0, 2, 1), batch.X)           # (S, K, D)
        total = occ.sum(axis=0)                                        # (K,)
        num = np.einsum("skd,sq->kdq", occ_x, omega)                   # (K, D, q)
        gram = np.einsum("sk,sq,sr->kqr", occ, omega, omega)           # (K, q, q)
        visited = total > 1e-10 * max(total.max(), 1.0)
        gram[~visited] = np.eye(q)
        ridge = _RIDGE * np.trace(gram, axis1=1, axis2=2) / q
        gram[:, np.arange(q - 1), np.arange(q - 1)] += ridge[:, None]
        penalty = np.zeros(q)
        penalty[p:p + m] = float(self.smoothing)
        gram += np.diag(penalty)
        z = np.linalg.solve(gram, num.transpose(0, 2, 1)).transpose(0, 2, 1)  # (K, D, q) = [W | V | mu_bar_c]
        bend = z[:, :, p:p + m]

        # sum_t gamma (x - Z w)(x - Z w)^T = Sxx - N Z^T - Z N^T + Z G Z^T, per state.
        cross = np.matmul(num, z.transpose(0, 2, 1))
        fit = np.matmul(np.matmul(z, gram), z.transpose(0, 2, 1))
        sxx = unpack_second_moments(gamma.reshape(-1, k).T @ batch.moments.reshape(gamma[..., 0].size, -1),
                                    self.covariance_type)
        # fit includes Z diag(penalty) Z^T = lambda V V^T: the penalty's share of the covariance.
        if self.covariance_type == "full":
            scatter = sxx - cross - cross.transpose(0, 2, 1) + fit
            scatter = 0.5 * (scatter + scatter.transpose(0, 2, 1))
        else:
            scatter = (sxx - 2.0 * np.diagonal(cross, axis1=1, axis2=2) + np.diagonal(fit, axis1=1, axis2=2))
        weights = np.where(visited, total, 1.0)
        if self._prior is not None:  # MAP under the conjugate prior
            w = float(self.covars_weight)
            scatter = scatter + w * (np.diag(self._prior) if self.covariance_type == "full" else self._prior)
            weights = weights + w
        covars = scatter / weights.reshape((-1,) + (1,) * (scatter.ndim - 1))
        if self.covariance_type == "full":
            covars[:, np.arange(d), np.arange(d)] += self.reg_covar
        else:
            covars = np.maximum(covars, 0.0) + self.reg_covar

        # Unvisited states (ergodic models only) keep their parameters.
        # contiguous, as a loaded model's are: a fitted and a reloaded model then compute bit for bit alike
        self.W_ = np.ascontiguousarray(np.where(visited[:, None, None], z[:, :, :p], getattr(self, "W_", z[:, :, :p])))
        self.V_ = np.ascontiguousarray(np.where(visited[:, None, None], bend, getattr(self, "V_", bend)))
        mean_c = z[:, :, -1] + batch.offset - z[:, :, :p] @ phi_centre - bend @ g_centre
        self.mean_bar_ = np.where(visited[:, None], mean_c, getattr(self, "mean_bar_", mean_c))
        self.covars_ = np.where(visited.reshape((-1,) + (1,) * (covars.ndim - 1)), covars,
                                getattr(self, "covars_", covars))
        # A state never left (or never reached) keeps its old row, or at the start a self-loop.
        rows = xi.sum(axis=1, keepdims=True)
        keep = getattr(self, "transmat_", np.eye(k))
        self.transmat_ = np.where(rows > 0, xi / np.where(rows > 0, rows, 1.0), keep)
        if not self._left_right:
            start = gamma[:, 0].sum(axis=0)
            self.startprob_ = start / start.sum()

    # ------------------------------------------------------------------------------------- fit
    def fit(self, X, lengths=None, phi=None) -> ParametricHMM:
        """Train by extended Baum-Welch on sequences ``X`` (N, D) with ``lengths`` (``None``: one sequence)
        and their effects ``phi`` (S, p), one per sequence (required).

        The training effects must affinely span R^p (at least p + 1 of them, not all on one
        hyperplane) or W is not identifiable.  Left-right models start from each sequence cut into
        K equal parts (so training sequences need >= K frames); left-right-skip models from the same
        cut with a third of its moves turned into skips; ergodic models from the cut with smoothed
        transitions.
        """
        self._check_params()
        if phi is None:
            raise InvalidInputError("fit needs the effects phi (n_sequences, p) of the training sequences: "
                                    "fit(X, lengths, phi)")
        X, lengths = validate_sequences(X, lengths)
        phi = check_train_phi(phi, lengths.size)
        k = int(self.n_states)
        if self._left_right and lengths.min() < k:
            short = np.flatnonzero(lengths < k)
            raise InvalidInputError(f"{short.size} sequence(s) (first: #{short[0]}, {lengths[short[0]]} frames) are "
                                    f"shorter than the {k}-state left-right chain; every sequence needs >= n_states "
                                    "frames (use fewer states or drop the short sequences)")
        self._prior = self._prior_variances(X.shape[1])
        self.effect_features_ = self._effect_features(phi)
        batch = SequenceBatch.build(X, lengths, phi, X.mean(axis=0), self.covariance_type)
        for name in ("W_", "V_", "mean_bar_", "covars_", "transmat_", "startprob_"):
            self.__dict__.pop(name, None)
        self.n_features_in_ = X.shape[1]
        self.phi_dim_ = phi.shape[1]
        self.train_phi_ = phi

        gamma, xi = equal_parts(lengths, k)
        if self._left_right:
            self.startprob_ = np.eye(k)[0]
            if self.topology == "left-right-skip" and k > 2:
                moves = np.diagonal(xi, offset=1).copy()
                xi[np.arange(k - 1), np.arange(1, k)] = (1.0 - _SKIP_SHARE) * moves
                xi[np.arange(k - 2), np.arange(2, k)] = _SKIP_SHARE * moves[:-1]
        else:
            # Blur the cut so every state sees data and every transition stays possible.
            gamma = np.where(gamma.any(axis=2, keepdims=True), 0.9 * gamma + 0.1 / k, 0.0)
            xi = xi + 1.0
            first = gamma[:, 0].sum(axis=0)
            self.startprob_ = first / first.sum()
        self._fit_em(batch, gamma, xi)
        return self

    def _effect_features(self, phi: np.ndarray) -> ThinPlateFeatures:
        """``g`` for the training effects ``phi`` (S, p); IdentifiabilityError if an unpenalised bend
        has more coefficients than the distinct effects can pin down."""
        p = phi.shape[1]
        if self.mean_model == "linear" or p == 0:
            return ThinPlateFeatures.none(p)
        features = ThinPlateFeatures.from_effects(phi, int(self.max_centres))
        n_distinct = int(effect_groups(phi).max()) + 1
        if self.smoothing == 0 and n_distinct < p + 1 + features.n_features:
            raise IdentifiabilityError(
                f"mean_model='tps' with smoothing=0 has {p + 1 + features.n_features} coefficients per state (1 + p = "
                f"{p + 1} affine, {features.n_features} thin-plate centres) but the training effects hold only "
                f"{n_distinct} distinct values; give smoothing > 0, or max_centres <= {max(n_distinct - p - 1, 0)}")
        return features

    def _fit_em(self, batch: SequenceBatch, gamma: np.ndarray, xi: np.ndarray) -> None:
        self._m_step(batch, gamma, xi)
        history: list[float] = []
        converged = False
        for it in range(int(self.n_iter)):
            try:
                ll, gamma, xi = self._e_step(batch)
            except InvalidInputError as exc:
                raise InvalidInputError(f"EM iteration {it}: {exc}; increase reg_covar (now {self.reg_covar})") from exc
            total = float(ll.sum()) + self._log_prior()
            if not np.isfinite(total):
                raise InvalidInputError(f"EM iteration {it}: a training sequence has zero likelihood under the "
                                        "current model; check the data for outliers or increase reg_covar")
            history.append(total)
            gain = total - history[-2] if len(history) > 1 else np.inf
            logger.debug("EM iteration %d: log-likelihood %.6f (gain %.3g)", it, total, gain)
            if gain < -1e-8 * abs(total):
                # reg_covar and the ridge on W make the M-step inexact: small falls are expected (fitting the
                # classes of one paper recording: 60 falls, at most 2.2e-4 of the objective), large ones
                # point to states with few frames
                level = logging.WARNING if gain < -EM_FALL_WARNING * abs(total) else logging.DEBUG
                logger.log(level, "EM log-likelihood fell by %.3g at iteration %d: reg_covar and the ridge on W make "
                           "the M-step inexact; a large fall points to states with few frames", -gain, it)
            self._m_step(batch, gamma, xi)
            if gain < self.tol:
                converged = True
                break
        self.log_likelihood_history_ = np.array(history)
        self.monitor_ = EMReport(tuple(history), converged, len(history))

    def _log_prior(self) -> float:
        """The part of the EM objective besides the log-likelihood: the covariances' log-density (up to a
        constant) under the prior, ``-w/2 sum_j (tr(diag(prior) S_j^-1) + log det S_j)``, and the ridge
        on the bend, ``-lambda/2 sum_j tr(V_j^T S_j^-1 V_j)``; 0 for neither."""
        total = 0.0
        if self.V_.shape[2] and self.smoothing > 0:
            if self.covariance_type == "full":
                total -= 0.5 * self.smoothing * float(np.sum(self.V_ * np.linalg.solve(self.covars_, self.V_)))
            else:
                total -= 0.5 * self.smoothing * float(np.sum(self.V_**2 / self.covars_[:, :, None]))
        if self._prior is None:
            return total
        if self.covariance_type == "full":
            inverse_diagonal = np.diagonal(np.linalg.inv(self.covars_), axis1=1, axis2=2)
            log_det = np.linalg.slogdet(self.covars_)[1]
        else:
            inverse_diagonal, log_det = 1.0 / self.covars_, np.log(self.covars_).sum(axis=1)
        return total + float(-0.5 * self.covars_weight * np.sum(inverse_diagonal @ self._prior + log_det))

    # ----------------------------------------------------------------------------- inference
    def score(self, X, phi) -> float:
        """Log-likelihood of one sequence ``X`` (T, D) under the model at effect ``phi`` (p,)."""
        check_is_fitted(self)
        X = self._check_sequence(X)
        phi = self._check_phi(phi)
        return float(self._score_batch(X, phi[None])[0])

    def _score_batch(self, X: np.ndarray, phis: np.ndarray) -> np.ndarray:
        """Log-likelihood of the same sequence at each row of ``phis`` (R, p), batched over R."""
        r = phis.shape[0]
        batch = SequenceBatch.build(np.tile(X, (r, 1)), np.full(r, X.shape[0]), phis, self.mean_bar_.mean(axis=0),
                             self.covariance_type)
        return self._e_step(batch)[0]

    def predict(self, X, phi) -> np.ndarray:
        """Most likely state of each frame of ``X`` (T, D) at effect ``phi`` (Viterbi), ``(T,)`` ints."""
        check_is_fitted(self)
        X = self._check_sequence(X)
        phi = self._check_phi(phi)
        offset = self.mean_bar_.mean(axis=0)
        logb = log_gaussian_density_padded((X - offset)[None], self._means_at(phi[None], offset), self.covars_,
                                           self.covariance_type)[0]
        with np.errstate(divide="ignore"):
            return viterbi(np.log(self.startprob_), np.log(self.transmat_), logb, [X.shape[0]], self._log_end())[1]

    def estimate_phi(self, X, n_restarts: int = 5, n_iter: int = 30, tol: float = 1e-6) -> np.ndarray:
        """The effect phi (p,) that maximises the likelihood of one sequence ``X`` (T, D), by EM.

        Starts from the mean training effect and ``n_restarts - 1`` random training effects, all run
        together as one batch. For the linear mean model each M-step is the closed form
        ``phi = (sum_tj g_tj W_j^T S_j^-1 W_j)^-1 sum_tj g_tj W_j^T S_j^-1 (x_t - mean_bar_j)``; for a
        bending mean it is one Gauss-Newton step with the Jacobian ``W_j + V_j dg/dphi``, halved until
        the expected log-likelihood does not fall (generalised EM: the likelihood still never falls),
        which is why several starts matter there.
        """
        return self._estimate(X, n_restarts, n_iter, tol)[0]

    def _estimate(self, X, n_restarts: int = 5, n_iter: int = 30, tol: float = 1e-6) -> tuple[np.ndarray, float]:
        check_is_fitted(self)
        X = self._check_sequence(X)
        if not (is_int(n_restarts) and is_int(n_iter) and n_restarts >= 1 and n_iter >= 1):
            raise InvalidInputError(f"n_restarts and n_iter must be ints >= 1; got {n_restarts!r}, {n_iter!r}")
        if self.phi_dim_ == 0:
            return np.zeros(0), self.score(X, np.zeros(0))
        phis = self._restart_phis(n_restarts)
        r = phis.shape[0]
        offset = self.mean_bar_.mean(axis=0)
        batch = SequenceBatch.build(np.tile(X, (r, 1)), np.full(r, X.shape[0]), phis, offset, self.covariance_type)
        previous = np.full(r, -np.inf)
        for _ in range(int(n_iter)):
            ll, gamma, _ = self._e_step(batch)
            batch.phi = phmm_effects.phi_update(self, batch, gamma)
            if np.all(ll - previous < tol):
                break
            previous = ll
        ll = self._e_step(batch)[0]
        best = int(np.argmax(ll))
        return batch.phi[best].copy(), float(ll[best])

    def _restart_phis(self, n_restarts: int) -> np.ndarray:
        """Where :meth:`estimate_phi` starts its EMs ``(r, p)``: the mean training effect, then up to
        ``n_restarts - 1`` distinct training effects drawn with ``random_state``."""
        rng = np.random.default_rng(self.random_state)
        train = self.train_phi_
        picks = rng.choice(train.shape[0], size=min(int(n_restarts) - 1, train.shape[0]), replace=False)
        return np.vstack([train.mean(axis=0, keepdims=True), train[picks]])

    # ----------------------------------------------------------------------------- synthesis
    def synthesize(self, phi, n_frames: int | None = None) -> np.ndarray:
        """Prototype movement ``(T, D)`` for effect ``phi``: the state means at phi, linearly interpolated.

        Mean ``j + 1`` is reached ``v_j / (1 - a_jj)`` frames (the expected time in state j, whose
        visit probability ``v_j`` is 1 without skips) after mean ``j``, so
        ``T = round(sum_{j<K-1} v_j / (1 - a_jj)) + 1``; with ``n_frames`` the same path is resampled
        to that many frames.  Left-right models (with or without skips) only.

        A phi far outside the training effects (a component beyond their range widened by
        :data:`EXTRAPOLATION_MARGIN` of its span at either end) warns with :class:`ExtrapolationWarning`:
        the movement is then an extrapolation of the linear mean model that no demonstration supports.
        """
        check_is_fitted(self)
        if not self._left_right:
            raise InvalidInputError("synthesize needs a left-right model (topology='left-right'); this one is ergodic")
        phi = self._check_phi(phi)
        self._warn_if_extrapolating(phi)
        if n_frames is not None and (not is_int(n_frames) or n_frames < 1):
            raise InvalidInputError(f"n_frames must be None or an int >= 1; got {n_frames!r}")
        means = self.mean_bar_ + self.W_ @ phi                                   # (K, D)
        if self.V_.shape[2]:
            means = means + self.V_ @ self.effect_features_.transform(phi)[0]
        stay = np.clip(np.diagonal(self.transmat_)[:-1], 0.0, 1.0 - 1e-12)
        anchors = np.concatenate([[0.0], np.cumsum(self._visit_probabilities()[:-1] / (1.0 - stay))])
        if n_frames is None:
            n_frames = int(round(anchors[-1])) + 1
        times = np.linspace(0.0, anchors[-1], int(n_frames))
        if means.shape[0] == 1:
            return np.repeat(means, int(n_frames), axis=0)
        return np.stack([np.interp(times, anchors, means[:, i]) for i in range(means.shape[1])], axis=1)

    def _warn_if_extrapolating(self, phi: np.ndarray) -> None:
        """Warn (for the caller of the public method) if a component of ``phi`` is far outside the training range."""
        low, high = self.train_phi_.min(axis=0), self.train_phi_.max(axis=0)
        margin = EXTRAPOLATION_MARGIN * (high - low)
        far = np.flatnonzero((phi < low - margin) | (phi > high + margin))
        if far.size:
            ranges = "; ".join(f"phi[{i}] = {phi[i]:.4g}, trained on [{low[i]:.4g}, {high[i]:.4g}]" for i in far)
            warnings.warn(f"phi is far outside the training effects ({ranges}): beyond each range widened by "
                          f"{EXTRAPOLATION_MARGIN:g} of its span at either end, the synthesised movement is an "
                          f"unchecked extrapolation of the {self.mean_model} mean model (a bending mean strays "
                          "further than a linear one)", ExtrapolationWarning, stacklevel=3)

    def _visit_probabilities(self) -> np.ndarray:
        """Probability that a left-right chain passes through each state (1 for all without skips)."""
        a = self.transmat_
        k = a.shape[0]
        leave = np.clip(1.0 - np.diagonal(a), 1e-12, None)
        visit = np.zeros(k)
        visit[0] = 1.0
        for j in range(1, k):
            visit[j] = sum(visit[i] * a[i, j] / leave[i] for i in range(max(j - 2, 0), j))
        return visit

    # ------------------------------------------------------------------------------ files
    # ------------------------------------------------------------------------------ files
    def _write(self, path: Path, overwrite: bool) -> None:
        """Write the versioned ``.npz`` archive of :mod:`~hoap_actions.primitives.hmm.phmm_file`."""
        phmm_file.write_model(self, path, overwrite)

    @classmethod
    def _read(cls, path: Path) -> tuple[Any, Any, dict[str, np.ndarray]]:
        """The archive's ``kind``, ``format_version`` (as Python values; None if absent) and entries."""
        return phmm_file.read_model(path)

    @classmethod
    def _from_file(cls, path: Path, arrays: dict[str, np.ndarray], version: int) -> ParametricHMM:
        """The model in a readable archive, checked for meaning as well as shape."""
        model = phmm_file.model_from_arrays(cls, path, arrays, version)
        history = model.log_likelihood_history_
        model.monitor_ = EMReport(tuple(history.tolist()), model.__dict__.pop("converged_"), history.size)
        return model
