"""ParametricHMM with a bending mean (``mean_model="tps"``): features, the penalised M-step, EM, effect
estimation, model selection by resynthesis, files and bad input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from em_checks import assert_objective_rises

from hoap_actions.errors import DataFileError, ExtrapolationWarning, IdentifiabilityError, InvalidInputError
from hoap_actions.primitives.hmm.effect_features import ThinPlateFeatures, effect_groups
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.selection import MeanModelSelection, select_mean_model

K, D = 4, 3
SD = 0.02
GRID = np.array([[u, v] for u in np.linspace(-1, 1, 4) for v in np.linspace(-1, 1, 4)])


def bent_means(phi: np.ndarray) -> np.ndarray:
    """(K, D) state means that bend with phi: affine plus a bump that no linear model follows."""
    u, v = phi
    base = np.arange(K)[:, None] * np.array([1.0, 0.5, -0.3])
    return base + np.outer(np.ones(K), [0.3 * u, 0.2 * v, 0.0]) + np.outer(np.linspace(0.5, 1.0, K),
                                                                         [np.cos(1.5 * u), u * v, np.sin(1.5 * v)])


def sequences(rng, effects, repetitions: int = 3, means=bent_means):
    """Left-right sequences, each state held 3-6 frames, at every effect ``repetitions`` times."""
    seqs, phis = [], []
    for phi in effects:
        for _ in range(repetitions):
            states = np.repeat(np.arange(K), rng.integers(3, 7, size=K))
            seqs.append(means(phi)[states] + SD * rng.normal(size=(states.size, D)))
            phis.append(phi)
    return np.concatenate(seqs), [len(s) for s in seqs], np.array(phis), seqs


@pytest.fixture(scope="module")
def data():
    return sequences(np.random.default_rng(0), GRID)


@pytest.fixture(scope="module")
def tps(data):
    X, lengths, phis, _ = data
    return ParametricHMM(n_states=K, mean_model="tps", smoothing=1e-3, random_state=0).fit(X, lengths, phis)


# ------------------------------------------------------------------------------------ features
def test_thin_plate_jacobian_matches_finite_differences():
    features = ThinPlateFeatures.from_effects(GRID * [0.4, 0.1] + [0.2, -0.3], max_centres=64)
    phi = np.array([[0.05, -0.31], [0.41, -0.22], [0.2, -0.3]])
    h = 1e-6
    numeric = np.stack([(features.transform(phi + h * e) - features.transform(phi - h * e)) / (2 * h)
                        for e in np.eye(2)], axis=2)
    np.testing.assert_allclose(features.jacobian(phi), numeric, rtol=1e-5, atol=1e-6)


def test_centres_are_the_distinct_effects_thinned_evenly():
    repeated = np.repeat(GRID, 3, axis=0) + 1e-5
    features = ThinPlateFeatures.from_effects(repeated, max_centres=64)
    assert features.n_features == 16
    np.testing.assert_allclose(features.transform(GRID)[np.arange(16), np.arange(16)], 0.0, atol=1e-9)
    few = ThinPlateFeatures.from_effects(GRID, max_centres=5)
    assert few.n_features == 5
    corners = {(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)}
    assert corners <= {tuple(np.round(c, 6)) for c in few.centres}  # farthest points first: the corners
    np.testing.assert_array_equal(effect_groups(np.array([[0.0, 0.0], [1.0, 1.0], [1e-5, 0.0], [1.0, 1.0 - 1e-5]])),
                                  [0, 1, 0, 1])


# ----------------------------------------------------------------------------------------- maths
@pytest.mark.parametrize("covariance_type", ["full", "diag"])
@pytest.mark.parametrize("prior", [None, 0.01])
def test_penalised_objective_rises_monotonically(data, covariance_type, prior):
    X, lengths, phis, _ = data
    m = ParametricHMM(n_states=K, covariance_type=covariance_type, mean_model="tps", smoothing=0.5, n_iter=25,
                      tol=1e-9, covars_prior=None if prior is None else np.full(D, prior), covars_weight=3.0)
    assert_objective_rises(m.fit(X, lengths, phis).log_likelihood_history_)


@pytest.mark.parametrize("covariance_type", ["full", "diag"])
def test_m_step_is_the_ridge_regression_on_affine_and_thin_plate_features(covariance_type):
    """One state: W, V and the mean are the ridge solution of frames on [phi, g(phi), 1] (penalty only on
    V), solved here independently as least squares with sqrt(lambda) rows; the covariance is the
    residual scatter plus lambda V V^T over the frames."""
    rng = np.random.default_rng(3)
    X, lengths, phis, _ = sequences(rng, GRID, repetitions=1)
    lam = 0.7
    m = ParametricHMM(n_states=1, covariance_type=covariance_type, mean_model="tps", smoothing=lam,
                      n_iter=1, reg_covar=0.0).fit(X, lengths, phis)
    g = m.effect_features_.transform(phis)
    design = np.repeat(np.hstack([phis, g, np.ones((len(phis), 1))]), lengths, axis=0)
    m_features = g.shape[1]
    penalty_rows = np.hstack([np.zeros((m_features, 2)), np.sqrt(lam) * np.eye(m_features), np.zeros((m_features, 1))])
    coef = np.linalg.lstsq(np.vstack([design, penalty_rows]), np.vstack([X, np.zeros((m_features, D))]),
                           rcond=None)[0]
    np.testing.assert_allclose(m.W_[0], coef[:2].T, atol=1e-7)
    np.testing.assert_allclose(m.V_[0], coef[2:2 + m_features].T, atol=1e-7)
    np.testing.assert_allclose(m.mean_bar_[0], coef[-1], atol=1e-7)
    resid = X - design @ coef
    scatter = resid.T @ resid + lam * coef[2:2 + m_features].T @ coef[2:2 + m_features]
    expected = scatter / len(X) if covariance_type == "full" else np.diag(scatter) / len(X)
    np.testing.assert_allclose(m.covars_[0], expected, rtol=1e-6, atol=1e-12)


def test_tps_follows_a_bending_mean_that_the_linear_model_cannot(data, tps):
    X, lengths, phis, _ = data
    linear = ParametricHMM(n_states=K, random_state=0).fit(X, lengths, phis)
    held_out = np.array([[-0.5, 0.1], [0.2, -0.7], [0.6, 0.55]])
    for model, bound in ((tps, 0.06), (linear, None)):
        errors = [np.abs(model._means_at(phi[None], np.zeros(D))[0] - bent_means(phi)).max() for phi in held_out]
        if bound is not None:
            assert max(errors) < bound
        else:
            assert max(errors) > 0.15


def test_estimate_phi_finds_a_known_effect_of_a_known_nonlinear_model(tps):
    """Sequences drawn from the fitted (known) bending model at effects it never saw: the estimate lands
    on them; the same model without its bend (V = 0) misses them."""
    rng = np.random.default_rng(7)
    truths = np.array([[-0.55, 0.35], [0.25, -0.65], [0.7, 0.1]])
    model_means = lambda phi: tps._means_at(phi[None], np.zeros(D))[0]  # noqa: E731  (a one-line local function)
    _, _, _, seqs = sequences(rng, truths, repetitions=1, means=model_means)
    straight = ParametricHMM.__new__(ParametricHMM)
    straight.__dict__.update(tps.__dict__, V_=np.zeros_like(tps.V_))
    for seq, truth in zip(seqs, truths):
        np.testing.assert_allclose(tps.estimate_phi(seq, n_restarts=5), truth, atol=0.03)
        assert np.abs(straight.estimate_phi(seq, n_restarts=5) - truth).max() > 0.05


def test_gauss_newton_steps_never_lower_the_expected_log_likelihood(tps, data):
    """Generalised EM: from any start, every effect update raises (or keeps) the marginal likelihood."""
    _, _, _, seqs = data
    seq = seqs[5]
    for start in ([-1.0, 1.0], [0.9, -0.9], [0.0, 0.0]):
        start = np.array(start)
        previous = tps.score(seq, start)
        tps_copy = ParametricHMM.__new__(ParametricHMM)
        tps_copy.__dict__.update(tps.__dict__, train_phi_=start[None])  # one restart: from this start
        for n_iter in (1, 2, 4, 8):
            phi = tps_copy.estimate_phi(seq, n_restarts=1, n_iter=n_iter)
            score = tps.score(seq, phi)
            assert score >= previous - 1e-8
            previous = score


def test_a_heavily_smoothed_bend_is_the_linear_model(data):
    """lambda -> infinity pins V to 0: the bending model's means become the linear model's."""
    X, lengths, phis, _ = data
    linear = ParametricHMM(n_states=K, random_state=0, n_iter=10, tol=0.0).fit(X, lengths, phis)
    stiff = ParametricHMM(n_states=K, random_state=0, n_iter=10, tol=0.0, mean_model="tps",
                          smoothing=1e9).fit(X, lengths, phis)
    assert linear.V_.shape == (K, D, 0) and linear.effect_features_.n_features == 0
    assert np.abs(stiff.V_).max() < 1e-6
    np.testing.assert_allclose(stiff.W_, linear.W_, atol=1e-5)
    np.testing.assert_allclose(stiff.mean_bar_, linear.mean_bar_, atol=1e-5)


# ----------------------------------------------------------------------------------- selection
def test_select_mean_model_prefers_the_bend_on_bending_data(data):
    X, lengths, phis, _ = data
    result = select_mean_model(X, lengths, phis, [{"mean_model": "linear"},
                                                  {"mean_model": "tps", "smoothing": 1e-3},
                                                  {"mean_model": "tps", "smoothing": 1e3}],
                               n_folds=4, random_state=0, n_states=K)
    assert isinstance(result, MeanModelSelection)
    assert result.best == {"mean_model": "tps", "smoothing": 1e-3}
    assert result.errors[1] < result.errors[0] and result.errors[1] < result.errors[2]
    assert len(result.errors) == 3 and all(e > 0 for e in result.errors)


def test_select_mean_model_keeps_repetitions_of_one_effect_in_one_fold(data):
    X, lengths, phis, _ = data
    result = select_mean_model(X, lengths, phis, [{"mean_model": "linear"}], n_folds=16, n_states=K)
    assert result.n_folds == 16  # 16 locations x 3 repetitions: each fold holds out one location


def test_select_mean_model_bad_input(data):
    X, lengths, phis, _ = data
    with pytest.raises(InvalidInputError, match="candidates"):
        select_mean_model(X, lengths, phis, [], n_states=K)
    with pytest.raises(InvalidInputError, match="n_folds"):
        select_mean_model(X, lengths, phis, [{"mean_model": "linear"}], n_folds=17, n_states=K)
    with pytest.raises(InvalidInputError, match="mean_model"):
        select_mean_model(X, lengths, phis, [{"mean_model": "cubic"}], n_states=K)


# ---------------------------------------------------------------------------------------- files
def test_save_load_round_trip_keeps_the_bend(tps, data, tmp_path):
    _, _, phis, seqs = data
    tps.save(tmp_path / "tps.npz")
    loaded = ParametricHMM.load(tmp_path / "tps.npz")
    assert repr(loaded) == repr(tps)
    np.testing.assert_array_equal(loaded.V_, tps.V_)
    np.testing.assert_array_equal(loaded.effect_features_.centres, tps.effect_features_.centres)
    np.testing.assert_allclose(loaded.synthesize(phis[3]), tps.synthesize(phis[3]), rtol=1e-14, atol=1e-15)
    assert loaded.score(seqs[0], phis[0]) == tps.score(seqs[0], phis[0])


def test_version_2_files_load_as_linear_models(data, tmp_path):
    X, lengths, phis, seqs = data
    linear = ParametricHMM(n_states=K, random_state=0).fit(X, lengths, phis)
    linear.save(tmp_path / "new.npz")
    with np.load(tmp_path / "new.npz", allow_pickle=False) as raw:
        old = {key: raw[key] for key in raw.files
               if key not in ("mean_model", "smoothing", "max_centres", "V_", "feature_centres_", "feature_low_",
                              "feature_span_")}
    old["format_version"] = np.array(2)
    old["train_params_"] = old.pop("train_phi_")  # its name in files before version 4
    np.savez(tmp_path / "v2.npz", **old)
    v2 = ParametricHMM.load(tmp_path / "v2.npz")
    assert v2.mean_model == "linear" and v2.V_.shape == (K, D, 0)
    assert v2.score(seqs[0], phis[0]) == linear.score(seqs[0], phis[0])


def test_load_rejects_contradicting_or_malformed_features(tps, tmp_path):
    tps.save(tmp_path / "tps.npz")
    with np.load(tmp_path / "tps.npz", allow_pickle=False) as raw:
        arrays = dict(raw)
    np.savez(tmp_path / "said_linear.npz", **{**arrays, "mean_model": np.array("linear")})
    with pytest.raises(DataFileError, match="V_ has 16 feature column"):
        ParametricHMM.load(tmp_path / "said_linear.npz")
    np.savez(tmp_path / "flat.npz", **{**arrays, "feature_span_": np.array([1.0, 0.0])})
    with pytest.raises(DataFileError, match="feature_span_"):
        ParametricHMM.load(tmp_path / "flat.npz")
    np.savez(tmp_path / "short.npz", **{**arrays, "feature_centres_": arrays["feature_centres_"][:3]})
    with pytest.raises(DataFileError, match="feature_centres_"):
        ParametricHMM.load(tmp_path / "short.npz")


# ------------------------------------------------------------------------------------ bad input
def test_bad_smoothing_and_mean_model(data):
    X, lengths, phis, _ = data
    for kwargs, match in (({"smoothing": -1.0}, "smoothing"), ({"smoothing": float("nan")}, "smoothing"),
                          ({"mean_model": "cubic"}, "mean_model"), ({"max_centres": 0}, "max_centres")):
        with pytest.raises(InvalidInputError, match=match):
            ParametricHMM(n_states=K, mean_model=kwargs.pop("mean_model", "tps"), **kwargs).fit(X, lengths, phis)


def test_unpenalised_bend_needs_enough_distinct_effects(data):
    X, lengths, phis, _ = data
    with pytest.raises(IdentifiabilityError, match="16 distinct values.*max_centres <= 13"):
        ParametricHMM(n_states=K, mean_model="tps", smoothing=0.0).fit(X, lengths, phis)
    fitted = ParametricHMM(n_states=K, mean_model="tps", smoothing=0.0, max_centres=13).fit(X, lengths, phis)
    assert fitted.effect_features_.n_features == 13


def test_synthesis_far_outside_the_training_range_warns_naming_it(tps):
    with pytest.warns(ExtrapolationWarning, match=r"trained on \[-1, 1\].*tps mean model"):
        tps.synthesize([3.5, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tps.synthesize([1.2, -1.2])  # a little beyond the grid's edge is routine
