"""The recognition baselines (per-class hmmlearn HMMs, a frame-wise classifier): known answers on two
well-separated classes with a grammar, the joined chains against hmmlearn's own Viterbi, the scores, the contract."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError, NotFittedError
from hoap_actions.primitives.baselines.frame_labels import episode_scores, recording_scores, true_cuts
from hoap_actions.primitives.baselines.recognition_comparison import discovery_labels, plot_timeline, timeline_runs

hmm = pytest.importorskip("hmmlearn.hmm")

from hoap_actions.primitives.baselines.class_hmms import ClassHMMs  # noqa: E402
from hoap_actions.primitives.baselines.frame_classifier import (  # noqa: E402
    FrameClassifier,
    marker_frame_features,
    window_features,
)

CLASSES = (3, 7, 5)  # every sequence: 3, then 7, then 5 (ids need not be 0..C-1)
START = {3: np.array([0.0, 0.0]), 7: np.array([4.0, 4.0]), 5: np.array([-4.0, 4.0])}


def sequences(seed: int, n: int) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """``n`` sequences of the three classes in grammar order, each class a ramp of 2-D points from its
    start, 15-30 frames long, with small noise: (X, labels, lengths)."""
    rng = np.random.default_rng(seed)
    X, labels, lengths = [], [], []
    for _ in range(n):
        total = 0
        for c in CLASSES:
            T = int(rng.integers(15, 31))
            ramp = START[c] + np.linspace(0.0, 1.0, T)[:, None] * np.array([1.0, 0.5])
            X.append(ramp + rng.normal(0.0, 0.05, ramp.shape))
            labels.append(np.full(T, c))
            total += T
        lengths.append(total)
    return np.concatenate(X), np.concatenate(labels), lengths


@pytest.fixture(scope="module")
def data():
    return sequences(0, 12), sequences(1, 5)


@pytest.fixture(scope="module")
def class_hmms(data):
    (X, labels, lengths), _ = data
    return ClassHMMs(n_states=3, n_iter=10).fit(X, lengths, labels=labels)


def test_class_hmms_decode_held_out_sequences_perfectly(class_hmms, data):
    _, (X, labels, lengths) = data
    assert np.array_equal(class_hmms.predict(X, lengths), labels)
    assert class_hmms.grammar_.is_grammatical(list(CLASSES))
    assert not class_hmms.grammar_.is_grammatical([7, 3, 5])


def test_class_hmms_class_cut_pieces_through_the_grammar(class_hmms, data):
    _, (X, labels, lengths) = data
    first = X[: lengths[0]]
    cuts = [(a, b) for _, a, b in true_cuts(labels[: lengths[0]])]
    assert np.array_equal(class_hmms.predict_segments(first, cuts), CLASSES)


def test_the_joined_chains_decode_as_hmmlearn_decodes_the_same_composite_hmm(class_hmms, data):
    """The chains and grammar as one hmmlearn GaussianHMM (the final class's last state absorbing, as
    hmmlearn has no end state): its Viterbi path and log-probability are those of the project's decoder."""
    _, (X, _, lengths) = data
    chained = class_hmms.chained_
    n = chained.state_class.size
    transmat = np.zeros((n, n))
    transmat[np.arange(n), np.arange(n)] = np.exp(chained.log_stay)
    transmat[np.arange(n - 1), np.arange(1, n)] = np.exp(chained.log_next[:-1])
    for a, last in enumerate(chained.last):
        transmat[last, chained.first] += np.exp(chained.log_exit[a] + chained.log_grammar[a])
    final = int(np.flatnonzero(np.isfinite(chained.log_end))[0])
    transmat[chained.last[final]] = np.eye(n)[chained.last[final]]
    composite = hmm.GaussianHMM(n_components=n, covariance_type="diag", init_params="", params="")
    composite.startprob_ = np.zeros(n)
    composite.startprob_[chained.first] = np.exp(chained.log_start)
    composite.transmat_ = transmat
    composite.means_ = chained.means
    composite.covars_ = chained.variances
    absorbing = dataclasses.replace(chained, log_stay=np.where(np.arange(n) == chained.last[final], 0.0,
                                                                chained.log_stay),
                                    log_exit=np.where(np.arange(len(chained.last)) == final, 0.0, chained.log_exit),
                                    log_end=np.where(np.isfinite(chained.log_end), 0.0, -np.inf))
    Z = (X[: lengths[0]] - class_hmms.mean_) / class_hmms.scale_
    logprob, states = composite.decode(Z, algorithm="viterbi")
    labels, score = absorbing.viterbi(absorbing.log_emissions(Z))
    np.testing.assert_allclose(absorbing.log_emissions(Z), composite._compute_log_likelihood(Z), rtol=1e-10)
    assert np.array_equal(labels, chained.state_class[states])
    assert score == pytest.approx(logprob, rel=1e-10)


def test_a_class_whose_runs_are_as_short_as_its_chain_keeps_a_proper_chain(data):
    """Every run of class 7 is exactly 3 frames, the chain's length: EM sees no stay anywhere, and without
    the transition pseudo-count the last state's row would be all zeros (then NaN parameters)."""
    (X, labels, lengths), _ = data
    keep = np.ones(len(X), bool)
    for start in np.flatnonzero(np.diff(np.r_[-1, labels]) != 0):
        if labels[start] == 7:
            keep[start + 3:start + np.argmax(labels[start:] != 7)] = False
    short_lengths = [int(np.sum(keep[a:b])) for a, b in zip(np.r_[0, np.cumsum(lengths)[:-1]], np.cumsum(lengths))]
    model = ClassHMMs(n_states=3, n_iter=10).fit(X[keep], short_lengths, labels=labels[keep])
    for chain in model.hmms_.values():
        np.testing.assert_allclose(chain.transmat_.sum(axis=1), 1.0)
        assert np.all(np.isfinite(chain.means_))
    assert model.exit_probabilities_[list(model.class_ids_).index(7)] == 1.0
    assert np.mean(model.predict(X[keep], short_lengths) == labels[keep]) > 0.95


def test_class_hmms_chains_are_left_right_and_exit_probabilities_in_range(class_hmms):
    for model in class_hmms.hmms_.values():
        assert np.allclose(np.triu(model.transmat_), model.transmat_)
        assert np.allclose(np.tril(model.transmat_, 1), model.transmat_)
        assert model.startprob_[0] == 1.0
    assert np.all((class_hmms.exit_probabilities_ > 0) & (class_hmms.exit_probabilities_ <= 1))


@pytest.fixture(scope="module")
def classifier(data):
    pytest.importorskip("sklearn")
    (X, labels, lengths), _ = data
    return FrameClassifier(offsets=(-2, 0, 2), train_stride=1, max_iter=20).fit(X, lengths, labels=labels)


@pytest.mark.parametrize("smoothing", ["none", "majority", "grammar"])
def test_the_classifier_recognises_held_out_sequences_perfectly(classifier, data, smoothing):
    _, (X, labels, lengths) = data
    classifier.set_params(smoothing=smoothing)
    assert np.array_equal(classifier.predict(X, lengths), labels)
    assert np.array_equal(classifier.smooth(classifier.predict_proba(X, lengths), lengths), labels)
    first = X[: lengths[0]]
    cuts = [(a, b) for _, a, b in true_cuts(labels[: lengths[0]])]
    assert np.array_equal(classifier.predict_segments(first, cuts), CLASSES)


def test_grammar_smoothing_removes_a_flicker_the_grammar_forbids(classifier):
    """Frames whose evidence points briefly to a class the grammar does not allow there are decoded
    into the run around them; the frame-by-frame classes keep the flicker."""
    proba = np.tile(np.eye(3)[[0]], (40, 1)) * 0.98 + 0.02 / 3  # class 3 (index 0: ids sorted 3, 5, 7)
    proba[20:40] = np.eye(3)[2] * 0.98 + 0.02 / 3               # then 7
    proba = np.vstack([proba, np.tile(np.eye(3)[1] * 0.98 + 0.02 / 3, (20, 1))])  # then 5
    proba[10:12] = np.eye(3)[1] * 0.9 + 0.1 / 3                 # a 2-frame flicker to 5 inside 3
    classifier.set_params(smoothing="none")
    assert set(classifier._smoothed(proba)[10:12]) == {1}
    classifier.set_params(smoothing="grammar")
    assert np.array_equal(classifier._smoothed(proba), np.repeat([0, 2, 1], [20, 20, 20]))


def test_majority_smoothing_is_a_centred_mode_filter(classifier):
    best = np.array([0, 0, 1, 0, 0, 2, 2, 2, 0, 2, 2])
    classifier.set_params(smoothing="majority", smoothing_window=3)
    assert np.array_equal(classifier._smoothed(np.eye(3)[best]), [0, 0, 0, 0, 0, 2, 2, 2, 2, 2, 2])


def test_window_and_marker_features():
    X = np.arange(10.0).reshape(5, 2)
    out = window_features(X, [(0, 3), (3, 5)], (-1, 0, 1))
    assert np.array_equal(out[0], [0, 1, 0, 1, 2, 3])      # clamped at the first sequence's start
    assert np.array_equal(out[2], [2, 3, 4, 5, 4, 5])      # and at its end: never the next sequence's frame
    assert np.array_equal(out[3], [6, 7, 6, 7, 8, 9])
    H = np.zeros((4, 3, 3))
    H[:, 0] = [1.0, 2.0, 3.0]
    H[:, 1] = [1.5, 2.0, 3.0]
    H[:, 2, 0] = np.arange(4) * 0.01
    F = marker_frame_features(H, fps=100.0)
    assert F.shape == (4, 18)
    assert np.allclose(F[:, :3], [1.0, 2.0, 3.0]) and np.allclose(F[:, 3:6], [0.5, 0.0, 0.0])
    assert np.allclose(F[:, 6:9], np.c_[np.arange(4) * 0.01 - 1.0, np.full(4, -2.0), np.full(4, -3.0)])
    assert np.allclose(F[:, 15], 1.0)  # marker 2 moves 1 cm per frame at 100 fps: 1 m/s


def test_scores_of_a_labelling():
    truth = np.array([-1, 0, 0, 0, 1, 1, 1, 1, -1, 2, 2])
    predicted = np.array([0, 0, 0, 1, 1, 1, 2, 2, 2, 2, 2])
    scores = episode_scores(predicted, truth, cut_classes=np.array([0, 1, 1]))
    assert scores["frames"] == 9 and scores["frames_right"] == 6
    assert scores["segments"] == 3 and scores["segments_right"] == 3  # class 1's run is half 2: ties go to the lower
    assert scores["edit"] == pytest.approx(1.0)                        # runs 0, 1, 2 against 0, 1, 2
    assert scores["cuts_right"] == 2
    figures = recording_scores([scores, episode_scores(truth, truth, np.array([0, 1, 2]))])
    assert figures["frame_accuracy"] == pytest.approx(15 / 18)
    assert figures["oracle_cut_accuracy"] == pytest.approx(5 / 6)


@pytest.mark.parametrize("name", ["ClassHMMs", "FrameClassifier"])
def test_contract(data, name):
    if name == "FrameClassifier":
        pytest.importorskip("sklearn")
    estimator = {"ClassHMMs": ClassHMMs, "FrameClassifier": FrameClassifier}[name]()
    (X, labels, lengths), _ = data
    with pytest.raises(NotFittedError):
        estimator.predict(X)
    with pytest.raises(InvalidInputError, match="labels"):
        estimator.fit(X, lengths)
    with pytest.raises(InvalidInputError, match="lengths"):
        estimator.fit(X, [5], labels=labels)
    with pytest.raises(InvalidInputError, match="labels must be"):
        estimator.fit(X, lengths, labels=labels[:-1])
    assert type(estimator)(**estimator.get_params()).get_params() == estimator.get_params()
    bad = {"ClassHMMs": {"n_states": 0}, "FrameClassifier": {"smoothing": "median"}}[name]
    with pytest.raises(InvalidInputError, match=next(iter(bad))):
        type(estimator)(**bad).fit(X, lengths, labels=labels)


def test_a_fitted_model_takes_new_decoding_params_only(data):
    _, (X, labels, lengths) = data
    model = ClassHMMs(n_states=3, n_iter=10).fit(X[:300], None, labels=labels[:300])
    before = model.chained_.log_stay.copy()
    model.set_params(stay_weight=2.0)
    np.testing.assert_allclose(model.chained_.log_stay, 2.0 * before)
    with pytest.raises(InvalidInputError, match="fit a new one"):
        model.set_params(n_states=4)
    with pytest.raises(InvalidInputError, match="stay_weight"):
        model.set_params(stay_weight=-1.0)
    assert model.stay_weight == 2.0


def test_cuts_are_checked(class_hmms, data):
    (X, _, _), _ = data
    with pytest.raises(InvalidInputError, match="cuts"):
        class_hmms.predict_segments(X[:30], [(0, 20), (10, 30)])


def test_discovery_labels_and_the_timeline_figure(tmp_path):
    discovery = SimpleNamespace(segmentations_=[[(0, 0, 3), (4, 3, 5)], [(0, 0, 2), (2, 2, 4)]])
    labels = discovery_labels(discovery, [5, 4])
    assert np.array_equal(labels, [0, 0, 0, 4, 4, 0, 0, 2, 2])
    with pytest.raises(InvalidInputError, match="fitted on 2 demonstrations"):
        discovery_labels(discovery, [5, 5])
    truth, guess = [labels[:5], labels[5:]], [np.array([0, 0, 4, 4, 4]), np.array([0, -1, 2, 2])]
    assert timeline_runs(truth) == [[0, 0, 3], [4, 3, 5], [0, 5, 7], [2, 7, 9]]
    timeline = {"title": "two episodes", "fps": 10.0, "kinds": {"0": "approach", "2": "remove", "4": "manipulation"},
                "episode_starts": [0, 5], "rows": {"true": timeline_runs(truth), "guess": timeline_runs(guess)}}
    plot_timeline(timeline, tmp_path / "timeline.png")
    assert (tmp_path / "timeline.png").stat().st_size > 1000
