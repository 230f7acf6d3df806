"""The synthesis baselines (ProMP, DMP, GMR): known answers on movement families linear in the effect,
cross-checks against movement_primitives' own ProMP, the estimator contract, and the shared selection rule."""

from __future__ import annotations

import sys

import numpy as np
import pytest

pytest.importorskip("movement_primitives.dmp")
pytest.importorskip("gmr")

from hoap_actions.errors import InvalidInputError, NotFittedError
from hoap_actions.primitives.baselines.mixture_regression import GMRSynthesis
from hoap_actions.primitives.baselines.movement_primitives import DMPSynthesis, ProMPSynthesis
from hoap_actions.primitives.baselines.synthesis_base import HAND_XY
from hoap_actions.primitives.hmm.selection import select_mean_model
from hoap_actions.primitives.trajectory_metrics import warped_rms_error

D = 18
GRID = np.array([[x, y] for x in (-0.15, 0.0, 0.15) for y in (-0.4, 0.0, 0.4)])
NEW = np.array([0.07, -0.23])  # a target between the grid's locations


def basis_family(n_weights: int, seed: int = 0):
    """Movements that are exactly ``basis @ (W0 + W1 . phi)`` on the ProMP's own basis: a weight matrix
    affine in the effect."""
    rng = np.random.default_rng(seed)
    W0 = rng.normal(0.0, 0.1, (n_weights, D))
    W1 = rng.normal(0.0, 0.3, (2, n_weights, D))
    model = ProMPSynthesis(n_weights_per_dim=n_weights)

    def movement(phi: np.ndarray, n_frames: int) -> np.ndarray:
        return model.basis(n_frames) @ (W0 + np.tensordot(phi, W1, axes=1))

    return movement


def batch(movement, lengths=(24, 30, 27, 30)):
    """Every grid location, one movement per length in ``lengths``: (X, lengths, phi)."""
    movements, phis = [], []
    for phi in GRID:
        for n in lengths:
            movements.append(movement(phi, n))
            phis.append(phi)
    return np.concatenate(movements), [len(m) for m in movements], np.array(phis)


def smooth_family(phi: np.ndarray, n_frames: int) -> np.ndarray:
    """(n, 18) smooth reaches from a common start to ends affine in phi (hand x, y end at phi + offsets)."""
    s = np.linspace(0.0, 1.0, n_frames)[:, None]
    shape = 3 * s**2 - 2 * s**3
    start = np.linspace(-0.5, 0.3, D)
    end = start + 0.05 * np.arange(D) / D
    end[list(HAND_XY)] = np.tile(phi, 4) + np.repeat([0.0, 0.1, 0.03, -0.04], 2)
    return start + shape * (end - start) + 0.02 * np.sin(np.pi * s) * phi[0]


def test_promp_weights_equal_the_librarys():
    from movement_primitives.promp import ProMP

    rng = np.random.default_rng(1)
    Y = np.cumsum(rng.normal(size=(40, D)), axis=0) * 0.01
    ours = ProMPSynthesis(n_weights_per_dim=7, ridge=1e-6).movement_weights(Y)
    theirs = ProMP(n_dims=D, n_weights_per_dim=7).weights(np.linspace(0.0, 1.0, 40), Y, lmbda=1e-6)
    np.testing.assert_allclose(ours, theirs, atol=1e-9)


def test_promp_on_a_family_linear_in_phi_is_exact_at_training_and_new_effects():
    movement = basis_family(8)
    X, lengths, phi = batch(movement)
    model = ProMPSynthesis(n_weights_per_dim=8, prior=0.0).fit(X, lengths, phi)
    assert model.n_frames_ == round(np.mean(lengths))
    for target in (GRID[4], GRID[0], NEW):
        np.testing.assert_allclose(model.synthesize(target), movement(target, model.n_frames_), atol=1e-5)


def test_promp_conditioning_is_the_gaussian_conditional_of_the_hand_end_alone():
    """The library's conditioning with the free coordinates' variance FREE_VARIANCE equals conditioning on
    the via columns only, written out (eq. 5 of Paraschos et al. on the selected rows)."""
    X, lengths, phi = batch(smooth_family)
    model = ProMPSynthesis(n_weights_per_dim=6, prior=1e-2).fit(X, lengths, phi)
    nw, cols = 6, list(HAND_XY)
    end_basis = model.basis(2)[-1]
    A = np.zeros((len(cols), D * nw))
    for row, c in enumerate(cols):
        A[row, c * nw:(c + 1) * nw] = end_basis
    mu, S = model.weight_mean_, model.weight_cov_
    R = np.diag(np.maximum(model.end_point_.variance_, 1e-12))
    w = mu + S @ A.T @ np.linalg.solve(A @ S @ A.T + R, model.end_point_(NEW) - A @ mu)
    expected = model.basis(model.n_frames_) @ w.reshape(D, nw).T
    np.testing.assert_allclose(model.synthesize(NEW), expected, atol=1e-6)


def test_promp_ends_the_hand_on_the_target():
    X, lengths, phi = batch(smooth_family)
    model = ProMPSynthesis(n_weights_per_dim=10).fit(X, lengths, phi)
    np.testing.assert_allclose(model.end_point_(NEW), smooth_family(NEW, 5)[-1, list(HAND_XY)], atol=1e-9)
    np.testing.assert_allclose(model.synthesize(NEW)[-1, list(HAND_XY)], model.end_point_(NEW), atol=2e-3)


def test_dmp_reaches_its_goal_and_reproduces_a_training_location():
    X, lengths, phi = batch(smooth_family)
    model = DMPSynthesis(n_weights_per_dim=20, n_neighbours=1).fit(X, lengths, phi)
    path = model.synthesize(NEW)
    np.testing.assert_allclose(path[-1, list(HAND_XY)], model.end_point_(NEW), atol=2e-3)
    np.testing.assert_allclose(path[0], smooth_family(NEW, 5)[0], atol=1e-9)  # every movement starts at rest
    at_training = model.synthesize(GRID[2])
    assert warped_rms_error(at_training, smooth_family(GRID[2], model.n_frames_)) < 2e-3


def test_dmp_neighbours_weigh_by_inverse_distance_in_the_unit_box():
    X, lengths, phi = batch(smooth_family)
    model = DMPSynthesis(n_neighbours=2).fit(X, lengths, phi)
    assert model.locations_.shape == (9, 2)
    share = model.neighbour_weights(np.array([-0.15, -0.4 + 0.8 / 6]))  # a sixth of the y span from a corner
    nearest = np.flatnonzero(share)
    np.testing.assert_allclose(model.locations_[nearest], [[-0.15, -0.4], [-0.15, 0.0]], atol=1e-12)
    np.testing.assert_allclose(share[nearest], [2 / 3, 1 / 3])
    np.testing.assert_array_equal(model.neighbour_weights(GRID[5]), np.eye(9)[5])


def test_dmp_affine_goals_follow_the_effect_for_every_coordinate():
    X, lengths, phi = batch(smooth_family)
    model = DMPSynthesis(n_neighbours=1, other_goals="affine").fit(X, lengths, phi)
    assert len(model.end_point_.columns) == D
    np.testing.assert_allclose(model.synthesize(NEW)[-1], smooth_family(NEW, 5)[-1], atol=3e-3)


def test_gmr_recovers_movements_affine_in_phi_and_time():
    rng = np.random.default_rng(2)
    a, B, c = rng.normal(size=D), rng.normal(size=(2, D)), rng.normal(size=D)

    def affine(phi, n):
        return a + phi @ B + np.linspace(0.0, 1.0, n)[:, None] * c

    X, lengths, phi = batch(affine)
    model = GMRSynthesis(n_components=3, reg_covar=1e-9, frame_step=1).fit(X, lengths, phi)
    np.testing.assert_allclose(model.synthesize(NEW), affine(NEW, model.n_frames_), atol=1e-4)


def test_gmr_follows_a_smooth_family_better_with_more_components():
    """Piecewise affine in time: a curved path (about 0.5 m long) is met within 1 cm by 6 components."""
    X, lengths, phi = batch(smooth_family)
    errors = [warped_rms_error(GMRSynthesis(n_components=k).fit(X, lengths, phi).synthesize(NEW),
                               smooth_family(NEW, 28)) for k in (2, 6)]
    assert errors[1] < min(errors[0], 1e-2)


@pytest.mark.parametrize("cls", [ProMPSynthesis, DMPSynthesis, GMRSynthesis])
def test_contract(cls):
    X, lengths, phi = batch(smooth_family, lengths=(12, 14))
    model = cls()
    with pytest.raises(NotFittedError):
        model.synthesize(NEW)
    assert repr(model).startswith(cls.__name__) and type(model)(**model.get_params()).get_params() == model.get_params()
    with pytest.raises(InvalidInputError, match="phi"):
        model.fit(X, lengths)
    with pytest.raises(InvalidInputError, match="lengths"):
        model.fit(X, [5, 5], phi[:2])
    with pytest.raises(InvalidInputError, match="phi must have shape"):
        model.fit(X, lengths, phi[:, :1].ravel())
    with pytest.raises(InvalidInputError, match="frames"):
        model.fit(X[:2 * len(lengths)], [2] * len(lengths), phi)
    assert model.fit(X, lengths, phi) is model
    assert model.synthesize(NEW).shape == (model.n_frames_, D)
    for bad in (NEW[:1], np.array([np.nan, 0.0]), NEW[None]):
        with pytest.raises(InvalidInputError, match="phi"):
            model.synthesize(bad)


@pytest.mark.parametrize("cls, params", [
    (ProMPSynthesis, {"n_weights_per_dim": 1}), (ProMPSynthesis, {"prior": -1.0}),
    (ProMPSynthesis, {"via_columns": (6, 6)}), (DMPSynthesis, {"n_neighbours": 0}),
    (DMPSynthesis, {"other_goals": "nearest"}), (DMPSynthesis, {"via_columns": (40,)}),
    (GMRSynthesis, {"n_components": 0}), (GMRSynthesis, {"reg_covar": 0.0}), (GMRSynthesis, {"frame_step": 1.5}),
])
def test_bad_hyper_parameters_are_refused_at_fit(cls, params):
    X, lengths, phi = batch(smooth_family, lengths=(12,))
    with pytest.raises(InvalidInputError, match=next(iter(params))):
        cls(**params).fit(X, lengths, phi)


def test_gmr_refuses_more_components_than_frames():
    X, lengths, phi = batch(smooth_family, lengths=(5,))
    with pytest.raises(InvalidInputError, match="at least 30 frames"):
        GMRSynthesis(n_components=30, frame_step=4).fit(X, lengths, phi)


@pytest.mark.parametrize("module, cls", [("gmr", GMRSynthesis), ("movement_primitives.promp", ProMPSynthesis)])
def test_a_missing_package_says_how_to_install_it(monkeypatch, module, cls):
    monkeypatch.setitem(sys.modules, module, None)
    X, lengths, phi = batch(smooth_family, lengths=(12,))
    with pytest.raises(InvalidInputError, match=r'pip install "hoap-actions\[bench\]"'):
        cls().fit(X, lengths, phi)


def test_the_resynthesis_rule_chooses_the_basis_the_family_was_made_with():
    movement = basis_family(8, seed=3)
    X, lengths, phi = batch(movement, lengths=(27, 27))  # the synthesis's length: DTW adds no resampling error
    choice = select_mean_model(X, lengths, phi, [{"n_weights_per_dim": 3}, {"n_weights_per_dim": 8}], n_folds=9,
                               estimator=ProMPSynthesis, prior=0.0)
    assert choice.best == {"n_weights_per_dim": 8}
    assert choice.errors[1] < 1e-4 < choice.errors[0]
