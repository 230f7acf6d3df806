"""Primitive discovery (paper's eqs. 1-3, Figs. 5 and 7) on synthetic object trajectories, pure numpy."""

from __future__ import annotations

import json
from itertools import pairwise, product

import numpy as np
import pytest

from hoap_actions.errors import DataExistsError, DataFileError, InvalidInputError, NotFittedError
from hoap_actions.primitives.discovery.estimator import (
    APPROACH,
    MANIPULATION,
    REMOVE,
    UNKNOWN,
    PrimitiveDiscovery,
)
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.discovery.substrings import find_primitives, longest_common_substring
from hoap_actions.primitives.evaluation.segmentation import boundary_f1
from hoap_actions.primitives.hmm import hmm_math
from hoap_actions.primitives.hmm.gaussians import gaussian_kl, merge_gaussians, symmetric_kl_matrix
from hoap_actions.primitives.hmm.sparse_viterbi import sparse_viterbi

DIRECTIONS = {"right": (1.0, 0.0), "left": (-1.0, 0.0), "up": (0.0, 1.0), "down": (0.0, -1.0)}
DISTANCES = (0.04, 0.08, 0.12)  # 2, 4 and 6 spacings of 2 cm: the Fig. 7 P1 / P1 P2 / P1 P2 P3 case
PARK = np.array([-0.25, 0.0, 0.25])
TWO_CM = {"spacing": 0.02, "threshold": 2.0}  # the synthetic pushes' geometry is laid out in 2-cm pieces


def minimum_jerk(n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def push_demo(direction, distance, rng, noise=0.0):
    """Object at rest, pushed (minimum jerk) along ``direction``, at rest again; hand markers; true labels."""
    start = np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), 0.02])
    yaw = rng.uniform(-0.5, 0.5)
    n_approach, n_remove = rng.integers(20, 30, size=2)
    n_push = int(30 * (0.8 + 8 * distance)) + int(rng.integers(0, 5))
    u = np.array([*DIRECTIONS[direction], 0.0])
    travelled = np.concatenate([np.zeros(n_approach), distance * minimum_jerk(n_push), np.full(n_remove, distance)])
    poses = np.hstack([start + travelled[:, None] * u, np.tile([0.0, 0.0, yaw], (len(travelled), 1))])
    poses += noise * rng.standard_normal(poses.shape)
    grasp = start - 0.03 * u
    hand = np.concatenate(
        [
            PARK + minimum_jerk(n_approach)[:, None] * (grasp - PARK),
            grasp + travelled[n_approach : n_approach + n_push, None] * u,
            grasp + distance * u + minimum_jerk(n_remove)[:, None] * (PARK - grasp - distance * u),
        ]
    )
    markers = np.hstack([hand + 0.01 * k for k in range(6)])
    labels = np.repeat([0, 1, 2], [n_approach, n_push, n_remove])
    return poses, markers, labels


def stacked(trajectories):
    """Per-demonstration arrays as the estimator takes them: concatenated, with their lengths."""
    return np.concatenate(trajectories), [len(t) for t in trajectories]


def push_dataset(seed=0, noise=0.0, repeats=1):
    rng = np.random.default_rng(seed)
    keys = [key for _ in range(repeats) for key in product(DIRECTIONS, DISTANCES)]
    demos = [push_demo(d, dist, rng, noise) for d, dist in keys]
    return keys, [o for o, _, _ in demos], [h for _, h, _ in demos], [lab for _, _, lab in demos]


@pytest.fixture(scope="module")
def pushes():
    keys, objects, hands, labels = push_dataset(seed=1, noise=3e-4, repeats=2)
    model = PrimitiveDiscovery(**TWO_CM, random_state=0).fit(*stacked(objects), np.concatenate(hands))
    return keys, objects, hands, labels, model


def random_spd(rng, n):
    a = rng.standard_normal((n, n))
    return a @ a.T + n * np.eye(n) * 0.1


# --------------------------------------------------------------------------------- eqs. (1) - (3)


def test_kl_of_identical_gaussians_is_zero():
    rng = np.random.default_rng(0)
    mean, cov = rng.standard_normal(6), random_spd(rng, 6)
    assert gaussian_kl(mean, cov, mean, cov) == pytest.approx(0.0, abs=1e-10)
    sym = symmetric_kl_matrix(mean[None], cov[None], mean[None], cov[None])
    assert sym[0, 0] == pytest.approx(0.0, abs=1e-10)


def test_kl_matches_one_dimensional_closed_form():
    m0, s0, m1, s1 = 0.3, 0.5, -0.2, 1.5
    expected = np.log(s1 / s0) + (s0**2 + (m0 - m1) ** 2) / (2 * s1**2) - 0.5
    assert gaussian_kl([m0], [[s0**2]], [m1], [[s1**2]]) == pytest.approx(expected, rel=1e-12)


def test_kl_matches_monte_carlo():
    rng = np.random.default_rng(1)
    mean_q, cov_q = rng.standard_normal(3), random_spd(rng, 3)
    mean_p, cov_p = rng.standard_normal(3), random_spd(rng, 3)
    x = rng.multivariate_normal(mean_q, cov_q, size=200_000)

    def log_pdf(x, mean, cov):
        d = x - mean
        return -0.5 * (np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d) + np.linalg.slogdet(2 * np.pi * cov)[1])

    log_ratio = log_pdf(x, mean_q, cov_q) - log_pdf(x, mean_p, cov_p)
    standard_error = log_ratio.std() / np.sqrt(len(x))
    assert gaussian_kl(mean_q, cov_q, mean_p, cov_p) == pytest.approx(log_ratio.mean(), abs=4 * standard_error)


def test_symmetric_kl_matrix_is_the_vectorised_mean_of_both_directions():
    rng = np.random.default_rng(2)
    means_a, covs_a = rng.standard_normal((3, 4)), np.array([random_spd(rng, 4) for _ in range(3)])
    means_b, covs_b = rng.standard_normal((5, 4)), np.array([random_spd(rng, 4) for _ in range(5)])
    matrix = symmetric_kl_matrix(means_a, covs_a, means_b, covs_b)
    assert matrix.shape == (3, 5)
    for k, m in product(range(3), range(5)):
        both = gaussian_kl(means_a[k], covs_a[k], means_b[m], covs_b[m]) + gaussian_kl(
            means_b[m], covs_b[m], means_a[k], covs_a[k]
        )
        assert matrix[k, m] == pytest.approx(both / 2, rel=1e-9)


def test_merge_follows_eqs_2_and_3_on_a_known_answer():
    mean, cov = merge_gaussians(np.zeros(2), np.diag([1.0, 4.0]), np.ones(2), np.diag([4.0, 1.0]))
    # precisions (1, 1/4) and (1/4, 1) average to 5/8 each: covariance 1.6 I
    np.testing.assert_allclose(cov, 1.6 * np.eye(2))
    np.testing.assert_allclose(mean, 1.6 * 0.5 * np.array([0.25, 1.0]))


def test_merge_weighting_extremes_and_identical_states():
    rng = np.random.default_rng(3)
    m0, c0, m1, c1 = rng.standard_normal(3), random_spd(rng, 3), rng.standard_normal(3), random_spd(rng, 3)
    mean, cov = merge_gaussians(m0, c0, m1, c1, omega=1.0)
    np.testing.assert_allclose(mean, m0)
    np.testing.assert_allclose(cov, c0)
    mean, cov = merge_gaussians(m0, c0, m0, c0)
    np.testing.assert_allclose(mean, m0)
    np.testing.assert_allclose(cov, c0)
    with pytest.raises(InvalidInputError, match="omega"):
        merge_gaussians(m0, c0, m1, c1, omega=1.5)


# ------------------------------------------------------------------------------- LCS (Fig. 5)


def test_fig5_example():
    primitives, labels = find_primitives([[1, 2, 3, 4, 5, 6, 7, 8], [9, 10, 1, 2, 3, 4, 11, 12]])
    assert primitives == [(1, 2, 3, 4), (5, 6, 7, 8), (9, 10), (11, 12)]
    assert labels == [[0, 1], [2, 0, 3]]
    assert longest_common_substring([1, 2, 3, 4, 5, 6, 7, 8], [9, 10, 1, 2, 3, 4, 11, 12]) == (0, 2, 4)


def test_longest_common_substring_matches_brute_force():
    rng = np.random.default_rng(4)
    for _ in range(50):
        a, b = rng.integers(0, 4, size=rng.integers(0, 12)), rng.integers(0, 4, size=rng.integers(0, 12))
        start_a, start_b, length = longest_common_substring(a, b)
        brute = max(
            (n for n in range(min(len(a), len(b)) + 1) for i in range(len(a) - n + 1) for j in range(len(b) - n + 1)
             if np.array_equal(a[i : i + n], b[j : j + n])),
            default=0,
        )
        assert length == brute
        assert np.array_equal(a[start_a : start_a + length], b[start_b : start_b + length])


def test_shorter_common_substrings_split_longer_primitives():
    # the Fig. 7 push structure: the longest push reuses the shorter pushes' primitives
    primitives, labels = find_primitives([[1, 2], [1, 2, 3, 4], [1, 2, 3, 4, 5, 6]])
    assert primitives == [(1, 2), (3, 4), (5, 6)]
    assert labels == [[0], [0, 1], [0, 1, 2]]


def test_primitives_tile_every_sequence():
    rng = np.random.default_rng(5)
    for _ in range(30):
        sequences = [list(rng.integers(0, 6, size=rng.integers(0, 10))) for _ in range(rng.integers(1, 5))]
        primitives, labels = find_primitives(sequences)
        assert len(set(primitives)) == len(primitives)
        for seq, lab in zip(sequences, labels):
            assert [s for k in lab for s in primitives[k]] == seq


def test_longest_common_piece_is_the_first_longest_shared_by_two_pieces():
    # (1, 2) and (3, 4) are both shared and longest: the first in order wins; repeats inside one piece do not count
    assert find_primitives([[5, 1, 2, 3, 4], [3, 4, 6, 1, 2]])[0] == [(5,), (1, 2), (3, 4), (6,)]
    assert find_primitives([[1, 2, 1, 2], [3]]) == ([(1, 2, 1, 2), (3,)], [[0], [1]])


# ------------------------------------------------------------------------------ sparse Viterbi


def random_sparse_hmm(rng, k, n_frames):
    """A left-right-like HMM with random extra jumps and forbidden entries, and random frame scores."""
    transmat = rng.random((k, k)) * (rng.random((k, k)) < 0.4)
    transmat[np.arange(k), np.arange(k)] += 0.2
    transmat /= transmat.sum(axis=1, keepdims=True)
    startprob = rng.random(k) * (rng.random(k) < 0.6)
    startprob[0] += 0.1
    with np.errstate(divide="ignore"):
        return np.log(startprob / startprob.sum()), np.log(transmat), rng.normal(size=(n_frames, k))


def test_sparse_viterbi_matches_the_dense_one():
    rng = np.random.default_rng(11)
    for trial in range(150):
        lengths = rng.integers(1, 15, size=rng.integers(1, 6))
        log_start, log_trans, log_frameprob = random_sparse_hmm(rng, int(rng.integers(1, 9)), int(lengths.sum()))
        if trial % 3 == 0:
            log_frameprob = np.round(log_frameprob)  # ties: both go to the lowest state index
        best, path = sparse_viterbi(log_start, log_trans, log_frameprob, lengths)
        dense_best, dense_path = hmm_math.viterbi(log_start, log_trans, log_frameprob, lengths)
        np.testing.assert_allclose(best, dense_best)
        np.testing.assert_array_equal(path, dense_path)


def test_sparse_viterbi_impossible_sequence_and_bad_input():
    with np.errstate(divide="ignore"):
        log_start = np.log([1.0, 0.0])
        log_trans = np.log(np.eye(2))  # state 0 never reaches state 1
        log_frameprob = np.log([[1.0, 0.0], [0.0, 1.0]])  # the second frame fits state 1 only
    best, _ = sparse_viterbi(log_start, log_trans, log_frameprob, [2])
    assert best[0] == -np.inf
    with pytest.raises(InvalidInputError, match="shapes"):
        sparse_viterbi(np.zeros(2), np.zeros((3, 3)), np.zeros((4, 2)), [4])
    with pytest.raises(InvalidInputError, match="lengths"):
        sparse_viterbi(np.zeros(2), np.zeros((2, 2)), np.zeros((4, 2)), [3])


# ------------------------------------------------------------------------- discovery on pushes


def manipulation_ids(model, demo):
    return [pid for pid, *_ in model.segmentations_[demo] if model.primitive_kinds_[pid] == MANIPULATION]


def test_pushes_give_fig7_structure(pushes):
    keys, _, _, _, model = pushes
    assert model.primitive_kinds_.count(APPROACH) == 1 and model.primitive_kinds_.count(REMOVE) == 1
    per_direction = {}
    for demo, (direction, distance) in enumerate(keys):
        kinds = [model.primitive_kinds_[pid] for pid, *_ in model.segmentations_[demo]]
        assert kinds[0] == APPROACH and kinds[-1] == REMOVE
        per_direction.setdefault(direction, {}).setdefault(distance, set()).add(tuple(manipulation_ids(model, demo)))
    used = []
    for direction, by_distance in per_direction.items():
        assert all(len(v) == 1 for v in by_distance.values()), f"repetitions of a {direction} push disagree"
        short, middle, long = (next(iter(by_distance[d])) for d in DISTANCES)
        assert len(short) == 1 and middle[:1] == short and long[:2] == middle and len(long) == 3  # P1, P1 P2, P1 P2 P3
        used.append(set(long))
    assert len(set.union(*used)) == 12, "pushes in different directions share no primitive"


def test_segments_tile_frames_and_match_true_phases(pushes):
    _, objects, _, labels, model = pushes
    coarse = []
    for demo, obj in enumerate(objects):
        segments = model.segmentations_[demo]
        assert segments[0][1] == 0 and segments[-1][2] == len(obj)
        assert all(a[2] == b[1] and a[1] < a[2] for a, b in pairwise(segments))
        kinds = np.empty(len(obj), int)
        for pid, start, end in segments:
            kinds[start:end] = (APPROACH, MANIPULATION, REMOVE).index(model.primitive_kinds_[pid])
        coarse.append(kinds)
    # minimum-jerk pushes barely move at both ends, so the boundaries land within ~0.4 s of the truth
    assert boundary_f1(coarse, labels, tolerance_frames=12) == 1.0


def test_classes_carry_effects(pushes):
    keys, objects, hands, _, model = pushes
    assert [c.primitive_id for c in model.classes_] == list(range(len(model.primitives_)))
    for cls in model.classes_:
        assert cls.kind == model.primitive_kinds_[cls.primitive_id]
        for segment in cls.segments:
            track = hands[segment.demo][:, 6:9] if cls.kind != MANIPULATION else objects[segment.demo][:, :3]
            assert segment.source == ("object" if cls.kind == MANIPULATION else "hand")
            np.testing.assert_allclose(segment.phi, np.r_[track[segment.start], track[segment.end - 1]])
        if cls.kind == MANIPULATION:  # every primitive moves the object by about two spacings
            displacement = np.linalg.norm(cls.phis[:, 3:] - cls.phis[:, :3], axis=1)
            np.testing.assert_allclose(displacement, 0.04, atol=0.012)
        X, lengths = cls.movements(*stacked(hands))
        assert lengths.tolist() == [s.end - s.start for s in cls.segments] and X.shape == (sum(lengths), 18)
        first = cls.segments[0]
        np.testing.assert_array_equal(X[: lengths[0]], hands[first.demo][first.start : first.end])
    approach = model.classes_[model.primitive_kinds_.index(APPROACH)]
    np.testing.assert_allclose(approach.phis[:, :3], np.tile(PARK + 0.02, (len(keys), 1)), atol=1e-9)
    with pytest.raises(InvalidInputError, match="lengths"):
        approach.movements(*stacked(hands[:2]))


def test_predict_reproduces_the_training_segmentation(pushes):
    _, objects, _, _, model = pushes
    predicted = model.predict(*stacked(objects))
    assert len(predicted) == len(objects) and all(labels.dtype.kind == "i" for labels in predicted)
    for labels, segments in zip(predicted, model.segmentations_):
        expected = np.concatenate([np.full(end - start, pid) for pid, start, end in segments])
        np.testing.assert_array_equal(labels, expected)


def test_same_seed_same_result():
    _, objects, hands, _ = push_dataset(seed=7, noise=3e-4)
    a = PrimitiveDiscovery(**TWO_CM, random_state=3).fit(*stacked(objects), np.concatenate(hands))
    b = PrimitiveDiscovery(**TWO_CM, random_state=3).fit(*stacked(objects), np.concatenate(hands))
    assert a.primitives_ == b.primitives_ and a.segmentations_ == b.segmentations_ and a.classes_ == b.classes_
    np.testing.assert_array_equal(a.joint_means_, b.joint_means_)
    np.testing.assert_array_equal(a.transmat_, b.transmat_)


def test_joint_hmm_is_a_valid_hmm(pushes):
    *_, model = pushes
    k = len(model.joint_means_)
    assert model.joint_covars_.shape == (k, 6, 6) and model.transmat_.shape == (k, k)
    np.testing.assert_allclose(model.transmat_.sum(axis=1), 1.0)
    np.testing.assert_allclose(model.startprob_.sum(), 1.0)
    assert np.all(np.linalg.eigvalsh(model.joint_covars_) > 0)
    assert all(a != b for s in model.state_sequences_ for a, b in pairwise(s))  # repetitions dropped


def test_rotation_gets_gaussians_and_is_relative_to_the_initial_pose():
    t = minimum_jerk(60)
    demos = []
    for yaw0 in (0.0, 1.0, -2.0):
        yaw = np.concatenate([np.full(20, yaw0), yaw0 + np.pi / 2 * t, np.full(20, yaw0 + np.pi / 2)])
        demos.append(np.hstack([np.tile([0.1, -0.05, 0.02], (len(yaw), 1)), np.zeros((len(yaw), 2)), yaw[:, None]]))
    model = PrimitiveDiscovery(**TWO_CM).fit(*stacked(demos))
    assert model.primitive_kinds_ == [APPROACH, MANIPULATION, REMOVE]
    assert len(model.primitives_[1]) == 4  # pi/2 rad * 5 cm = 7.9 cm of arc: four 2-cm Gaussians
    assert len(set(model.state_sequences_)) == 1  # the same rotation from any initial yaw


def test_grammar_of_discovered_primitives():
    """Discovery's class sequences feed the grammar: every demonstration is grammatical."""
    _, objects, hands, _ = push_dataset(seed=3)
    model = PrimitiveDiscovery(**TWO_CM).fit(*stacked(objects), np.concatenate(hands))
    sequences = [[pid for pid, *_ in segments] for segments in model.segmentations_]
    grammar = ActionGrammar().fit(sequences)
    assert all(grammar.is_grammatical(seq) for seq in sequences)
    approach, remove = model.primitive_kinds_.index("approach"), model.primitive_kinds_.index("remove")
    assert grammar.next_distribution() == {approach: 1.0}
    assert len(grammar.next_distribution([approach])) == 4  # the first primitive of each direction
    assert not grammar.is_grammatical([remove, approach])


def test_rest_and_motion_frames_decode_to_rest_and_motion_states(pushes):
    """Approach and remove are exactly the rest pieces of the cut: Viterbi may not move them."""
    _, objects, _, _, model = pushes
    for obj, segments in zip(objects, model.segmentations_):
        _, cuts = model._prepare(obj)
        assert segments[0][2] == cuts[0][1] and segments[-1][1] == cuts[-1][0]
        assert model.primitive_kinds_[segments[0][0]] == APPROACH and model.primitive_kinds_[segments[-1][0]] == REMOVE


def test_rest_ends_where_the_push_starts_though_the_object_creeps_before():
    """A settling object creeps by micrometres, monotonically in noise-free data (as the simulator's
    block does); the rest must end at the hand's contact, not where the creep began."""
    n_rest, n_push = 60, 40
    settle = np.minimum(np.arange(n_rest), 3) * 7e-6 - np.linspace(0.0, 1e-6, n_rest)  # 20 um, then 1 um back
    y = np.concatenate([settle, settle[-1] + 0.002 * np.arange(1, n_push + 1), np.full(40, settle[-1] + 0.08)])
    poses = np.zeros((len(y), 6))
    poses[:, 1], poses[:, 2] = y, 0.025
    model = PrimitiveDiscovery(**TWO_CM).fit(poses, [len(poses)])
    assert abs(model.segmentations_[0][0][2] - n_rest) <= 1
    assert abs(model.segmentations_[0][-1][1] - (n_rest + n_push)) <= 1


def same_segmentations_up_to_renaming(a: PrimitiveDiscovery, b: PrimitiveDiscovery) -> bool:
    """The same cuts in every demonstration, and primitive ids that map one-to-one."""
    renaming: dict[int, int] = {}
    for cuts_a, cuts_b in zip(a.segmentations_, b.segmentations_, strict=True):
        if [cut[1:] for cut in cuts_a] != [cut[1:] for cut in cuts_b]:
            return False
        for (id_a, *_), (id_b, *_) in zip(cuts_a, cuts_b):
            if renaming.setdefault(id_a, id_b) != id_b:
                return False
    return len(set(renaming.values())) == len(renaming)


def test_results_do_not_change_when_data_and_spacing_scale_together(pushes):
    """With the default reg_covar (spacing^2 / 48) the method's only length scales are spacing and threshold."""
    _, objects, hands, _, model = pushes
    scale = 3.0
    scaled = [np.hstack([o[:, :3] * scale, o[:, 3:]]) for o in objects]
    big = PrimitiveDiscovery(spacing=0.02 * scale, threshold=2.0, rotation_radius=0.05 * scale)
    big.fit(*stacked(scaled), np.concatenate(hands))
    assert len(big.primitives_) == len(model.primitives_)
    assert same_segmentations_up_to_renaming(big, model)  # the canonical order's tie-break digests the raw poses
    assert model.covariance_floor == pytest.approx(0.02**2 / 48)
    assert PrimitiveDiscovery(reg_covar=1e-6).covariance_floor == 1e-6


def test_predict_on_a_motion_no_demonstration_showed():
    """A model of still objects has no motion states: the masked decoding is impossible and falls back."""
    _, objects, _, _ = push_dataset(seed=2)
    model = PrimitiveDiscovery(**TWO_CM).fit(np.tile(objects[0][:1], (30, 1)), [30])
    (labels,) = model.predict(objects[0], [len(objects[0])])
    assert set(labels.tolist()) <= {0, UNKNOWN} and labels[0] == 0


# ------------------------------------------------------------------------------ documented edges


def test_single_demonstration_is_approach_one_manipulation_remove():
    _, objects, hands, _ = push_dataset(seed=2)
    model = PrimitiveDiscovery(**TWO_CM).fit(objects[2], [len(objects[2])], hands[2])
    assert model.primitive_kinds_ == [APPROACH, MANIPULATION, REMOVE]
    assert len(model.primitives_[1]) == 6  # 12 cm: nothing to compare with, so one primitive
    assert [pid for pid, *_ in model.segmentations_[0]] == [0, 1, 2]


def test_object_that_never_moves_is_all_approach():
    _, objects, hands, _ = push_dataset(seed=2)
    still = np.tile(objects[0][:1], (40, 1))
    model = PrimitiveDiscovery().fit(still, [40])
    assert model.primitive_kinds_ == [APPROACH] and model.segmentations_ == [[(0, 0, 40)]]
    mixed = PrimitiveDiscovery().fit(*stacked([still, objects[0]]), np.concatenate([hands[0][:40], hands[0]]))
    assert mixed.segmentations_[0] == [(0, 0, 40)]
    assert [mixed.primitive_kinds_[p] for p, *_ in mixed.segmentations_[1]] == [APPROACH, MANIPULATION, REMOVE]
    single_frame = PrimitiveDiscovery().fit(objects[0][:1], [1])
    assert single_frame.segmentations_ == [[(0, 0, 1)]]


def test_without_hands_stationary_effects_use_the_object():
    _, objects, _, _ = push_dataset(seed=2)
    model = PrimitiveDiscovery().fit(*stacked(objects[:3]))
    approach = model.classes_[0]
    assert approach.kind == APPROACH and {s.source for s in approach.segments} == {"object"}
    assert sorted(s.demo for s in approach.segments) == [0, 1, 2]
    np.testing.assert_allclose(approach.phis[:, :3], [objects[s.demo][0, :3] for s in approach.segments])


@pytest.mark.parametrize(
    "X, lengths, message",
    [
        (np.zeros((0, 6)), [], "at least one sample"),
        (np.zeros((10, 3)), [10], r"6 columns"),
        (np.zeros(6), [1], "2-D"),
        (np.full((10, 6), np.nan), [10], "NaN"),
        ([np.zeros((10, 6)), np.zeros((5, 6))], [10, 5], "concatenated"),
        (np.array([["a"] * 6]), [1], "numeric"),
        (np.zeros((10, 6)), [4, 4], "sum to the number of rows of X \\(10\\); they sum to 8"),
        (np.zeros((10, 6)), [10, 0], "every length must be >= 1"),
        (np.zeros((10, 6)), [5.5, 4.5], "integers"),
        (np.zeros((10, 6)), [], "non-empty"),
        (np.zeros((10, 6)), [[10]], "1-D"),
    ],
)
def test_bad_poses_and_lengths(X, lengths, message):
    with pytest.raises(InvalidInputError, match=message):
        PrimitiveDiscovery().fit(X, lengths)


def test_implausible_poses_are_named_by_demonstration_frame_and_row():
    X = np.zeros((30, 6))
    X[17, 0] = 1e6
    with pytest.raises(InvalidInputError, match=r"X demonstration 1 frame 7 \(row 17\) has an object coordinate"):
        PrimitiveDiscovery().fit(X, [10, 20])
    X[17, 0], X[25, 3:] = 0.0, 1e3
    with pytest.raises(InvalidInputError, match=r"X demonstration 1 frame 15 \(row 25\) has a rotation vector"):
        PrimitiveDiscovery().fit(X, [10, 20])


def test_bad_hands_and_parameters():
    _, objects, hands, _ = push_dataset(seed=2)
    X, lengths = stacked(objects[:2])
    H = np.concatenate(hands[:2])
    with pytest.raises(InvalidInputError, match=r"H must have shape \(N, 18\)"):
        PrimitiveDiscovery().fit(X, lengths, H[:-1])
    with pytest.raises(InvalidInputError, match=r"\(N, 18\)"):
        PrimitiveDiscovery().fit(X, lengths, H[:, :9])
    with pytest.raises(InvalidInputError, match="NaN"):
        PrimitiveDiscovery().fit(X, lengths, np.where(np.arange(len(H))[:, None] == 3, np.nan, H))
    far = H.copy()
    far[len(objects[0]) + 2, 4] = 500.0
    with pytest.raises(InvalidInputError, match=r"H demonstration 1 frame 2 .* marker coordinate"):
        PrimitiveDiscovery().fit(X, lengths, far)
    for params in ({"spacing": 0.0}, {"threshold": -1.0}, {"reg_covar": float("nan")}, {"hand_marker": 6},
                   {"spacing": "2 cm"}):
        with pytest.raises(InvalidInputError, match=next(iter(params))):
            PrimitiveDiscovery(**params).fit(*stacked(objects[:1]))


def test_not_fitted():
    with pytest.raises(NotFittedError, match="this PrimitiveDiscovery is not fitted yet: call fit"):
        PrimitiveDiscovery().predict(np.zeros((5, 6)), [5])
    with pytest.raises(NotFittedError):
        PrimitiveDiscovery().save("unused.json")


# ---------------------------------------------------------------------------------- persistence


def test_save_load_round_trip(pushes, tmp_path):
    _, objects, _, _, model = pushes
    path = tmp_path / "discovery.json"
    model.save(path)
    assert json.loads(path.read_text())["format_version"] == 2
    assert json.loads(path.read_text())["params"]["reg_covar"] is None
    loaded = PrimitiveDiscovery.load(path)
    assert loaded.get_params() == model.get_params()
    assert loaded.primitives_ == model.primitives_ and loaded.segmentations_ == model.segmentations_
    assert loaded.classes_ == model.classes_ and loaded.state_sequences_ == model.state_sequences_
    np.testing.assert_array_equal(loaded.joint_covars_, model.joint_covars_)
    for a, b in zip(loaded.predict(*stacked(objects[:3])), model.predict(*stacked(objects[:3]))):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(DataExistsError):
        model.save(path)
    model.save(path, overwrite=True)


def test_load_rejects_bad_files(tmp_path):
    with pytest.raises(DataFileError, match="no PrimitiveDiscovery file"):
        PrimitiveDiscovery.load(tmp_path / "missing.json")
    (tmp_path / "garbage.json").write_text("{not json")
    with pytest.raises(DataFileError, match="JSON"):
        PrimitiveDiscovery.load(tmp_path / "garbage.json")
    (tmp_path / "future.json").write_text(json.dumps({"kind": "PrimitiveDiscovery", "format_version": 99}))
    with pytest.raises(DataFileError, match="format_version"):
        PrimitiveDiscovery.load(tmp_path / "future.json")
    (tmp_path / "partial.json").write_text(
        json.dumps({"kind": "PrimitiveDiscovery", "format_version": 1, "params": {}})
    )
    with pytest.raises(DataFileError, match="corrupt"):
        PrimitiveDiscovery.load(tmp_path / "partial.json")


# ------------------------------------------------------------------------- order-free merging


def test_agglomerative_merging_gives_fig7_structure_whatever_the_order(pushes):
    keys, objects, hands, _, _ = pushes
    order = np.random.default_rng(5).permutation(len(objects))
    fitted = [PrimitiveDiscovery(**TWO_CM, merging="agglomerative").fit(
        *stacked([objects[i] for i in o]), np.concatenate([hands[i] for i in o]))
        for o in (np.arange(len(objects)), order)]
    a, b = fitted
    np.testing.assert_array_equal(a.joint_means_, b.joint_means_)
    assert a.primitives_ == b.primitives_ and a.primitive_kinds_ == b.primitive_kinds_
    for k, i in enumerate(order):  # the same segmentation of every demonstration, under the caller's index
        assert b.segmentations_[k] == a.segmentations_[i]
    assert {(c.primitive_id, tuple(sorted((s.demo, s.start) for s in c.segments))) for c in a.classes_} == {
        (c.primitive_id, tuple(sorted((int(order[s.demo]), s.start) for s in c.segments))) for c in b.classes_}
    for demo, (_direction, distance) in enumerate(keys):
        chain = manipulation_ids(a, demo)
        assert len(chain) == DISTANCES.index(distance) + 1  # P1 / P1 P2 / P1 P2 P3, as the fold gives them


def test_cluster_pieces_merges_closest_first_within_what_is_allowed():
    from hoap_actions.primitives.discovery.state_clustering import cluster_pieces

    means = np.array([[0.0], [0.1], [5.0], [5.2], [0.05]])
    covs = np.ones((5, 1, 1))
    allowed = np.ones((5, 5), dtype=bool)
    label, merged_means, merged_covs = cluster_pieces(means, covs, allowed, threshold=1.0)
    np.testing.assert_array_equal(label, [0, 0, 1, 1, 0])
    np.testing.assert_allclose(merged_means[:, 0], [0.05, 5.1])  # equal-weight merges of eqs. (2)-(3)
    np.testing.assert_allclose(merged_covs[:, 0, 0], 1.0)
    allowed[0, 1] = allowed[1, 0] = False  # e.g. two pieces of one demonstration: never one state
    label, _, _ = cluster_pieces(means, covs, allowed, threshold=1.0)
    assert label[0] != label[1] and label[2] == label[3] and label[4] in (label[0], label[1])
    permutation = np.array([3, 0, 4, 2, 1])
    again, _, _ = cluster_pieces(means[permutation], covs, allowed[np.ix_(permutation, permutation)], threshold=1.0)
    assert {frozenset(permutation[again == k]) for k in set(again)} == {frozenset(np.flatnonzero(label == k))
                                                                       for k in set(label)}


def test_a_version_1_discovery_file_is_the_papers_fold(pushes, tmp_path):
    *_, model = pushes
    path = tmp_path / "model.json"
    model.save(path)
    document = json.loads(path.read_text())
    document["format_version"] = 1
    del document["params"]["merging"]
    path.write_text(json.dumps(document))
    assert PrimitiveDiscovery.load(path).merging == "fold"
    with pytest.raises(InvalidInputError, match="merging must be one of"):
        PrimitiveDiscovery(merging="greedy").fit(*stacked(pushes[1][:2]))
