"""hmm_math against hmmlearn (independent reference), brute-force enumeration, hand-worked cases, invariants."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.hmm import hmm_math as hm

hmmlearn_hmm = pytest.importorskip("hmmlearn.hmm")

RTOL = 1e-8


# ------------------------------------------------------------------------------------------ helpers
def random_model(rng, k, d, topology, covariance_type):
    means = rng.normal(scale=2.0, size=(k, d))
    if covariance_type == "full":
        b = rng.normal(size=(k, d, d))
        covars = b @ b.transpose(0, 2, 1) + 0.5 * np.eye(d)
    else:
        covars = rng.uniform(0.3, 2.0, size=(k, d))
    if topology == "ergodic":
        startprob = rng.dirichlet(np.ones(k))
        transmat = rng.dirichlet(np.ones(k), size=k)
    else:
        startprob = np.eye(k)[0]
        transmat = hm.left_right_transmat(k, 0.7)
    return startprob, transmat, means, covars


def reference(startprob, transmat, means, covars, covariance_type):
    model = hmmlearn_hmm.GaussianHMM(n_components=len(startprob), covariance_type=covariance_type,
                                     init_params="", params="t", n_iter=1, implementation="log")
    model.startprob_, model.transmat_, model.means_, model.covars_ = startprob, transmat, means, covars
    return model


def split(X, lengths):
    return np.split(X, np.cumsum(lengths)[:-1])


def logs(*arrays):
    with np.errstate(divide="ignore"):
        return [np.log(a) for a in arrays]


def brute_force(pi, a, b, end=None):
    """Sum and max over all K^T state paths of one sequence with frame probabilities b (T, K)."""
    t, k = b.shape
    end = np.ones(k) if end is None else end
    total, best, best_path = 0.0, -1.0, None
    posts = np.zeros((t, k))
    trans = np.zeros((k, k))
    for path in itertools.product(range(k), repeat=t):
        p = pi[path[0]] * b[0, path[0]] * end[path[-1]]
        for i in range(1, t):
            p *= a[path[i - 1], path[i]] * b[i, path[i]]
        total += p
        posts[np.arange(t), path] += p
        for i in range(1, t):
            trans[path[i - 1], path[i]] += p
        if p > best:
            best, best_path = p, path
    return total, posts / total, trans / total, best, np.array(best_path)


# ------------------------------------------------------------------------------- validate_sequences
def test_validate_sequences_accepts_and_defaults():
    X, lengths = hm.validate_sequences([[1, 2], [3, 4], [5, 6]], [1, 2])
    assert X.dtype == np.float64 and X.shape == (3, 2)
    assert lengths.dtype == np.int64 and lengths.tolist() == [1, 2]
    assert hm.validate_sequences(np.zeros((4, 1)))[1].tolist() == [4]


@pytest.mark.parametrize("X, lengths, match", [
    (np.zeros(5), None, "2-D"),
    (np.zeros((0, 2)), None, "at least one sample"),
    (np.array([[0.0, np.nan]]), None, "finite"),
    (np.array([[np.inf]]), None, "finite"),
    (np.zeros((5, 2)), [2, 2], "sum to the number of rows"),
    (np.zeros((5, 2)), [5, 0], ">= 1"),
    (np.zeros((5, 2)), [2.5, 2.5], "integers"),
    (np.zeros((5, 2)), [[5]], "1-D"),
    ([["a", "b"]], None, "numeric"),
])
def test_validate_sequences_rejects(X, lengths, match):
    with pytest.raises(InvalidInputError, match=match):
        hm.validate_sequences(X, lengths)


# ------------------------------------------------------------------------------- Gaussian densities
@pytest.mark.parametrize("covariance_type", ["full", "diag"])
def test_log_gaussian_density_matches_scipy(covariance_type):
    rng = np.random.default_rng(0)
    _, _, means, covars = random_model(rng, 4, 3, "ergodic", covariance_type)
    X = rng.normal(scale=3.0, size=(50, 3)) + 100.0        # far from the origin: centring must cope
    means = means + 100.0
    got = hm.log_gaussian_density(X, means, covars, covariance_type)
    for k in range(4):
        cov = covars[k] if covariance_type == "full" else np.diag(covars[k])
        np.testing.assert_allclose(got[:, k], multivariate_normal(means[k], cov).logpdf(X), rtol=1e-10, atol=1e-10)


def test_log_gaussian_density_known_answer():
    # log N(0 | 0, 1) = -log(2 pi) / 2;  log N(2 | 0, 1) = -log(2 pi) / 2 - 2;  log N(2 | 0, 4) = -log(8 pi) / 2 - 1/2
    got = hm.log_gaussian_density([[0.0], [2.0]], [[0.0]], [[[1.0]]])
    np.testing.assert_allclose(got[:, 0], [-0.5 * np.log(2 * np.pi), -0.5 * np.log(2 * np.pi) - 2.0], rtol=1e-14)
    got = hm.log_gaussian_density([[2.0]], [[0.0]], [[4.0]], "diag")
    np.testing.assert_allclose(got, [[-0.5 * np.log(8 * np.pi) - 0.5]])


def test_log_gaussian_density_per_sequence_means():
    rng = np.random.default_rng(1)
    _, _, _, covars = random_model(rng, 3, 2, "ergodic", "full")
    X = rng.normal(size=(2, 5, 2))
    means = rng.normal(size=(2, 3, 2))
    got = hm.log_gaussian_density_padded(X, means, covars)
    for s in range(2):
        np.testing.assert_allclose(got[s], hm.log_gaussian_density(X[s], means[s], covars), rtol=1e-12)


def test_log_gaussian_density_rejects_bad_covariance():
    with pytest.raises(InvalidInputError, match="positive definite"):
        hm.log_gaussian_density(np.zeros((2, 2)), np.zeros((1, 2)), np.array([[[1.0, 2.0], [2.0, 1.0]]]))
    with pytest.raises(InvalidInputError, match="> 0"):
        hm.log_gaussian_density(np.zeros((2, 2)), np.zeros((1, 2)), np.array([[1.0, 0.0]]), "diag")
    with pytest.raises(InvalidInputError, match="covariance_type"):
        hm.log_gaussian_density(np.zeros((2, 2)), np.zeros((1, 2)), np.array([[1.0, 1.0]]), "spherical")
    with pytest.raises(InvalidInputError, match="same D"):
        hm.log_gaussian_density(np.zeros((2, 3)), np.zeros((1, 2)), np.ones((1, 2)), "diag")


def test_second_moments_round_trip():
    rng = np.random.default_rng(2)
    X = rng.normal(size=(3, 4, 5))
    packed = hm.second_moments(X)
    assert packed.shape == (3, 4, 15)
    np.testing.assert_allclose(hm.unpack_second_moments(packed), X[..., :, None] * X[..., None, :])
    np.testing.assert_allclose(hm.second_moments(X, "diag"), X**2)


# --------------------------------------------------------------------- cross-check against hmmlearn
@pytest.mark.parametrize("covariance_type", ["full", "diag"])
@pytest.mark.parametrize("topology", ["ergodic", "left-right"])
@pytest.mark.parametrize("seed", [0, 1])
def test_matches_hmmlearn(covariance_type, topology, seed):
    rng = np.random.default_rng(seed)
    k, d = 5, 3
    startprob, transmat, means, covars = random_model(rng, k, d, topology, covariance_type)
    lengths = np.array([9, 1, 23, 5, 40]) if topology == "ergodic" else np.array([9, 6, 23, 5, 40])
    X = rng.normal(scale=2.0, size=(lengths.sum(), d))
    ref = reference(startprob, transmat, means, covars, covariance_type)
    log_pi, log_a = logs(startprob, transmat)
    logb = hm.log_gaussian_density(X, means, covars, covariance_type)

    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, lengths)
    np.testing.assert_allclose(ll, [ref.score(x) for x in split(X, lengths)], rtol=RTOL)
    np.testing.assert_allclose(gamma, ref.predict_proba(X, lengths), rtol=RTOL, atol=1e-12)

    best, path = hm.viterbi(log_pi, log_a, logb, lengths)
    ref_best, ref_path = zip(*(ref.decode(x, algorithm="viterbi") for x in split(X, lengths)))
    np.testing.assert_allclose(best, ref_best, rtol=RTOL)
    np.testing.assert_array_equal(path, np.concatenate(ref_path))

    # One Baum-Welch step of hmmlearn (transitions only, flat prior) is xi normalised by rows.
    ref.fit(X, lengths)
    rows = xi.sum(axis=1) > 0
    np.testing.assert_allclose(xi[rows] / xi[rows].sum(axis=1, keepdims=True), ref.transmat_[rows],
                               rtol=RTOL, atol=1e-12)


def test_invariants_and_padded_form():
    rng = np.random.default_rng(3)
    startprob, transmat, means, covars = random_model(rng, 6, 2, "ergodic", "full")
    lengths = np.array([1, 2, 17, 30])
    X = rng.normal(size=(lengths.sum(), 2))
    log_pi, log_a = logs(startprob, transmat)
    logb = hm.log_gaussian_density(X, means, covars)
    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, lengths)
    np.testing.assert_allclose(gamma.sum(axis=1), 1.0, rtol=1e-12)
    assert xi.sum() == pytest.approx(lengths.sum() - lengths.size, rel=1e-12)
    assert np.all(xi >= 0) and np.all(gamma >= 0)
    # A frame's posterior equals the sum of the transition posteriors out of it (checked in total).
    np.testing.assert_allclose(xi.sum(axis=1), gamma[np.concatenate([np.arange(a, a + n - 1) for a, n in
                                                                     zip(np.cumsum(lengths) - lengths, lengths)])]
                               .sum(axis=0), rtol=1e-10)
    ll_p, gamma_p, xi_p = hm.forward_backward_padded(log_pi, log_a, hm.pad_sequences(logb, lengths), lengths)
    np.testing.assert_allclose(ll_p, ll)
    np.testing.assert_allclose(hm.unpad_sequences(gamma_p, lengths), gamma)
    assert np.all(gamma_p[0, 1:] == 0.0)
    np.testing.assert_allclose(xi_p, xi)


# -------------------------------------------------------------------------------- known answers
def test_hand_computed_two_state_chain():
    # pi = (1, 0), A = [[.5, .5], [0, 1]], b(x1) = (.2, .6), b(x2) = (.1, .4).
    # Paths: 00 -> 1 * .2 * .5 * .1 = .01; 01 -> 1 * .2 * .5 * .4 = .04; P(X) = .05.
    # Best path 01 with probability .04; gamma_2 = (.2, .8); xi = [[.2, .8], [0, 0]].
    log_pi, log_a, logb = logs(np.array([1.0, 0.0]), np.array([[0.5, 0.5], [0.0, 1.0]]),
                               np.array([[0.2, 0.6], [0.1, 0.4]]))
    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, [2])
    assert ll[0] == pytest.approx(np.log(0.05), rel=1e-14)
    np.testing.assert_allclose(gamma, [[1.0, 0.0], [0.2, 0.8]], atol=1e-15)
    np.testing.assert_allclose(xi, [[0.2, 0.8], [0.0, 0.0]], atol=1e-15)
    best, path = hm.viterbi(log_pi, log_a, logb, [2])
    assert best[0] == pytest.approx(np.log(0.04), rel=1e-14) and path.tolist() == [0, 1]
    # Forcing the end in state 0 leaves only path 00.
    ll, gamma, _ = hm.forward_backward(log_pi, log_a, logb, [2], log_endprob=logs(np.array([1.0, 0.0]))[0])
    assert ll[0] == pytest.approx(np.log(0.01), rel=1e-14)
    np.testing.assert_allclose(gamma, [[1.0, 0.0], [1.0, 0.0]], atol=1e-15)


@pytest.mark.parametrize("with_end", [False, True])
def test_brute_force_enumeration(with_end):
    rng = np.random.default_rng(4)
    k, t = 3, 5
    pi = rng.dirichlet(np.ones(k))
    a = rng.dirichlet(np.ones(k), size=k)
    a[0, 2] = 0.0                                             # a forbidden transition (-inf in log space)
    a /= a.sum(axis=1, keepdims=True)
    b = rng.uniform(0.01, 1.0, size=(t, k))
    end = np.array([0.0, 1.0, 1.0]) if with_end else None
    total, posts, trans, best, best_path = brute_force(pi, a, b, end)
    log_pi, log_a, logb = logs(pi, a, b)
    log_end = logs(end)[0] if with_end else None
    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, [t], log_end)
    assert ll[0] == pytest.approx(np.log(total), rel=1e-12)
    np.testing.assert_allclose(gamma, posts, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(xi, trans, rtol=1e-10, atol=1e-14)
    vbest, vpath = hm.viterbi(log_pi, log_a, logb, [t], log_end)
    assert vbest[0] == pytest.approx(np.log(best), rel=1e-12)
    np.testing.assert_array_equal(vpath, best_path)


def test_single_state_is_sum_of_densities():
    logb = np.array([[-1.0], [-2.5], [-0.25]])
    ll, gamma, xi = hm.forward_backward([0.0], [[0.0]], logb, [3])
    assert ll[0] == pytest.approx(-3.75) and np.all(gamma == 1.0) and xi[0, 0] == pytest.approx(2.0)


# --------------------------------------------------------------- underflow and impossible sequences
def test_log_space_fallback_when_scaling_underflows():
    # Left-right chain; the first sequence jumps at once to data only the last state explains, so
    # every reachable state's scaled emission underflows to 0 and the exact log-space path must take over.
    k = 4
    means = np.array([[0.0, 0.0], [10.0, 0.0], [20.0, 0.0], [30.0, 0.0]])
    covars = np.full((k, 2), 0.01)
    startprob, transmat = np.eye(k)[0], hm.left_right_transmat(k, 0.5)
    X = np.array([[0, 0], [30, 0], [30, 0], [30, 0], [30, 0], [0.1, 0], [10, 0], [20, 0], [30, 0.0]])
    lengths = np.array([5, 4])
    ref = reference(startprob, transmat, means, covars, "diag")
    log_pi, log_a = logs(startprob, transmat)
    logb = hm.log_gaussian_density(X, means, covars, "diag")
    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, lengths)
    assert ll[0] < -20000
    np.testing.assert_allclose(ll, [ref.score(x) for x in split(X, lengths)], rtol=RTOL)
    np.testing.assert_allclose(gamma, ref.predict_proba(X, lengths), atol=1e-12)
    assert xi.sum() == pytest.approx(lengths.sum() - lengths.size, rel=1e-12)
    # Only state 3 may end the sequence (a left-right model that must traverse the chain).
    log_end = logs(np.eye(k)[-1])[0]
    ll_end, gamma_end, _ = hm.forward_backward(log_pi, log_a, logb, lengths, log_end)
    np.testing.assert_allclose(gamma_end[[4, 8]], [np.eye(k)[-1]] * 2, atol=1e-12)
    _, path = hm.viterbi(log_pi, log_a, logb, lengths, log_end)
    assert path.tolist() == [0, 1, 2, 3, 3, 0, 1, 2, 3]


def log_enumeration(log_pi, log_a, logb, log_end):
    """Exact ll, gamma and xi of one sequence by enumerating every state path in log space (no underflow)."""
    t, k = logb.shape
    paths = np.array(list(itertools.product(range(k), repeat=t)))
    with np.errstate(invalid="ignore"):
        lp = (log_pi[paths[:, 0]] + logb[np.arange(t), paths].sum(axis=1)
              + log_a[paths[:, :-1], paths[:, 1:]].sum(axis=1) + log_end[paths[:, -1]])
    ll = np.logaddexp.reduce(lp)
    w = np.exp(lp - ll)
    gamma = np.stack([np.bincount(paths[:, i], w, minlength=k) for i in range(t)])
    xi = np.zeros((k, k))
    np.add.at(xi, (paths[:, :-1].ravel(), paths[:, 1:].ravel()), np.repeat(w, t - 1))
    return ll, gamma, xi


@pytest.mark.parametrize("logb", [
    # A path 1e-348 behind after two frames (its forward probability is flushed) wins later, when the
    # states ahead explain the data 500 nats worse per frame: the scaled pass must notice (ll was -1500.7).
    [[0, 0, 0], [-400, 0, 0], [-400, 0, 0], [0, -500, -500], [0, -500, -500], [0, -500, -500], [0, 0, 0], [0, 0, 0]],
    # 1e-174 behind (kept by the recursion, but below the statistics' flush) with backward factors of
    # 1e174: ll and gamma were right, the transition counts lost the staying step.
    [[0, 0, 0], [-400, 0, 0], [0, -500, -500], [0, -500, -500], [0, 0, 0], [0, 0, 0]],
])
def test_flushed_path_that_wins_later(logb):
    logb = np.array(logb, dtype=float)
    log_pi, log_a, log_end = logs(np.eye(3)[0], hm.left_right_transmat(3, 0.5), np.eye(3)[-1])
    ref_ll, ref_gamma, ref_xi = log_enumeration(log_pi, log_a, logb, log_end)
    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, [len(logb)], log_end)
    assert ll[0] == pytest.approx(ref_ll, rel=1e-12)
    np.testing.assert_allclose(gamma, ref_gamma, atol=1e-12)
    np.testing.assert_allclose(xi, ref_xi, atol=1e-12)
    # the same inside a batch of ordinary sequences
    batch = np.vstack([np.zeros((4, 3)), logb, np.zeros((5, 3))])
    ll_b, gamma_b, xi_b = hm.forward_backward(log_pi, log_a, batch, [4, len(logb), 5], log_end)
    assert ll_b[1] == pytest.approx(ref_ll, rel=1e-12)
    np.testing.assert_allclose(gamma_b[4:4 + len(logb)], ref_gamma, atol=1e-12)
    others = [log_enumeration(log_pi, log_a, np.zeros((n, 3)), log_end)[2] for n in (4, 5)]
    np.testing.assert_allclose(xi_b, ref_xi + others[0] + others[1], atol=1e-12)


def test_impossible_sequence_gives_minus_inf_and_zero_posteriors():
    log_pi, log_a = logs(np.eye(3)[0], hm.left_right_transmat(3))
    log_end = logs(np.eye(3)[-1])[0]
    logb = np.zeros((2 + 4, 3))
    ll, gamma, xi = hm.forward_backward(log_pi, log_a, logb, [2, 4], log_end)  # 2 frames cannot reach state 2
    assert ll[0] == -np.inf and np.isfinite(ll[1])
    assert np.all(gamma[:2] == 0.0) and gamma[2:].sum() == pytest.approx(4.0)
    assert xi.sum() == pytest.approx(3.0)


def test_left_right_paths_never_go_back():
    rng = np.random.default_rng(5)
    startprob, transmat, means, covars = random_model(rng, 6, 2, "left-right", "full")
    lengths = np.array([20, 35, 8])
    X = rng.normal(scale=3.0, size=(lengths.sum(), 2))
    log_pi, log_a = logs(startprob, transmat)
    logb = hm.log_gaussian_density(X, means, covars)
    _, path = hm.viterbi(log_pi, log_a, logb, lengths)
    for p in split(path, lengths):
        assert p[0] == 0 and np.all(np.diff(p) >= 0) and np.all(np.diff(p) <= 1)
    _, _, xi = hm.forward_backward(log_pi, log_a, logb, lengths)
    assert np.all(xi[transmat == 0] == 0)


# ------------------------------------------------------------------------------------ topology/shapes
def test_left_right_transmat():
    a = hm.left_right_transmat(4, 0.25)
    np.testing.assert_allclose(a, [[0.25, 0.75, 0, 0], [0, 0.25, 0.75, 0], [0, 0, 0.25, 0.75], [0, 0, 0, 1]])
    assert hm.left_right_transmat(1).tolist() == [[1.0]]
    for bad in ({"n_states": 0}, {"n_states": 2.5}, {"n_states": 3, "stay_prob": 1.0}):
        with pytest.raises(InvalidInputError):
            hm.left_right_transmat(**bad)


def test_shape_and_value_errors():
    with pytest.raises(InvalidInputError, match="log_transmat"):
        hm.forward_backward(np.zeros(2), np.zeros((3, 3)), np.zeros((4, 2)), [4])
    with pytest.raises(InvalidInputError, match="NaN"):
        hm.forward_backward(np.zeros(2), np.zeros((2, 2)), np.full((4, 2), np.nan), [4])
    with pytest.raises(InvalidInputError, match="sum to"):
        hm.viterbi(np.zeros(2), np.zeros((2, 2)), np.zeros((4, 2)), [3])
    with pytest.raises(InvalidInputError, match="log_endprob"):
        hm.forward_backward(np.zeros(2), np.zeros((2, 2)), np.zeros((4, 2)), [4], log_endprob=np.zeros(3))
