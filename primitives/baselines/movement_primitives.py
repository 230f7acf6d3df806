"""ProMP and DMP synthesis for a new effect, from the ``movement_primitives`` package, as a robot-learning
reader would set them up for the paper's Fig. 8 (reaches to a target never demonstrated).

* :class:`ProMPSynthesis`: a probabilistic movement primitive (Paraschos et al. 2013) over all 18 marker
  coordinates: a Gaussian over the basis weights of the training movements (each fitted by ridge
  regression on the library's normalised radial basis, time scaled to [0, 1]), conditioned by the
  library's via-point rule (eq. 5-6, ``ProMP.condition_position``) on the hand's final (x, y) at the
  effect (:class:`~hoap_actions.primitives.baselines.synthesis_base.EndPointMap`, observation variance
  its residual on the training movements). The other coordinates get an uninformative variance, so they
  follow through the weights' covariance with the hand: the prior's correlation is what generalises.
* :class:`DMPSynthesis`: a dynamical movement primitive (Ijspeert et al. 2013) whose shape (forcing-term
  weights) and start are those of the training locations nearest the effect (inverse-distance weighted,
  distances in the unit box of the training effects, so that a grid's rows and columns count alike),
  its goal the hand's end point at the effect for the conditioned coordinates and, for the others,
  the neighbours' end or an affine function of the effect; integrated open loop by the library.

Both are benchmark-only: no file format, hence no ``save``/``load``. ``movement_primitives`` is an
optional dependency (``pip install "hoap-actions[bench]"``), imported when a model is fitted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.baselines.synthesis_base import (
    HAND_XY,
    EndPointMap,
    SynthesisBaseline,
    check_positive_int,
    check_positive_real,
    import_optional,
)
from hoap_actions.primitives.hmm.effect_features import effect_groups, unit_range

__all__ = ["DMPSynthesis", "ProMPSynthesis"]

GOAL_RULES = ("neighbours", "affine")
FREE_VARIANCE = 1e6  # m^2: the observation variance of a coordinate the via point leaves free (no information)


class ProMPSynthesis(SynthesisBaseline):
    """ProMP over the marker coordinates, conditioned on the hand's end point at the effect (module docstring).

    Parameters
    ----------
    n_weights_per_dim:
        Radial basis functions per coordinate (the library's, centres evenly over normalised time).
    prior:
        Added to the diagonal of the weights' sample covariance, as a fraction of its mean variance: with
        few training movements the covariance has low rank; the prior lets the via point also bend the
        path where no demonstration varied.
    ridge:
        Ridge penalty of each movement's weight regression.
    via_columns:
        Coordinates whose final value the effect sets (default: the hand markers' x and y).

    Attributes (after ``fit``)
    --------------------------
    weight_mean_, weight_cov_:
        ``(D * n_weights_per_dim,)`` and its square: the weight distribution (coordinate-major, the
        library's order).
    end_point_:
        :class:`~hoap_actions.primitives.baselines.synthesis_base.EndPointMap` of ``via_columns``.
    """

    _learned = SynthesisBaseline._learned + ("weight_mean_", "weight_cov_", "end_point_")

    def __init__(self, n_weights_per_dim: int = 10, prior: float = 1e-3, ridge: float = 1e-8,
                 via_columns: Sequence[int] = HAND_XY) -> None:
        self.n_weights_per_dim = n_weights_per_dim
        self.prior = prior
        self.ridge = ridge
        self.via_columns = via_columns

    def _check_params(self) -> None:
        check_positive_int("n_weights_per_dim", self.n_weights_per_dim, low=2)
        check_positive_real("prior", self.prior, allow_zero=True)
        check_positive_real("ridge", self.ridge, allow_zero=True)
        self._check_via_columns(self.via_columns)

    def basis(self, n_frames: int) -> np.ndarray:
        """``(n_frames, n_weights_per_dim)``: the library's normalised basis of one coordinate over
        ``n_frames`` evenly spaced times in [0, 1] (column k: the path of weight vector e_k)."""
        ProMP = import_optional("movement_primitives.promp", "ProMP").ProMP
        one = ProMP(n_dims=1, n_weights_per_dim=int(self.n_weights_per_dim))
        return np.column_stack([one.trajectory_from_weights(np.linspace(0.0, 1.0, n_frames), e)[:, 0]
                                for e in np.eye(int(self.n_weights_per_dim))])

    def movement_weights(self, movement: np.ndarray) -> np.ndarray:
        """``(D * n_weights_per_dim,)``: the ridge fit of one movement ``(T, D)`` on :meth:`basis`, all
        coordinates in one solve (equal to the library's ``ProMP.weights``, which builds the block diagonal)."""
        B = self.basis(len(movement))
        W = np.linalg.solve(B.T @ B + self.ridge * np.eye(B.shape[1]), B.T @ movement)
        return W.T.ravel()

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None, phi: np.ndarray | None = None
            ) -> ProMPSynthesis:
        """Fit the weight distribution to movements ``X`` ``(N, D)`` of ``lengths`` frames and the end
        point map to their last frames and effects ``phi`` ``(S, p)``."""
        import_optional("movement_primitives.promp", "ProMP")
        movements, phi = self._check_training(X, lengths, phi)
        weights = np.stack([self.movement_weights(m) for m in movements])
        self.weight_mean_ = weights.mean(axis=0)
        cov = np.cov(weights, rowvar=False, bias=True)
        scale = float(np.mean(np.diag(cov))) or 1.0
        self.weight_cov_ = cov + self.prior * scale * np.eye(cov.shape[0])
        self.end_point_ = EndPointMap(self.via_columns).fit(np.stack([m[-1] for m in movements]), phi)
        return self

    def synthesize(self, phi) -> np.ndarray:
        """``(n_frames_, D)``: the mean of the ProMP conditioned on the hand's end point at ``phi``."""
        phi = self._check_phi(phi)
        ProMP = import_optional("movement_primitives.promp", "ProMP").ProMP
        promp = ProMP(n_dims=self.n_features_in_, n_weights_per_dim=int(self.n_weights_per_dim))
        promp.from_weight_distribution(self.weight_mean_, self.weight_cov_)
        end = promp.mean_trajectory(np.linspace(0.0, 1.0, 2))[-1]
        variance = np.full(self.n_features_in_, FREE_VARIANCE)
        end[self.end_point_.columns] = self.end_point_(phi)
        variance[self.end_point_.columns] = np.maximum(self.end_point_.variance_, 1e-12)
        conditioned = promp.condition_position(end, np.diag(variance), t=1.0, t_max=1.0)
        return conditioned.mean_trajectory(np.linspace(0.0, 1.0, self.n_frames_))


class DMPSynthesis(SynthesisBaseline):
    """DMP with the nearest training locations' shape and the effect's goal (module docstring).

    Parameters
    ----------
    n_weights_per_dim:
        Forcing-term basis functions per coordinate.
    n_neighbours:
        Training locations (distinct effects) whose movements give the shape and start, weighted by
        inverse distance in phi (a location at the effect itself takes all the weight).
    other_goals:
        The goal of the coordinates outside ``via_columns``: ``"neighbours"`` (the weighted end of the
        neighbours' movements) or ``"affine"`` (an affine function of the effect fitted to every training
        movement's last frame).
    regularization:
        Ridge penalty of the library's forcing-term regression.
    via_columns:
        Coordinates whose goal is the hand's end point at the effect (default: the hand markers' x and y).

    Attributes (after ``fit``)
    --------------------------
    locations_:
        ``(L, p)``: the distinct training effects (mean of each group of repetitions).
    location_weights_, location_starts_, location_goals_:
        ``(L, D * n_weights_per_dim)``, ``(L, D)``, ``(L, D)``: each location's mean forcing-term weights,
        first frame and last frame.
    end_point_:
        :class:`~hoap_actions.primitives.baselines.synthesis_base.EndPointMap` of ``via_columns``
        (``other_goals="affine"``: of every coordinate, ``via_columns`` first).
    """

    _learned = SynthesisBaseline._learned + ("locations_", "location_weights_", "location_starts_",
                                             "location_goals_", "end_point_")

    def __init__(self, n_weights_per_dim: int = 20, n_neighbours: int = 2, other_goals: str = "neighbours",
                 regularization: float = 1e-6, via_columns: Sequence[int] = HAND_XY) -> None:
        self.n_weights_per_dim = n_weights_per_dim
        self.n_neighbours = n_neighbours
        self.other_goals = other_goals
        self.regularization = regularization
        self.via_columns = via_columns

    def _check_params(self) -> None:
        check_positive_int("n_weights_per_dim", self.n_weights_per_dim, low=2)
        check_positive_int("n_neighbours", self.n_neighbours)
        if self.other_goals not in GOAL_RULES:
            raise InvalidInputError(f"other_goals must be one of {GOAL_RULES}; got {self.other_goals!r}")
        check_positive_real("regularization", self.regularization, allow_zero=True)
        self._check_via_columns(self.via_columns)

    def _dmp(self, n_frames: int):
        DMP = import_optional("movement_primitives.dmp", "DMP").DMP
        return DMP(n_dims=self.n_features_in_, execution_time=1.0, dt=1.0 / (n_frames - 1),
                   n_weights_per_dim=int(self.n_weights_per_dim))

    def fit(self, X: np.ndarray, lengths: Sequence[int] | None = None, phi: np.ndarray | None = None
            ) -> DMPSynthesis:
        """Imitate each movement of ``X`` ``(N, D)`` (``lengths`` frames each, time scaled to [0, 1]),
        average per training location of ``phi`` ``(S, p)``, and fit the end point map."""
        import_optional("movement_primitives.dmp", "DMP")
        movements, phi = self._check_training(X, lengths, phi)
        weights, starts, goals = [], [], []
        for movement in movements:
            dmp = self._dmp(len(movement))
            dmp.imitate(np.linspace(0.0, 1.0, len(movement)), movement, regularization_coefficient=self.regularization)
            weights.append(dmp.get_weights().copy())
            starts.append(dmp.start_y.copy())
            goals.append(dmp.goal_y.copy())
        groups = effect_groups(phi)
        members = [np.flatnonzero(groups == g) for g in range(int(groups.max()) + 1)]
        self.locations_ = np.stack([phi[m].mean(axis=0) for m in members])
        self.location_weights_ = np.stack([np.mean([weights[i] for i in m], axis=0) for m in members])
        self.location_starts_ = np.stack([np.mean([starts[i] for i in m], axis=0) for m in members])
        self.location_goals_ = np.stack([np.mean([goals[i] for i in m], axis=0) for m in members])
        columns = list(self.via_columns)
        if self.other_goals == "affine":
            columns += [c for c in range(self.n_features_in_) if c not in columns]
        self.end_point_ = EndPointMap(columns).fit(np.stack([m[-1] for m in movements]), phi)
        return self

    def neighbour_weights(self, phi: np.ndarray) -> np.ndarray:
        """``(L,)``: how much each training location contributes at ``phi`` (inverse distance in the unit
        box of the training effects over the ``n_neighbours`` nearest, summing to 1; all on a location
        within 1e-9 of phi; of equidistant locations, those first in the training data)."""
        _, span = unit_range(self.train_phi_)
        distance = np.linalg.norm((self.locations_ - phi) / span, axis=1)
        nearest = np.argsort(distance, kind="stable")[:int(self.n_neighbours)]
        out = np.zeros(len(distance))
        if distance[nearest[0]] < 1e-9:
            out[nearest[0]] = 1.0
        else:
            out[nearest] = 1.0 / distance[nearest]
        return out / out.sum()

    def synthesize(self, phi) -> np.ndarray:
        """``(n_frames_, D)``: the DMP with the neighbours' shape and start, run open loop to the goal at ``phi``."""
        phi = self._check_phi(phi)
        share = self.neighbour_weights(phi)
        goal = share @ self.location_goals_
        goal[self.end_point_.columns] = self.end_point_(phi)
        dmp = self._dmp(self.n_frames_)
        dmp.set_weights(share @ self.location_weights_)
        dmp.configure(start_y=share @ self.location_starts_, goal_y=goal)
        times, path = dmp.open_loop()
        frames = np.linspace(0.0, 1.0, self.n_frames_)
        return np.column_stack([np.interp(frames, times, path[:, d]) for d in range(path.shape[1])])
