"""Parametric HMMs (Wilson & Bobick 1999) for action primitives whose shape depends on their effect phi.

Each state's Gaussian mean depends on the effect, linearly, ``mu_j(phi) = mean_bar_j + W_j phi``
(``mean_model="linear"``, the paper's model), or with a smooth bend added,
``mu_j(phi) = mean_bar_j + W_j phi + V_j g(phi)`` with fixed thin-plate-spline features ``g``
(``mean_model="tps"``, :mod:`~hoap_actions.primitives.effect_features`) and a ridge on ``V_j``; covariances
and transitions are shared by all effects.  One model is trained per primitive class from its
demonstrations and their effects; it then synthesises a prototype movement for a desired effect
(left-right models, as in the paper), scores a movement, estimates the effect that best explains a
movement, and recognises which class a movement belongs to.

File format of :meth:`ParametricHMM.save` (``format_version`` 3; version 1 files, written before the
covariance prior existed, load as models without one; version 1 and 2 files, written before the mean
model could bend, load as linear models), an uncompressed ``.npz`` archive
readable with ``numpy.load(path, allow_pickle=False)``; every entry is a plain numeric or unicode array:

=======================  ===================  ===============================================================
key                      shape                meaning
=======================  ===================  ===============================================================
format_version           () int               3
kind                     () str               "ParametricHMM"
n_states, n_iter         () int               hyper-parameters as given to ``__init__``
topology                 () str               "left-right", "left-right-skip" or "ergodic"
covariance_type          () str               "full" or "diag"
tol, reg_covar           () float             hyper-parameters
covars_prior             (0,) or (D,)         prior variances (empty: no prior)
covars_weight            () float             the prior's weight in frames per state
mean_model               () str               "linear" or "tps" (version 3)
smoothing                () float             ridge on V (version 3)
max_centres              () int               most thin-plate centres (version 3)
random_state             (0,) or (1,) int     the seed; empty when it was not an int (None or a Generator)
startprob_               (K,)                 initial state distribution
transmat_                (K, K)               transition matrix (rows sum to 1)
mean_bar_                (K, D)               state means at phi = 0
W_                       (K, D, p)            effect-to-mean matrices
V_                       (K, D, m)            feature-to-mean matrices (m = 0: linear; version 3)
feature_centres_         (m, p)               thin-plate centres in the unit box of the training range (v3)
feature_low_, _span_     (p,)                 that box: q = (phi - low) / span (version 3)
covars_                  (K, D, D) or (K, D)  covariances ("full") or variances ("diag")
train_params_            (S, p), S >= 1       effects phi of the training sequences (attribute ``train_phi_``:
                                              restarts of estimate_phi; synthesize warns far outside their range)
log_likelihood_history_  (I,)                 training log-likelihood per EM iteration
converged_               () bool              whether training stopped on ``tol``
=======================  ===================  ===============================================================

:meth:`ParametricHMM.load` checks meaning as well as shapes: ``startprob_`` and every row of
``transmat_`` are probability distributions, a left-right chain starts in state 0 and only stays or
moves right (by one state, or two with skips), and covariances are symmetric positive definite.
"""

from __future__ import annotations

import logging
import warnings
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from hoap_actions.errors import (
    DataFileError,
    ExtrapolationWarning,
    IdentifiabilityError,
    InvalidInputError,
)
from hoap_actions.outputs import claimed_file
from hoap_actions.primitives.base import Estimator, check_is_fitted
from hoap_actions.primitives.effect_features import ThinPlateFeatures, effect_groups
from hoap_actions.primitives.hmm_math import (
    forward_backward_padded,
    log_gaussian_density_padded,
    pad_sequences,
    precision_cholesky,
    second_moments,
    unpack_second_moments,
    validate_sequences,
    viterbi,
)

__all__ = ["EMReport", "ParametricHMM", "Recognition", "recognize"]

logger = logging.getLogger(__name__)

EM_FALL_WARNING = 1e-3  # fraction of the objective by which an EM iteration may fall before it warns

FORMAT_VERSION = 3
_READABLE_VERSIONS = (1, 2, 3)
_TOPOLOGIES = ("left-right", "left-right-skip", "ergodic")
_MEAN_MODELS = ("linear", "tps")
# Effect estimation with a bending mean: Gauss-Newton steps inside EM, each halved until the expected
# log-likelihood does not fall (a generalised EM step); after this many halvings phi stays where it was.
_MAX_STEP_HALVINGS = 20
# Share of a left-right-skip chain's initial moves that skip a state: EM only rescales transitions it
# starts with, so skips must start non-zero; the training data then decide how often they are taken.
_SKIP_SHARE = 1.0 / 3.0
_COVARIANCE_TYPES = ("full", "diag")
# Loading: how a file is recognised, and how far saved values may be from what EM produces.
_ZIP_SIGNATURES = (b"PK\x03\x04", b"PK\x05\x06")  # an .npz archive is a zip file (with members / empty)
_OTHER_SIGNATURES = (
    (b"\x89HDF\r\n\x1a\n", "an HDF5 file (such as a demonstrations dataset)"),
    (b"\x93NUMPY", "a single .npy array, not an .npz archive"),
)
_SNIFF_BYTES = 16
_ACCEPTED_FILES = "ParametricHMM.load reads the .npz archives written by ParametricHMM.save"
# Entries stored under another name than their attribute (the file format is older than the name phi).
_ATTRIBUTE_OF_ENTRY = {"train_params_": "train_phi_"}
_PROBABILITY_TOLERANCE = 1e-6  # |sum - 1| of a saved distribution; EM's normalisation errs by ~1e-16
_SYMMETRY_TOLERANCE = 1e-8  # largest |S - S^T| relative to the largest |S| (EM's covariances are exactly symmetric)
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


@dataclass(frozen=True, eq=False)
class Recognition:
    """Result of :func:`recognize`: the best class id, its effect estimate, and every class's log-likelihood."""

    label: int
    phi: np.ndarray
    log_likelihoods: Mapping[int, float]
    phis: Mapping[int, np.ndarray] = field(default_factory=dict)


@dataclass
class _Batch:
    """Sequences padded once: frames (S, T, D) centred on ``offset``, their second moments, effects (S, p)."""

    X: np.ndarray
    moments: np.ndarray
    lengths: np.ndarray
    offset: np.ndarray
    phi: np.ndarray

    @classmethod
    def build(cls, X: np.ndarray, lengths: np.ndarray, phi: np.ndarray, offset: np.ndarray,
              covariance_type: str) -> _Batch:
        padded = pad_sequences(X - offset, lengths)
        return cls(padded, second_moments(padded, covariance_type), lengths, offset, phi)


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
        :func:`~hoap_actions.primitives.phmm_selection.select_mean_model`.
    max_centres:
        Most thin-plate centres (``"tps"``); more distinct training effects are thinned to an even cover.

    Attributes (after ``fit`` or ``load``)
    --------------------------------------
    startprob_, transmat_, mean_bar_, W_, V_, covars_:
        The learned HMM (module docstring); ``mu_j(phi) = mean_bar_[j] + W_[j] @ phi + V_[j] @ g(phi)``.
    effect_features_:
        ``g``, a :class:`~hoap_actions.primitives.effect_features.ThinPlateFeatures` (no features for "linear").
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
    _format_version = FORMAT_VERSION
    _readable_versions = _READABLE_VERSIONS

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
    def _check_hyper_parameters(self) -> None:
        if not _is_int(self.n_states) or self.n_states < 1:
            raise InvalidInputError(f"n_states must be a positive int; got {self.n_states!r}")
        if self.topology not in _TOPOLOGIES:
            raise InvalidInputError(f"topology must be one of {_TOPOLOGIES}; got {self.topology!r}")
        if self.covariance_type not in _COVARIANCE_TYPES:
            raise InvalidInputError(f"covariance_type must be one of {_COVARIANCE_TYPES}; got {self.covariance_type!r}")
        if not _is_int(self.n_iter) or self.n_iter < 1:
            raise InvalidInputError(f"n_iter must be an int >= 1; got {self.n_iter!r}")
        if not (_is_real(self.tol) and self.tol >= 0):
            raise InvalidInputError(f"tol must be a finite float >= 0; got {self.tol!r}")
        if not (_is_real(self.reg_covar) and self.reg_covar >= 0):
            raise InvalidInputError(f"reg_covar must be a finite float >= 0; got {self.reg_covar!r}")
        if not (_is_real(self.covars_weight) and self.covars_weight >= 0):
            raise InvalidInputError(f"covars_weight must be a finite float >= 0; got {self.covars_weight!r}")
        if self.mean_model not in _MEAN_MODELS:
            raise InvalidInputError(f"mean_model must be one of {_MEAN_MODELS}; got {self.mean_model!r}")
        if not (_is_real(self.smoothing) and self.smoothing >= 0):
            raise InvalidInputError(f"smoothing must be a finite float >= 0; got {self.smoothing!r}")
        if not _is_int(self.max_centres) or self.max_centres < 1:
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

    def _e_step(self, batch: _Batch) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-sequence log-likelihoods, padded posteriors (S, T, K) and expected transition counts (K, K)."""
        logb = log_gaussian_density_padded(batch.X, self._means_at(batch.phi, batch.offset), self.covars_,
                                           self.covariance_type, batch.moments)
        with np.errstate(divide="ignore"):
            return forward_backward_padded(np.log(self.startprob_), np.log(self.transmat_), logb,
                                           batch.lengths, self._log_end())

    def _m_step(self, batch: _Batch, gamma: np.ndarray, xi: np.ndarray) -> None:
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
    def fit(self, X, lengths, phi) -> ParametricHMM:
        """Train by extended Baum-Welch on sequences ``X`` (N, D) with ``lengths`` and their effects ``phi`` (S, p).

        The training effects must affinely span R^p (at least p + 1 of them, not all on one
        hyperplane) or W is not identifiable.  Left-right models start from each sequence cut into
        K equal parts (so training sequences need >= K frames); left-right-skip models from the same
        cut with a third of its moves turned into skips; ergodic models from the cut with smoothed
        transitions.
        """
        self._check_hyper_parameters()
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
        batch = _Batch.build(X, lengths, phi, X.mean(axis=0), self.covariance_type)
        for name in ("W_", "V_", "mean_bar_", "covars_", "transmat_", "startprob_"):
            self.__dict__.pop(name, None)
        self.n_features_in_ = X.shape[1]
        self.phi_dim_ = phi.shape[1]
        self.train_phi_ = phi

        gamma, xi = _equal_parts(lengths, k)
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

    def _fit_em(self, batch: _Batch, gamma: np.ndarray, xi: np.ndarray) -> None:
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
        batch = _Batch.build(np.tile(X, (r, 1)), np.full(r, X.shape[0]), phis, self.mean_bar_.mean(axis=0),
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
        if not (_is_int(n_restarts) and _is_int(n_iter) and n_restarts >= 1 and n_iter >= 1):
            raise InvalidInputError(f"n_restarts and n_iter must be ints >= 1; got {n_restarts!r}, {n_iter!r}")
        if self.phi_dim_ == 0:
            return np.zeros(0), self.score(X, np.zeros(0))
        rng = np.random.default_rng(self.random_state)
        train = self.train_phi_
        picks = rng.choice(train.shape[0], size=min(int(n_restarts) - 1, train.shape[0]), replace=False)
        phis = np.vstack([train.mean(axis=0, keepdims=True), train[picks]])
        r = phis.shape[0]
        offset = self.mean_bar_.mean(axis=0)
        batch = _Batch.build(np.tile(X, (r, 1)), np.full(r, X.shape[0]), phis, offset, self.covariance_type)
        previous = np.full(r, -np.inf)
        for _ in range(int(n_iter)):
            ll, gamma, _ = self._e_step(batch)
            batch.phi = self._phi_update(batch, gamma)
            if np.all(ll - previous < tol):
                break
            previous = ll
        ll = self._e_step(batch)[0]
        best = int(np.argmax(ll))
        return batch.phi[best].copy(), float(ll[best])

    def _phi_update(self, batch: _Batch, gamma: np.ndarray) -> np.ndarray:
        """A phi per sequence that raises the expected complete log-likelihood: its maximiser (linear
        means) or a damped Gauss-Newton step towards it (bending means)."""
        if self.V_.shape[2]:
            return self._phi_gauss_newton(batch, gamma)
        prec, _ = precision_cholesky(self.covars_, self.covariance_type)
        pw = np.matmul(prec, self.W_)                                          # (K, D, p): P_j W_j
        pm = np.einsum("kij,kj->ki", prec, self.mean_bar_ - batch.offset)      # (K, D):    P_j mu_bar_j
        occ = gamma.sum(axis=1)                                                # (S, K)
        occ_x = np.matmul(gamma.transpose(0, 2, 1), batch.X)                   # (S, K, D)
        lhs = np.einsum("sk,kdp,kdq->spq", occ, pw, pw)
        resid = np.einsum("kij,skj->ski", prec, occ_x) - occ[:, :, None] * pm[None]
        rhs = np.einsum("kdp,skd->sp", pw, resid)
        try:
            return np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError as exc:
            raise IdentifiabilityError("phi is not identifiable from this sequence under this model "
                                       "(sum_j W_j^T S_j^-1 W_j is singular)") from exc

    def _phi_gauss_newton(self, batch: _Batch, gamma: np.ndarray) -> np.ndarray:
        """One Gauss-Newton step on ``Q(phi) = sum_tj g_tj log N(x_t; mu_j(phi), S_j)`` per sequence, halved
        (per sequence) until Q does not fall; whitened by ``P_j`` with ``P_j^T P_j = S_j^-1``."""
        prec, _ = precision_cholesky(self.covars_, self.covariance_type)
        occ = gamma.sum(axis=1)                                                # (S, K)
        white_x = np.einsum("kij,skj->ski", prec, np.matmul(gamma.transpose(0, 2, 1), batch.X))  # P_j sum_t g x_t

        def white_means(phi: np.ndarray) -> np.ndarray:
            return np.einsum("kij,skj->ski", prec, self._means_at(phi, batch.offset))

        def expected(white_mu: np.ndarray) -> np.ndarray:
            return np.einsum("skd,skd->s", white_mu, white_x - 0.5 * occ[:, :, None] * white_mu)

        phi = batch.phi
        jac = self.W_[None] + np.einsum("kdm,smp->skdp", self.V_, self.effect_features_.jacobian(phi))
        white_jac = np.einsum("kij,skjp->skip", prec, jac)                     # (S, K, D, p)
        white_mu = white_means(phi)
        lhs = np.einsum("sk,skdp,skdq->spq", occ, white_jac, white_jac)
        rhs = np.einsum("skdp,skd->sp", white_jac, white_x - occ[:, :, None] * white_mu)
        try:
            step = np.linalg.solve(lhs, rhs[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError as exc:
            raise IdentifiabilityError("phi is not identifiable from this sequence under this model (the "
                                       "Gauss-Newton matrix sum_j J_j^T S_j^-1 J_j is singular)") from exc
        before, share = expected(white_mu), np.ones(phi.shape[0])
        for _ in range(_MAX_STEP_HALVINGS):
            worse = expected(white_means(phi + share[:, None] * step)) < before
            if not worse.any():
                break
            share = np.where(worse, 0.5 * share, share)
        else:
            share = np.where(expected(white_means(phi + share[:, None] * step)) < before, 0.0, share)
        return phi + share[:, None] * step

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
        if n_frames is not None and (not _is_int(n_frames) or n_frames < 1):
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
    def _write(self, path: Path, overwrite: bool) -> None:
        """Write the versioned ``.npz`` archive documented in this module."""
        seed = self.random_state
        arrays = {
            "format_version": np.array(self._format_version),
            "kind": np.array(self._file_kind),
            "n_states": np.array(int(self.n_states)),
            "topology": np.array(str(self.topology)),
            "covariance_type": np.array(str(self.covariance_type)),
            "n_iter": np.array(int(self.n_iter)),
            "tol": np.array(float(self.tol)),
            "reg_covar": np.array(float(self.reg_covar)),
            "random_state": np.array([int(seed)] if isinstance(seed, (int, np.integer)) else [], dtype=np.int64),
            "covars_prior": np.zeros(0) if self.covars_prior is None else np.asarray(self.covars_prior, dtype=float),
            "covars_weight": np.array(float(self.covars_weight)),
            "mean_model": np.array(str(self.mean_model)),
            "smoothing": np.array(float(self.smoothing)),
            "max_centres": np.array(int(self.max_centres)),
            "startprob_": self.startprob_,
            "transmat_": self.transmat_,
            "mean_bar_": self.mean_bar_,
            "W_": self.W_,
            "V_": self.V_,
            "feature_centres_": self.effect_features_.centres,
            "feature_low_": self.effect_features_.low,
            "feature_span_": self.effect_features_.span,
            "covars_": self.covars_,
            "train_params_": self.train_phi_,
            "log_likelihood_history_": getattr(self, "log_likelihood_history_", np.zeros(0)),
            "converged_": np.array(bool(getattr(self, "monitor_", EMReport((), False, 0)).converged)),
        }
        with claimed_file(path, overwrite, what="ParametricHMM file") as partial:
            with open(partial, "wb") as fh:
                np.savez(fh, **arrays)

    @classmethod
    def _read(cls, path: Path) -> tuple[Any, Any, dict[str, np.ndarray]]:
        """The archive's ``kind``, ``format_version`` (as Python values; None if absent) and entries."""
        if not path.is_file():
            raise DataFileError(f"model file {path} does not exist")
        arrays = _read_npz(path)
        kind, version = arrays.get("kind"), arrays.get("format_version")
        return (None if kind is None else kind.tolist()), (None if version is None else version.tolist()), arrays

    @classmethod
    def _from_file(cls, path: Path, arrays: dict[str, np.ndarray], version: int) -> ParametricHMM:
        """The model in the entries of a readable archive, checked for meaning as well as shape.

        An archive whose learned values a trained model cannot have (probabilities that do not sum to
        1, covariances that are not positive definite, ...) raises DataFileError: it would load and
        then fail far away.
        """
        try:
            seed = arrays["random_state"]
            model = cls(n_states=int(arrays["n_states"]), topology=str(arrays["topology"]),
                        covariance_type=str(arrays["covariance_type"]), n_iter=int(arrays["n_iter"]),
                        tol=float(arrays["tol"]), reg_covar=float(arrays["reg_covar"]),
                        random_state=int(seed[0]) if seed.size else None)
            if version >= 2:
                prior = np.asarray(arrays["covars_prior"], dtype=np.float64)
                model.covars_prior = prior if prior.size else None
                model.covars_weight = float(arrays["covars_weight"])
            if version >= 3:
                model.mean_model = str(arrays["mean_model"])
                model.smoothing = float(arrays["smoothing"])
                model.max_centres = int(arrays["max_centres"])
            model._check_hyper_parameters()
            k = model.n_states
            mean_bar = _entry(arrays, "mean_bar_", 2, path)
            w = _entry(arrays, "W_", 3, path)
            train = _entry(arrays, "train_params_", 2, path)
            d, p = mean_bar.shape[1], w.shape[2]
            try:
                model._prior_variances(d)
            except InvalidInputError as exc:
                raise DataFileError(f"{path}: entry covars_prior is malformed ({exc})") from exc
            cov_shape = (k, d, d) if model.covariance_type == "full" else (k, d)
            learned = {
                "startprob_": (_entry(arrays, "startprob_", 1, path), (k,)),
                "transmat_": (_entry(arrays, "transmat_", 2, path), (k, k)),
                "mean_bar_": (mean_bar, (k, d)),
                "W_": (w, (k, d, p)),
                "covars_": (_entry(arrays, "covars_", len(cov_shape), path), cov_shape),
                "train_params_": (train, (train.shape[0], p)),
            }
            if version >= 3:
                bend = _entry(arrays, "V_", 3, path)
                m = bend.shape[2]
                learned["V_"] = (bend, (k, d, m))
                learned["feature_centres_"] = (_entry(arrays, "feature_centres_", 2, path), (m, p))
                learned["feature_low_"] = (_entry(arrays, "feature_low_", 1, path), (p,))
                learned["feature_span_"] = (_entry(arrays, "feature_span_", 1, path), (p,))
            else:
                learned["V_"] = (np.zeros((k, d, 0)), (k, d, 0))
            for name, (value, shape) in learned.items():
                if value.shape != shape or not np.all(np.isfinite(value)):
                    raise DataFileError(f"{path}: entry {name} has shape {value.shape}, expected {shape} and finite")
                setattr(model, _ATTRIBUTE_OF_ENTRY.get(name, name), value)
            model.effect_features_ = _features_from_entries(model, path)
            model._check_learned_meaning(path)
            history = _entry(arrays, "log_likelihood_history_", 1, path)
            converged = bool(arrays["converged_"])
        except KeyError as exc:
            raise DataFileError(f"{path}: entry {exc} is missing; {_ACCEPTED_FILES}") from exc
        except (IndexError, TypeError, ValueError) as exc:
            raise DataFileError(f"{path}: missing or malformed entry ({exc})") from exc
        model.n_features_in_ = d
        model.phi_dim_ = p
        model.log_likelihood_history_ = history
        model.monitor_ = EMReport(tuple(history.tolist()), converged, history.size)
        return model

    def _check_learned_meaning(self, path: Path) -> None:
        """Raise DataFileError naming ``path`` and the entry if the learned values are not a valid HMM.

        Shapes and finiteness are checked already; this checks what EM always produces: probability
        distributions, symmetric positive definite covariances, and the transitions the topology allows.
        """
        def bad(name: str, problem: str, accepted: str) -> DataFileError:
            return DataFileError(f"{path}: entry {name} {problem}; accepted: {accepted}")

        if self.train_phi_.shape[0] == 0:
            raise bad("train_params_", "is empty", "the (S, p) effects of the S >= 1 training sequences")
        start, trans = self.startprob_, self.transmat_
        if np.any(start < 0) or abs(start.sum() - 1.0) > _PROBABILITY_TOLERANCE:
            raise bad("startprob_", f"is not a probability distribution (sum {start.sum():.6g}, smallest "
                      f"{start.min():.6g})", f"non-negative values summing to 1 (within {_PROBABILITY_TOLERANCE})")
        row_sums = trans.sum(axis=1)
        wrong = np.flatnonzero(np.any(trans < 0, axis=1) | (np.abs(row_sums - 1.0) > _PROBABILITY_TOLERANCE))
        if wrong.size:
            i = int(wrong[0])
            raise bad("transmat_", f"row {i} is not a probability distribution (sum {row_sums[i]:.6g}, smallest "
                      f"{trans[i].min():.6g}; {wrong.size} bad row(s))",
                      f"non-negative rows each summing to 1 (within {_PROBABILITY_TOLERANCE})")
        if self._left_right:
            reach = 2 if self.topology == "left-right-skip" else 1
            offsets = np.subtract.outer(np.arange(self.n_states), np.arange(self.n_states))  # i - j
            if start[0] < 1.0 - _PROBABILITY_TOLERANCE or np.any(trans[(offsets > 0) | (offsets < -reach)] != 0):
                raise bad("transmat_/startprob_", f"break the {self.topology} chain",
                          f"a chain that starts in state 0 and only stays or moves right by at most {reach} "
                          f"state(s), as training a {self.topology} model gives")
        covars = self.covars_
        if self.covariance_type == "full":
            asymmetry = np.abs(covars - covars.transpose(0, 2, 1)).max()
            if asymmetry > _SYMMETRY_TOLERANCE * max(np.abs(covars).max(), 1.0):
                raise bad("covars_", f"holds a non-symmetric matrix (largest asymmetry {asymmetry:.3g})",
                          "symmetric positive definite covariance matrices")
        try:
            precision_cholesky(covars, self.covariance_type)
        except InvalidInputError as exc:
            raise bad("covars_", "holds a covariance that is not positive definite",
                      "symmetric positive definite covariance matrices ('full') or variances > 0 ('diag')") from exc


# ------------------------------------------------------------------------------------- helpers
def _read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every entry of the ``.npz`` archive ``path`` as an array, never unpickling anything.

    Other files are told apart by their first bytes first, so the error says what the file looks
    like instead of numpy's guess that it might be pickled data.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
    except OSError as exc:
        raise DataFileError(f"could not read model file {path}: {exc}") from exc
    if not head.startswith(_ZIP_SIGNATURES):
        raise DataFileError(f"{path} is not a ParametricHMM file: it looks like {_describe_file(head)}; "
                            f"{_ACCEPTED_FILES}")
    arrays: dict[str, np.ndarray] = {}
    try:
        with np.load(path, allow_pickle=False) as data:
            for key in data.files:
                try:
                    arrays[key] = np.asarray(data[key])
                except ValueError as exc:  # an object array: numpy would need to unpickle it
                    raise DataFileError(f"{path}: entry {key} holds Python objects, not a plain numeric or text "
                                        f"array; {_ACCEPTED_FILES}, whose entries never hold objects") from exc
    except DataFileError:
        raise
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
        raise DataFileError(f"{path} is not a readable ParametricHMM .npz file (truncated or corrupt?): {exc}") from exc
    return arrays


def _describe_file(head: bytes) -> str:
    """What a file that is not a zip archive looks like, from its first bytes."""
    if not head:
        return "an empty file"
    for signature, description in _OTHER_SIGNATURES:
        if head.startswith(signature):
            return description
    if head.lstrip()[:1] in (b"{", b"["):
        return "a JSON document (such as a PrimitiveDiscovery or ActionGrammar model)"
    return f"no format hoap_actions writes (it starts with {head!r})"


def _entry(arrays: Mapping[str, np.ndarray], name: str, ndim: int, path: Path) -> np.ndarray:
    """The learned array ``name`` as float64 with ``ndim`` axes, or a DataFileError naming it."""
    if name not in arrays:
        raise DataFileError(f"{path}: entry {name} is missing; {_ACCEPTED_FILES}")
    value = arrays[name]
    if value.dtype.kind not in "biuf" or value.ndim != ndim:
        raise DataFileError(f"{path}: entry {name} is a {value.ndim}-D {value.dtype} array; accepted: a "
                            f"{ndim}-D numeric array")
    return value.astype(np.float64)


def _features_from_entries(model: ParametricHMM, path: Path) -> ThinPlateFeatures:
    """The thin-plate features a loaded model's entries describe (none for linear models and old files),
    or DataFileError if they contradict its mean model or are not usable features."""
    p, m = model.W_.shape[2], model.V_.shape[2]
    if not hasattr(model, "feature_centres_"):
        return ThinPlateFeatures.none(p)
    features = ThinPlateFeatures(model.__dict__.pop("feature_centres_"), model.__dict__.pop("feature_low_"),
                                 model.__dict__.pop("feature_span_"))
    if (model.mean_model == "linear" and m > 0) or (model.mean_model == "tps" and m == 0 and p > 0):
        raise DataFileError(f"{path}: entry V_ has {m} feature column(s) but mean_model is {model.mean_model!r}; "
                            "accepted: none for 'linear' (or an effect of size 0), one per thin-plate centre for 'tps'")
    try:
        features.check(p)
    except InvalidInputError as exc:
        raise DataFileError(f"{path}: entries feature_centres_/feature_low_/feature_span_ are malformed "
                            f"({exc})") from exc
    return features


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool) \
        and bool(np.isfinite(value))


def check_train_phi(train_phi, n_sequences: int) -> np.ndarray:
    """Training effects as float (S, p), affinely spanning R^p so each W_j is identifiable."""
    try:
        phi = np.asarray(train_phi, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"phi must be a numeric array of shape (n_sequences, p); got {exc}") from exc
    if phi.ndim != 2 or phi.shape[0] != n_sequences:
        raise InvalidInputError(f"phi must have shape (n_sequences, p) = ({n_sequences}, p), one effect per "
                                f"sequence; got shape {phi.shape} (use phi.reshape(-1, 1) for a scalar effect)")
    if not np.all(np.isfinite(phi)):
        raise InvalidInputError("phi must be finite; found NaN or inf")
    p = phi.shape[1]
    if p and np.linalg.matrix_rank(phi - phi.mean(axis=0)) < p:
        raise IdentifiabilityError(
            f"the {n_sequences} training effects do not affinely span R^{p} (rank "
            f"{np.linalg.matrix_rank(phi - phi.mean(axis=0))} < {p} after centring), so W is not identifiable; "
            f"give at least {p + 1} sequences whose effects do not all lie on one hyperplane (e.g. not collinear)"
        )
    return phi


def _equal_parts(lengths: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Hard posteriors (S, T, K) cutting each sequence into K equal parts, and their transition counts."""
    s, t_max = lengths.size, int(lengths.max())
    t = np.arange(t_max)
    state = np.minimum((t[None, :] * k) // lengths[:, None], k - 1)
    valid = t[None, :] < lengths[:, None]
    gamma = np.zeros((s, t_max, k))
    gamma[valid, state[valid]] = 1.0
    xi = np.zeros((k, k))
    pair = valid[:, 1:]
    np.add.at(xi, (state[:, :-1][pair], state[:, 1:][pair]), 1.0)
    return gamma, xi


# -------------------------------------------------------------------------------- recognition
def recognize(X, models: Mapping[int, ParametricHMM], n_restarts: int = 5) -> Recognition:
    """Classify one movement ``X`` (T, D): estimate phi under each class's model, pick the most likely class.

    ``models`` maps class ids (the discovery's ``primitive_id``) to fitted models.

    A chain that cannot reach its last state in ``X``'s frames (:attr:`ParametricHMM.min_frames`) cannot
    explain it and scores ``-inf``.
    """
    if not models:
        raise InvalidInputError("models must map at least one class id to a fitted ParametricHMM")
    X, _ = validate_sequences(X)
    scores: dict[int, float] = {}
    phis: dict[int, np.ndarray] = {}
    for label, model in models.items():
        check_is_fitted(model)
        if X.shape[0] < model.min_frames:
            scores[label], phis[label] = -np.inf, np.full(model.phi_dim_, np.nan)
            continue
        phis[label], scores[label] = model._estimate(X, n_restarts=n_restarts)
    best = max(scores, key=scores.__getitem__)
    if not np.isfinite(scores[best]):
        raise InvalidInputError(f"no model can explain a {X.shape[0]}-frame sequence (every log-likelihood is -inf)")
    return Recognition(label=best, phi=phis[best], log_likelihoods=scores, phis=phis)
