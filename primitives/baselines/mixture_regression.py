"""Gaussian mixture regression (GMR) synthesis for a new effect, from the ``gmr`` package: the third
robot-learning baseline of the paper's Fig. 8.

A Gaussian mixture over ``(phi, s, x)`` (the effect, the movement's normalised time s in [0, 1], the
marker coordinates; every frame of every training movement, each column standardised) is fitted by the
library's EM; a movement for a new effect is the library's conditional mean of x given ``(phi, s)``
along s (Calinon's GMR, with the effect as an extra input). The components start as time slices (the
frames of all training movements in order of normalised time, cut into K parts of equal count), so
that each one spans every training effect and the regression inside it is an affine function of phi;
EM may then let them specialise. EM runs one library iteration at a time with ``reg_covar`` added to
every covariance after each M-step (scikit-learn's floor; ``gmr`` has none): the marker coordinates of
a rigid hand are nearly collinear and every movement starts from the same rest pose, so a plain
maximum-likelihood covariance would be singular. A task-parameterised GMM (``pbdlib``) is not used: it needs the target
expressed as frames (a position and orientation), and the effect here is a point on the table.

Benchmark-only: no file format, hence no ``save``/``load``. ``gmr`` is an optional dependency
(``pip install "hoap-actions[bench]"``), imported when a model is fitted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.baselines.synthesis_base import (
    SynthesisBaseline,
    check_positive_int,
    check_positive_real,
    import_optional,
)

__all__ = ["GMRSynthesis"]


class GMRSynthesis(SynthesisBaseline):
    """GMM over (effect, time, markers), conditioned on the effect and time (module docstring).

    Parameters
    ----------
    n_components:
        Gaussians in the mixture (each starts as one slice of normalised time).
    reg_covar:
        Added to the diagonal of every covariance, in units of the standardised columns.
    n_iter, tol:
        EM iterations at most; EM stops when no component mean moves more than ``tol`` (standardised
        units) in an iteration.
    frame_step:
        Every ``frame_step``-th frame of each movement enters the fit (neighbouring frames at 30 Hz say
        nearly the same; the first and last always enter).

    Attributes (after ``fit``)
    --------------------------
    gmm_:
        The fitted ``gmr.GMM`` on standardised columns ``(phi, s, x)``.
    column_mean_, column_scale_:
        ``(p + 1 + D,)``: the standardisation.
    """

    _learned = SynthesisBaseline._learned + ("gmm_", "column_mean_", "column_scale_")

    def __init__(self, n_components: int = 10, reg_covar: float = 1e-3, n_iter: int = 100, tol: float = 1e-3,
                 frame_step: int = 2) -> None:
        self.n_components = n_components
        self.reg_covar = reg_covar
        self.n_iter = n_iter
        self.tol = tol
        self.frame_step = frame_step

    def _check_params(self) -> None:
        check_positive_int("n_components", self.n_components)
        check_positive_real("reg_covar", self.reg_covar)
        check_positive_int("n_iter", self.n_iter)
        check_positive_real("tol", self.tol)
        check_positive_int("frame_step", self.frame_step)

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None, phi: np.ndarray | None = None
            ) -> GMRSynthesis:
        """Fit the mixture to the frames of movements ``X`` ``(N, D)`` (``lengths`` frames each) with
        their effects ``phi`` ``(S, p)`` and normalised times."""
        GMM = import_optional("gmr", "GMR").GMM
        movements, phi = self._check_training(X, lengths, phi)
        rows = []
        for movement, effect in zip(movements, phi, strict=True):
            keep = np.unique(np.r_[np.arange(0, len(movement), int(self.frame_step)), len(movement) - 1])
            s = keep / (len(movement) - 1)
            rows.append(np.hstack([np.tile(effect, (keep.size, 1)), s[:, None], movement[keep]]))
        data = np.vstack(rows)
        self.column_mean_ = data.mean(axis=0)
        self.column_scale_ = np.maximum(data.std(axis=0), 1e-12)
        z = (data - self.column_mean_) / self.column_scale_
        k = int(self.n_components)
        if len(z) < k:
            raise InvalidInputError(f"{k} components need at least {k} frames; got {len(z)} (fewer components or a "
                                    "smaller frame_step)")
        slices = np.empty(len(z), dtype=np.intp)  # equal counts of frames in order of normalised time
        slices[np.argsort(data[:, self.phi_dim_], kind="stable")] = np.arange(len(z)) * k // len(z)
        means = np.stack([z[slices == j].mean(axis=0) for j in range(k)])
        floor = self.reg_covar * np.eye(z.shape[1])
        covariances = np.stack([np.cov(z[slices == j], rowvar=False, bias=True) + floor for j in range(k)])
        self.gmm_ = GMM(n_components=k, priors=np.bincount(slices, minlength=k) / len(z), means=means,
                        covariances=covariances, random_state=0)
        for _ in range(int(self.n_iter)):  # the library's EM one step at a time, each M-step's covariances floored
            previous = self.gmm_.means.copy()
            self.gmm_.from_samples(z, n_iter=1)
            self.gmm_.covariances += floor
            if np.max(np.abs(self.gmm_.means - previous)) < self.tol:
                break
        return self

    def synthesize(self, phi) -> np.ndarray:
        """``(n_frames_, D)``: the conditional mean of the markers given ``phi`` along normalised time."""
        phi = self._check_phi(phi)
        p = self.phi_dim_
        s = np.linspace(0.0, 1.0, self.n_frames_)[:, None]
        inputs = (np.hstack([np.tile(phi, (len(s), 1)), s]) - self.column_mean_[:p + 1]) / self.column_scale_[:p + 1]
        z = self.gmm_.predict(np.arange(p + 1), inputs)
        return z * self.column_scale_[p + 1:] + self.column_mean_[p + 1:]
