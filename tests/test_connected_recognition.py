"""Connected recognition: the chained HMM's Viterbi against a dense Viterbi over the same HMM, and its parts."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.hmm_math import viterbi
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.models.connected_recognition import ChainedHMM, chain_classes, exit_probability


def random_chained(rng: np.random.Generator, sizes=(3, 2, 4), dim: int = 2) -> ChainedHMM:
    """Three classes with random chains and a random grammar in which every transition is allowed."""
    sizes = np.array(sizes)
    n_classes, n_states = len(sizes), int(sizes.sum())
    first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    last = first + sizes - 1
    stay = rng.uniform(0.2, 0.8, n_states)
    forward = 1.0 - stay
    forward[last] = 0.0
    exit_p = 1.0 - stay[last]
    grammar = rng.dirichlet(np.ones(n_classes + 1), size=n_classes)  # to each class, then <end>
    with np.errstate(divide="ignore"):
        return ChainedHMM(
            class_ids=np.arange(10, 10 + n_classes),
            state_class=np.repeat(np.arange(n_classes), sizes),
            first=first, last=last,
            log_stay=np.log(stay), log_next=np.log(forward), log_exit=np.log(exit_p),
            log_start=np.log(rng.dirichlet(np.ones(n_classes))),
            log_end=np.log(grammar[:, -1]), log_grammar=np.log(grammar[:, :-1]),
            means=rng.normal(size=(n_states, dim)), variances=rng.uniform(0.5, 2.0, size=(n_states, dim)),
        )


def dense(chained: ChainedHMM) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The same HMM as a dense (start, transition, end) triple of log-probabilities."""
    n = chained.state_class.size
    log_a = np.full((n, n), -np.inf)
    log_a[np.arange(n), np.arange(n)] = chained.log_stay
    log_a[np.arange(n - 1), np.arange(1, n)] = chained.log_next[:-1]
    for a, la in enumerate(chained.last):
        log_a[la, chained.first] = chained.log_exit[a] + chained.log_grammar[a]
    log_pi = np.full(n, -np.inf)
    log_pi[chained.first] = chained.log_start
    log_end = np.full(n, -np.inf)
    log_end[chained.last] = chained.log_exit + chained.log_end
    return log_pi, log_a, log_end


@pytest.mark.parametrize("seed", range(5))
def test_viterbi_matches_a_dense_viterbi_over_the_same_hmm(seed):
    rng = np.random.default_rng(seed)
    chained = random_chained(rng)
    X = rng.normal(size=(40, 2))
    logb = chained.log_emissions(X)
    labels, score = chained.viterbi(logb)
    log_pi, log_a, log_end = dense(chained)
    best, states = viterbi(log_pi, log_a, logb, [len(X)], log_end)
    assert score == pytest.approx(float(best[0]), rel=1e-10)
    np.testing.assert_array_equal(labels, chained.state_class[states])


def test_log_emissions_are_diagonal_gaussian_log_densities():
    rng = np.random.default_rng(0)
    chained = random_chained(rng)
    X = rng.normal(size=(7, 2))
    expected = -0.5 * (((X[:, None, :] - chained.means[None]) ** 2 / chained.variances[None]).sum(axis=2)
                       + np.log(2 * np.pi * chained.variances).sum(axis=1)[None])
    np.testing.assert_allclose(chained.log_emissions(X), expected, rtol=1e-10, atol=1e-10)


def test_class_scores_are_each_chain_on_its_own():
    rng = np.random.default_rng(3)
    chained = random_chained(rng)
    X = rng.normal(size=(12, 2))
    logb = chained.log_emissions(X)
    scores = chained.class_scores(logb)
    _, log_a, _ = dense(chained)
    for c, (a, b) in enumerate(zip(chained.first, chained.last)):
        block = slice(a, b + 1)
        chain = log_a[block, block].copy()
        chain[-1, 0] = -np.inf  # the chain alone: no grammar transition back into the class
        pi = np.full(b - a + 1, -np.inf)
        pi[0] = 0.0
        end = np.full(b - a + 1, -np.inf)
        end[-1] = 0.0
        best, _ = viterbi(pi, chain, logb[:, block], [len(X)], end)
        assert scores[c] == pytest.approx(float(best[0]), rel=1e-10)
    assert np.isneginf(chained.class_scores(logb[:2])[2])  # 2 frames cannot cross a 4-state chain


def test_a_movement_no_grammatical_path_explains_gives_no_labels():
    chained = random_chained(np.random.default_rng(1))
    with np.errstate(divide="ignore"):
        blocked = ChainedHMM(**{**chained.__dict__, "log_end": np.full(3, -np.inf)})
    labels, score = blocked.viterbi(blocked.log_emissions(np.zeros((20, 2))))
    assert np.isneginf(score) and np.all(labels == -1)


def test_wrong_emission_shapes_are_refused():
    chained = random_chained(np.random.default_rng(1))
    with pytest.raises(InvalidInputError, match=r"log_emissions must be \(T >= 1, 9\)"):
        chained.viterbi(np.zeros((5, 4)))


def fitted_chain(rng: np.random.Generator, n_states: int = 3) -> tuple[ParametricHMM, list, np.ndarray]:
    """A left-right PHMM fitted on movements that dwell 4 frames in each of 3 levels (the last one too)."""
    movements, phis = [], np.linspace(0.0, 1.0, 6)[:, None]
    for phi in phis:
        levels = np.repeat(np.array([0.0, 5.0, 10.0]) + phi[0], 4)
        movements.append(levels[:, None] + 0.01 * rng.normal(size=(12, 1)))
    model = ParametricHMM(n_states=n_states, random_state=0).fit(np.concatenate(movements), [12] * 6, phis)
    return model, movements, phis


def test_exit_probability_is_movements_over_frames_in_the_last_state():
    model, movements, phis = fitted_chain(np.random.default_rng(0))
    assert exit_probability(model, movements, phis) == pytest.approx(6 / 24)  # 4 frames each in the last state


def test_chain_classes_joins_fitted_chains_with_the_grammar():
    rng = np.random.default_rng(0)
    model, movements, phis = fitted_chain(rng)
    grammar = ActionGrammar().fit([[7, 9], [7]])
    chained = chain_classes([model, model], [7, 9], [0.25, 0.5], grammar, stay_weight=2.0)
    assert chained.first.tolist() == [0, 3] and chained.last.tolist() == [2, 5]
    assert chained.log_grammar[0, 1] == pytest.approx(np.log(0.5)) and np.isneginf(chained.log_grammar[1, 0])
    assert chained.log_stay[2] == pytest.approx(2.0 * np.log(0.75))  # the last state: 1 - exit, to the power 2
    labels, _ = chained.viterbi(chained.log_emissions(np.concatenate([movements[0], movements[1]])))
    assert chained.class_ids[labels].tolist() == [7] * 12 + [9] * 12
    with pytest.raises(InvalidInputError, match="does not know classes"):
        chain_classes([model], [8], [0.5], grammar)
    with pytest.raises(InvalidInputError, match="stay_weight"):
        chain_classes([model], [7], [0.5], grammar, stay_weight=0)
