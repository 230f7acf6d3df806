"""ParametricHMM: known answers from a generating linear PHMM, EM properties, inference, files and bad input."""

from __future__ import annotations

import numpy as np
import pytest
from em_checks import assert_objective_rises

from hoap_actions.errors import (
    DataExistsError,
    DataFileError,
    IdentifiabilityError,
    InvalidInputError,
    NotFittedError,
)
from hoap_actions.primitives.hmm import hmm_math as hm
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.phmm_effects import phi_update
from hoap_actions.primitives.hmm.phmm_recognition import Recognition, recognize
from hoap_actions.primitives.hmm.selection import NStatesSelection, select_n_states

K, D, P = 4, 3, 2
SD = 0.05


# ----------------------------------------------------------------------------------- generative model
def make_class(seed: int):
    """A known linear PHMM: means walk through space, each state moves with phi through its own W."""
    rng = np.random.default_rng(seed)
    mean_bar = np.cumsum(rng.normal(size=(K, D)), axis=0)
    w = rng.normal(scale=0.5, size=(K, D, P))
    return mean_bar, w


def generate(rng, mean_bar, w, phi, stay=0.8, durations=None):
    """One left-right sequence: each state held for 1 + Geometric(1 - stay) frames (or ``durations``)."""
    durations = 1 + rng.geometric(1 - stay, size=K) if durations is None else durations
    states = np.repeat(np.arange(K), durations)
    means = mean_bar + w @ phi
    return means[states] + SD * rng.normal(size=(states.size, D))


def dataset(seed: int, class_seed: int = 1, n: int = 24):
    """Sequences, lengths, effects, the generating (mean_bar, W), and each state's mean duration."""
    rng = np.random.default_rng(seed)
    mean_bar, w = make_class(class_seed)
    phis = rng.uniform(-1, 1, size=(n, P))
    durations = 1 + rng.geometric(0.2, size=(n, K))
    seqs = [generate(rng, mean_bar, w, f, durations=d) for f, d in zip(phis, durations)]
    return np.concatenate(seqs), durations.sum(axis=1), phis, (mean_bar, w, durations.mean(axis=0))


@pytest.fixture(scope="module")
def data():
    return dataset(0)


@pytest.fixture(scope="module")
def model(data):
    X, lengths, phis, _ = data
    return ParametricHMM(n_states=K, random_state=0).fit(X, lengths, phis)


# ----------------------------------------------------------------------------------- known answers
def test_recovers_generating_parameters(model, data):
    _, _, _, (mean_bar, w, duration) = data
    np.testing.assert_allclose(model.W_, w, atol=0.03)
    np.testing.assert_allclose(model.mean_bar_, mean_bar, atol=0.03)
    np.testing.assert_allclose(np.sqrt(np.diagonal(model.covars_, axis1=1, axis2=2)), SD, rtol=0.25)
    # A geometric duration of mean d has stay probability 1 - 1/d; the data's own mean durations.
    np.testing.assert_allclose(np.diag(model.transmat_)[:-1], 1 - 1 / duration[:-1], atol=0.01)
    assert model.transmat_[-1, -1] == 1.0 and np.all(np.triu(model.transmat_, 2) == 0)
    assert model.startprob_.tolist() == [1.0, 0.0, 0.0, 0.0]


def test_learned_attributes_and_hyper_parameters(model, data):
    X, lengths, phis, _ = data
    assert (model.n_states, model.topology, model.covariance_type) == (K, "left-right", "full")
    assert model.phi_dim_ == P and model.n_features_in_ == D
    assert model.W_.shape == (K, D, P) and model.mean_bar_.shape == (K, D) and model.covars_.shape == (K, D, D)
    assert model.monitor_.n_iter == len(model.log_likelihood_history_) and model.monitor_.converged
    np.testing.assert_array_equal(model.train_phi_, phis)
    assert "n_states=4" in repr(model)


def test_synthesize_reproduces_generating_means(model, data):
    X, lengths, phis, (mean_bar, w, _) = data
    phi = phis[3]
    means = mean_bar + w @ phi
    traj = model.synthesize(phi)
    stay = np.diag(model.transmat_)[:-1]
    anchors = np.concatenate([[0.0], np.cumsum(1 / (1 - stay))])
    assert traj.shape == (int(round(anchors[-1])) + 1, D)
    np.testing.assert_allclose(traj[0], means[0], atol=0.03)
    np.testing.assert_allclose(traj[-1], means[-1], atol=0.03)
    # Resampled at the anchor times the path passes through every state mean at phi.
    resampled = model.synthesize(phi, n_frames=301)
    times = np.linspace(0, anchors[-1], 301)
    for j in range(K):
        np.testing.assert_allclose(resampled[np.argmin(np.abs(times - anchors[j]))], means[j], atol=0.05)
    # Between two anchors the path is the straight segment between their means.
    mid = model.synthesize(phi, n_frames=3)
    np.testing.assert_allclose(mid[1], np.array([np.interp(anchors[-1] / 2, anchors, model.mean_bar_[:, i]
                                                           + model.W_[:, i] @ phi) for i in range(D)]))


@pytest.mark.parametrize("covariance_type", ["full", "diag"])
@pytest.mark.parametrize("topology", ["left-right", "left-right-skip", "ergodic"])
def test_log_likelihood_rises_monotonically(data, covariance_type, topology):
    X, lengths, phis, _ = data
    m = ParametricHMM(n_states=K, topology=topology, covariance_type=covariance_type, n_iter=25, tol=1e-9)
    assert_objective_rises(m.fit(X, lengths, phis).log_likelihood_history_)


@pytest.mark.parametrize("covariance_type", ["full", "diag"])
@pytest.mark.parametrize("topology", ["left-right", "ergodic"])
def test_objective_with_covariance_prior_rises_monotonically(data, covariance_type, topology):
    X, lengths, phis, _ = data
    m = ParametricHMM(n_states=K, topology=topology, covariance_type=covariance_type, n_iter=25, tol=1e-9,
                      covars_prior=np.full(D, 0.01), covars_weight=5.0)
    assert_objective_rises(m.fit(X, lengths, phis).log_likelihood_history_)


@pytest.mark.parametrize("covariance_type", ["full", "diag"])
def test_covariance_prior_gives_the_map_covariance(covariance_type):
    """One state: the M-step's covariance is (scatter + w prior) / (frames + w) + reg_covar, with the
    scatter about the same regression fit as without a prior (the mean does not depend on it)."""
    rng = np.random.default_rng(5)
    w = rng.normal(size=(D, P))
    phis = rng.uniform(-1, 1, size=(6, P))
    X = np.concatenate([phi @ w.T + SD * rng.normal(size=(4, D)) for phi in phis])
    lengths = np.full(6, 4)
    prior, weight = np.array([0.01, 0.02, 0.03]), 7.0
    plain = ParametricHMM(n_states=1, covariance_type=covariance_type, n_iter=1).fit(X, lengths, phis)
    shrunk = ParametricHMM(n_states=1, covariance_type=covariance_type, n_iter=1, covars_prior=prior,
                           covars_weight=weight).fit(X, lengths, phis)
    np.testing.assert_allclose(shrunk.W_, plain.W_, atol=1e-12)
    scatter = (plain.covars_[0] - plain.reg_covar * (np.eye(D) if covariance_type == "full" else 1.0)) * len(X)
    prior_matrix = np.diag(prior) if covariance_type == "full" else prior
    expected = (scatter + weight * prior_matrix) / (len(X) + weight)
    expected = expected + plain.reg_covar * (np.eye(D) if covariance_type == "full" else 1.0)
    np.testing.assert_allclose(shrunk.covars_[0], expected, rtol=1e-10)


def test_m_step_for_w_matches_weighted_least_squares(data):
    # With posteriors fixed, Z_j = [W_j mu_bar_j] is the weighted least-squares fit of frames on [phi; 1].
    X, lengths, phis, _ = data
    m = ParametricHMM(n_states=K, n_iter=2, tol=0.0).fit(X, lengths, phis)
    batch = make_batch(m, X, lengths, phis)
    _, gamma, xi = m._e_step(batch)
    old_w = m.W_.copy()
    m._m_step(batch, gamma, xi)
    gamma = hm.unpad_sequences(gamma, lengths)
    omega = np.repeat(np.hstack([phis, np.ones((len(phis), 1))]), lengths, axis=0)
    for j in range(K):
        sw = np.sqrt(gamma[:, j])[:, None]
        z, *_ = np.linalg.lstsq(omega * sw, X * sw, rcond=None)
        np.testing.assert_allclose(m.W_[j], z[:-1].T, atol=1e-8)
        np.testing.assert_allclose(m.mean_bar_[j], z[-1], atol=1e-8)
        resid = X - omega @ z
        np.testing.assert_allclose(m.covars_[j], (gamma[:, j, None] * resid).T @ resid / gamma[:, j].sum()
                                   + m.reg_covar * np.eye(D), atol=1e-10)
    assert not np.allclose(old_w, m.W_, atol=1e-12)


def make_batch(m, X, lengths, phis):
    from hoap_actions.primitives.hmm.phmm_batch import SequenceBatch as _Batch
    return _Batch.build(X, lengths, phis, X.mean(axis=0), m.covariance_type)


# -------------------------------------------------------------------------------------- inference
def test_estimate_phi_recovers_held_out_phi(model):
    rng = np.random.default_rng(7)
    mean_bar, w = make_class(1)
    for phi in ([0.35, -0.6], [-0.8, 0.15]):
        x = generate(rng, mean_bar, w, np.array(phi))
        np.testing.assert_allclose(model.estimate_phi(x), phi, atol=0.05)


def expected_complete_ll(m, x, gamma, phi):
    """Q(phi) = sum_t sum_j gamma_tj log N(x_t | mean_bar_j + W_j phi, S_j), posteriors held fixed."""
    return float(np.sum(gamma * hm.log_gaussian_density(x, m.mean_bar_ + m.W_ @ phi, m.covars_, m.covariance_type)))


@pytest.mark.parametrize("covariance_type", ["full", "diag"])
def test_phi_update_is_stationary_point_of_expected_complete_ll(data, covariance_type):
    X, lengths, phis, _ = data
    m = ParametricHMM(n_states=K, covariance_type=covariance_type, n_iter=5).fit(X, lengths, phis)
    x = np.split(X, np.cumsum(lengths)[:-1])[5]
    batch = make_batch(m, x, np.array([len(x)]), np.array([[0.9, 0.9]]))    # posteriors at a poor guess
    _, gamma, _ = m._e_step(batch)
    phi_star = phi_update(m, batch, gamma)[0]
    gamma = gamma[0]
    h = 1e-5
    grad = [(expected_complete_ll(m, x, gamma, phi_star + h * e) - expected_complete_ll(m, x, gamma, phi_star - h * e))
            / (2 * h) for e in np.eye(P)]
    scale = np.abs([(expected_complete_ll(m, x, gamma, np.array([0.9, 0.9]) + h * e)
                     - expected_complete_ll(m, x, gamma, np.array([0.9, 0.9]) - h * e)) / (2 * h) for e in np.eye(P)])
    assert np.max(np.abs(grad)) < 1e-6 * max(1.0, scale.max())
    q_star = expected_complete_ll(m, x, gamma, phi_star)
    for step in np.random.default_rng(0).normal(scale=0.05, size=(5, P)):
        assert expected_complete_ll(m, x, gamma, phi_star + step) < q_star


def test_score_and_predict(model, data):
    X, lengths, phis, _ = data
    x = np.split(X, np.cumsum(lengths)[:-1])[0]
    at_true = model.score(x, phis[0])
    assert at_true > model.score(x, phis[0] + 0.5)
    assert np.isfinite(at_true)
    states = model.predict(x, phis[0])
    assert states[0] == 0 and states[-1] == K - 1 and np.all(np.diff(states) >= 0)


def test_recognize_picks_the_generating_class():
    models, truth = {}, {}
    for label, class_seed in ((0, 1), (1, 2), (2, 3)):  # class ids, as the discovery numbers its classes
        X, lengths, phis, _ = dataset(10 + class_seed, class_seed=class_seed, n=12)
        models[label] = ParametricHMM(n_states=K, n_iter=20, random_state=0).fit(X, lengths, phis)
        truth[label] = make_class(class_seed)
    rng = np.random.default_rng(99)
    for label, (mean_bar, w) in truth.items():
        phi = rng.uniform(-0.8, 0.8, size=P)
        result = recognize(generate(rng, mean_bar, w, phi), models)
        assert isinstance(result, Recognition)
        assert result.label == label
        assert set(result.log_likelihoods) == set(models)
        assert result.log_likelihoods[label] == max(result.log_likelihoods.values())
        np.testing.assert_allclose(result.phi, phi, atol=0.1)


def test_select_n_states_prefers_true_count(data):
    X, lengths, phis, _ = data
    result = select_n_states(X, lengths, phis, [2, K, 8], n_folds=3, random_state=0, n_iter=15)
    assert isinstance(result, NStatesSelection)
    assert result.n_states == K and set(result.scores) == {2, K, 8}


def test_scalar_effect():
    rng = np.random.default_rng(3)
    mean_bar = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 1.0]])
    w = np.array([[[0.0], [0.0]], [[1.0], [0.5]], [[0.0], [2.0]]])
    phis = np.linspace(-1, 1, 8)[:, None]
    seqs = [np.repeat(mean_bar + w @ f, 6, axis=0) + SD * rng.normal(size=(18, 2)) for f in phis]
    m = ParametricHMM(n_states=3).fit(np.concatenate(seqs), [18] * 8, phis)
    np.testing.assert_allclose(m.W_, w, atol=0.05)
    assert m.synthesize(0.5).shape[1] == 2
    assert m.estimate_phi(seqs[2]) == pytest.approx(phis[2], abs=0.05)


# ----------------------------------------------------------------------------------------- files
def test_save_load_round_trip(model, data, tmp_path):
    X, lengths, phis, _ = data
    path = tmp_path / "approach.npz"
    model.save(path)
    loaded = ParametricHMM.load(path)
    for name in ("startprob_", "transmat_", "mean_bar_", "W_", "covars_", "train_phi_",
                 "log_likelihood_history_"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(model, name))
    assert repr(loaded) == repr(model)
    assert loaded.monitor_ == model.monitor_
    x = X[: lengths[0]]
    assert loaded.score(x, phis[0]) == model.score(x, phis[0])
    np.testing.assert_allclose(loaded.synthesize(phis[1]), model.synthesize(phis[1]), rtol=1e-14)
    with np.load(path, allow_pickle=False) as raw:
        assert int(raw["format_version"]) == 4 and str(raw["topology"]) == "left-right"
        assert "train_phi_" in raw.files and "train_params_" not in raw.files  # saved under its own name
        assert str(raw["mean_model"]) == "linear" and raw["V_"].shape == (K, D, 0)
        assert raw["covars_prior"].shape == (0,)


def test_save_load_keeps_the_covariance_prior_and_reads_version_1_files(data, tmp_path):
    X, lengths, phis, _ = data
    prior = np.full(D, 0.02)
    m = ParametricHMM(n_states=K, covariance_type="diag", covars_prior=prior, covars_weight=3.0,
                      random_state=0).fit(X, lengths, phis)
    m.save(tmp_path / "prior.npz")
    loaded = ParametricHMM.load(tmp_path / "prior.npz")
    np.testing.assert_array_equal(loaded.covars_prior, prior)
    assert loaded.covars_weight == 3.0
    np.testing.assert_array_equal(loaded.covars_, m.covars_)
    # a version-1 file (no prior entries) is a model without a prior
    with np.load(tmp_path / "prior.npz", allow_pickle=False) as raw:
        old = {key: raw[key] for key in raw.files if key not in ("covars_prior", "covars_weight")}
    old["format_version"] = np.array(1)
    old["train_params_"] = old.pop("train_phi_")  # its name in files before version 4
    np.savez(tmp_path / "v1.npz", **old)
    v1 = ParametricHMM.load(tmp_path / "v1.npz")
    assert v1.covars_prior is None and v1.covars_weight == 1.0
    np.testing.assert_array_equal(v1.covars_, m.covars_)


def test_save_refuses_to_overwrite(model, tmp_path):
    path = tmp_path / "m.npz"
    model.save(path)
    with pytest.raises(DataExistsError, match="overwrite=True"):
        model.save(path)
    model.save(path, overwrite=True)
    assert ParametricHMM.load(path).n_states == K


def test_load_rejects_bad_files(model, tmp_path):
    with pytest.raises(DataFileError, match="does not exist"):
        ParametricHMM.load(tmp_path / "missing.npz")
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"PK\x03\x04 definitely not a zip archive")
    with pytest.raises(DataFileError, match="not a readable"):
        ParametricHMM.load(corrupt)
    good = tmp_path / "good.npz"
    model.save(good)
    with np.load(good) as raw:
        arrays = dict(raw)
    np.savez(tmp_path / "future.npz", **{**arrays, "format_version": np.array(5)})
    with pytest.raises(DataFileError, match="format_version 5"):
        ParametricHMM.load(tmp_path / "future.npz")
    np.savez(tmp_path / "bad_prior.npz", **{**arrays, "covars_prior": np.ones(D + 1)})
    with pytest.raises(DataFileError, match="covars_prior"):
        ParametricHMM.load(tmp_path / "bad_prior.npz")
    np.savez(tmp_path / "truncated.npz", **{k: v for k, v in arrays.items() if k != "W_"})
    with pytest.raises(DataFileError, match="W_"):
        ParametricHMM.load(tmp_path / "truncated.npz")
    np.savez(tmp_path / "pickled.npz", **{**arrays, "W_": np.array([{"a": 1}], dtype=object)})
    with pytest.raises(DataFileError):
        ParametricHMM.load(tmp_path / "pickled.npz")
    np.save(tmp_path / "array.npy", np.zeros(3))
    with pytest.raises(DataFileError, match="not an .npz archive"):
        ParametricHMM.load(tmp_path / "array.npy")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(DataFileError, match="not a ParametricHMM file"):
        ParametricHMM.load(tmp_path / "other.npz")


# ------------------------------------------------------------------------------------- bad input
def test_unfitted_model_raises_not_fitted():
    m = ParametricHMM()
    for call in (lambda: m.score(np.zeros((20, 2)), [0.0]), lambda: m.synthesize([0.0]),
                 lambda: m.estimate_phi(np.zeros((20, 2))), lambda: m.save("never.npz"),
                 lambda: m.predict(np.zeros((20, 2)), [0.0])):
        with pytest.raises(NotFittedError, match="not fitted"):
            call()


def test_wrong_phi_dimension(model, data):
    X, lengths, phis, _ = data
    x = X[: lengths[0]]
    for bad in ([0.1], [0.1, 0.2, 0.3], [[0.1, 0.2]]):
        with pytest.raises(InvalidInputError, match=r"shape \(2,\)"):
            model.score(x, bad)
        with pytest.raises(InvalidInputError, match=r"shape \(2,\)"):
            model.synthesize(bad)
    with pytest.raises(InvalidInputError, match=r"\(n_sequences, p\)"):
        ParametricHMM(n_states=K).fit(X, lengths, phis[:-1])
    with pytest.raises(InvalidInputError, match=r"reshape\(-1, 1\)"):
        ParametricHMM(n_states=K).fit(X, lengths, phis[:, 0])
    with pytest.raises(InvalidInputError, match="features per frame"):
        model.score(x[:, :2], phis[0])


def test_effects_must_span_the_parameter_space(data):
    X, lengths, phis, _ = data
    collinear = np.column_stack([phis[:, 0], 2 * phis[:, 0] + 1])
    with pytest.raises(IdentifiabilityError, match="affinely span"):
        ParametricHMM(n_states=K).fit(X, lengths, collinear)
    with pytest.raises(IdentifiabilityError, match="at least 3 sequences"):
        ParametricHMM(n_states=K).fit(X[: lengths[:2].sum()], lengths[:2], phis[:2])
    assert issubclass(IdentifiabilityError, ValueError)


def test_nan_is_rejected(data):
    X, lengths, phis, _ = data
    bad_x = X.copy()
    bad_x[7, 1] = np.nan
    with pytest.raises(InvalidInputError, match="finite"):
        ParametricHMM(n_states=K).fit(bad_x, lengths, phis)
    bad_phi = phis.copy()
    bad_phi[2, 0] = np.nan
    with pytest.raises(InvalidInputError, match="finite"):
        ParametricHMM(n_states=K).fit(X, lengths, bad_phi)


def test_sequences_shorter_than_the_chain(model, data):
    X, lengths, phis, _ = data
    with pytest.raises(InvalidInputError, match="shorter than the 30-state"):
        ParametricHMM(n_states=30).fit(X, lengths, phis)
    with pytest.raises(InvalidInputError, match="takes >= 4 frames"):
        model.score(X[:3], phis[0])
    # recognize treats such a model as unable to explain the sequence.
    with pytest.raises(InvalidInputError, match="no model"):
        recognize(X[:3], {0: model})


def test_bad_hyper_parameters(data):
    X, lengths, phis, _ = data
    for kwargs, match in (({"topology": "circular"}, "topology"), ({"covariance_type": "tied"}, "covariance_type"),
                          ({"n_states": 0}, "n_states"), ({"n_iter": 0}, "n_iter"), ({"tol": -1.0}, "tol"),
                          ({"reg_covar": float("nan")}, "reg_covar"), ({"covars_weight": -1.0}, "covars_weight"),
                          ({"covars_prior": np.ones(D + 1)}, "covars_prior must be 3 finite"),
                          ({"covars_prior": -np.ones(D)}, "covars_prior must be 3 finite")):
        with pytest.raises(InvalidInputError, match=match):
            ParametricHMM(**kwargs).fit(X, lengths, phis)


def test_synthesize_needs_left_right(data):
    X, lengths, phis, _ = data
    m = ParametricHMM(n_states=K, topology="ergodic", n_iter=3).fit(X, lengths, phis)
    with pytest.raises(InvalidInputError, match="left-right"):
        m.synthesize(phis[0])


# ----------------------------------------------------------------------------------- left-right-skip
@pytest.fixture(scope="module")
def skip_model(data):
    X, lengths, phis, _ = data
    return ParametricHMM(n_states=K, topology="left-right-skip", n_iter=20, random_state=0).fit(X, lengths, phis)


def test_skip_chain_moves_at_most_two_states_right(skip_model):
    a = skip_model.transmat_
    np.testing.assert_allclose(a.sum(axis=1), 1.0)
    i, j = np.indices(a.shape)
    assert np.all(a[(j < i) | (j > i + 2)] == 0.0)
    assert np.all(a[j == i + 2] > 0.0)  # skips started non-zero and EM keeps them possible
    np.testing.assert_array_equal(skip_model.startprob_, np.eye(K)[0])
    assert skip_model.min_frames == K // 2 + 1 == 3
    assert ParametricHMM(n_states=K).min_frames == K and ParametricHMM(n_states=K, topology="ergodic").min_frames == 1


def test_skip_chain_score_is_the_sum_over_every_path_from_first_to_last_state(skip_model, data):
    from itertools import product

    from scipy.special import logsumexp
    from scipy.stats import multivariate_normal

    X, lengths, phis, _ = data
    phi = phis[3]
    means = skip_model.mean_bar_ + skip_model.W_ @ phi
    a = skip_model.transmat_
    for x in (X[:3], X[:5]):  # 3 frames: only paths with a skip reach the last state
        logb = np.array([[multivariate_normal(means[j], skip_model.covars_[j]).logpdf(f) for j in range(K)]
                         for f in x])
        with np.errstate(divide="ignore"):
            log_a = np.log(a)
        paths = [p for p in product(range(K), repeat=len(x)) if p[0] == 0 and p[-1] == K - 1]
        log_paths = [sum(log_a[i, j] for i, j in zip(p[:-1], p[1:])) + logb[np.arange(len(x)), p].sum()
                     for p in paths]
        assert skip_model.score(x, phi) == pytest.approx(logsumexp(log_paths), rel=1e-9)
    with pytest.raises(InvalidInputError, match="takes >= 3 frames"):
        skip_model.score(X[:2], phi)


def test_skip_chains_recognise_performances_shorter_than_their_chain():
    models, truth = {}, {}
    for label, class_seed in ((0, 1), (1, 2), (2, 3)):  # class ids, as the discovery numbers its classes
        X, lengths, phis, _ = dataset(10 + class_seed, class_seed=class_seed, n=12)
        models[label] = ParametricHMM(n_states=K, topology="left-right-skip", n_iter=20,
                                      random_state=0).fit(X, lengths, phis)
        truth[label] = make_class(class_seed)
    plain_chain = {9: ParametricHMM(n_states=K, n_iter=5).fit(*dataset(3)[:3])}
    rng = np.random.default_rng(7)
    for label, (mean_bar, w) in truth.items():
        # three frames for four states: the second state is skipped
        fast = generate(rng, mean_bar, w, rng.uniform(-0.8, 0.8, size=P), durations=np.array([1, 0, 1, 1]))
        assert recognize(fast, models).label == label
        with pytest.raises(InvalidInputError, match="no model"):
            recognize(fast, plain_chain)


def test_skip_chain_synthesis_times_states_by_their_visit_probability(skip_model):
    import copy

    # a chain that skips often (trained on data without skips, EM makes skips rare)
    model = copy.deepcopy(skip_model)
    model.transmat_ = np.array([[0.6, 0.1, 0.3, 0.0], [0.0, 0.5, 0.2, 0.3], [0.0, 0.0, 0.7, 0.3], [0.0, 0.0, 0.0, 1.0]])
    a = model.transmat_
    # independent check of the visit probabilities: simulate the chain
    rng = np.random.default_rng(0)
    visits = np.zeros(K)
    for _ in range(20000):
        state, seen = 0, {0}
        while state != K - 1:
            state = int(rng.choice(K, p=a[state]))
            seen.add(state)
        visits[list(seen)] += 1
    visit = visits / 20000
    np.testing.assert_allclose(visit, model._visit_probabilities(), atol=0.01)
    phi = np.array([0.2, -0.4])
    path = model.synthesize(phi)
    expected_frames = np.sum(visit[:-1] / (1.0 - np.diagonal(a)[:-1])) + 1
    assert abs(len(path) - expected_frames) <= 1.0
    means = model.mean_bar_ + model.W_ @ phi
    np.testing.assert_allclose(path[0], means[0])
    np.testing.assert_allclose(path[-1], means[-1])


def test_skip_chain_save_load_round_trip(skip_model, data, tmp_path):
    X, _, phis, _ = data
    skip_model.save(tmp_path / "skip.npz")
    loaded = ParametricHMM.load(tmp_path / "skip.npz")
    assert loaded.topology == "left-right-skip"
    assert loaded.score(X[:3], phis[0]) == skip_model.score(X[:3], phis[0])
