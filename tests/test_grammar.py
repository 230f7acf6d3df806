"""The action grammar: a probabilistic finite-state automaton over primitive classes."""

from __future__ import annotations

import itertools
import json
import math
from collections import Counter

import numpy as np
import pytest

from hoap_actions.errors import DataExistsError, DataFileError, InvalidInputError, NotFittedError
from hoap_actions.primitives.discovery.grammar import END, ActionGrammar

DEMOS = [
    ["approach", "push", "remove"],
    ["approach", "push", "remove"],
    ["approach", "move", "remove"],
    ["approach", "rotate", "remove"],
]


@pytest.fixture
def grammar():
    return ActionGrammar().fit(DEMOS)


def test_learns_approach_act_remove(grammar):
    assert grammar.symbols_ == ["approach", "push", "remove", "move", "rotate"]
    assert grammar.next_distribution() == {"approach": 1.0}
    assert grammar.next_distribution(["approach"]) == {"push": 0.5, "move": 0.25, "rotate": 0.25}
    for action in ("push", "move", "rotate"):
        assert grammar.next_distribution(["approach", action]) == {"remove": 1.0}
    assert grammar.next_distribution(["approach", "push", "remove"]) == {END: 1.0}


def test_is_grammatical(grammar):
    for action in ("push", "move", "rotate"):
        assert grammar.is_grammatical(["approach", action, "remove"])
    assert not grammar.is_grammatical(["remove", "approach"])
    assert not grammar.is_grammatical(["approach", "push", "remove", "approach"])
    assert not grammar.is_grammatical(["approach", "push"])  # push never ended a demonstration
    assert not grammar.is_grammatical(["approach", "push", "move", "remove"])
    assert not grammar.is_grammatical(["approach", "grasp", "remove"])  # unknown class
    assert not grammar.is_grammatical([])


def test_log_probability(grammar):
    assert grammar.log_probability(["approach", "push", "remove"]) == pytest.approx(math.log(0.5))
    assert grammar.log_probability(["approach", "move", "remove"]) == pytest.approx(math.log(0.25))
    assert grammar.log_probability(["remove", "approach"]) == -math.inf
    assert grammar.log_probability(["approach", "grasp", "remove"]) == -math.inf


def test_smoothing_changes_probabilities_not_the_language():
    grammar = ActionGrammar(smoothing=1.0).fit(DEMOS)
    assert np.isfinite(grammar.log_probability(["remove", "approach"]))
    assert not grammar.is_grammatical(["remove", "approach"])
    after_approach = grammar.next_distribution(["approach"])
    assert sum(after_approach.values()) == pytest.approx(1.0)
    # counts 2, 1, 1 (+1 each) over 5 classes and the end: 3/10 for push
    assert after_approach["push"] == pytest.approx(3 / 10) and after_approach["approach"] == pytest.approx(1 / 10)
    assert END not in grammar.next_distribution()  # the empty sequence is never possible
    assert all(grammar.is_grammatical(grammar.sample(seed)) for seed in range(50))


def test_sample_gives_grammatical_sequences_with_the_learned_frequencies(grammar):
    samples = [tuple(grammar.sample(np.random.default_rng(seed))) for seed in range(400)]
    assert all(grammar.is_grammatical(s) for s in samples)
    counts = Counter(s[1] for s in samples)
    assert set(counts) == {"push", "move", "rotate"}
    assert 0.4 < counts["push"] / 400 < 0.6
    assert grammar.sample(5) == grammar.sample(5)


def test_cycles_are_learned_and_sampled():
    grammar = ActionGrammar().fit([[0, 1, 2], [0, 1, 1, 2]])
    assert grammar.is_grammatical([0, 1, 1, 1, 2])
    assert grammar.next_distribution([0, 1]) == {1: pytest.approx(1 / 3), 2: pytest.approx(2 / 3)}
    assert all(grammar.is_grammatical(grammar.sample(seed)) for seed in range(30))


def test_text_and_dot(grammar):
    text = str(grammar)
    assert "approach -> push (0.50) | move (0.25) | rotate (0.25)" in text
    assert "<start> -> approach (1.00)" in text and "remove -> <end> (1.00)" in text
    dot = grammar.to_dot()
    assert dot.startswith("digraph ActionGrammar {") and dot.rstrip().endswith("}")
    assert '"approach" -> "push" [label="0.50"];' in dot
    assert '"remove" -> "<end>" [label="1.00"];' in dot
    assert dot.count("->") == 8
    assert "not fitted" in str(ActionGrammar())


def test_integer_classes_and_numpy_ints():
    grammar = ActionGrammar().fit([np.array([0, 3, 2]), [0, 4, 2]])
    assert grammar.symbols_ == [0, 3, 2, 4] and all(type(s) is int for s in grammar.symbols_)
    assert grammar.is_grammatical([np.int64(0), 3, 2])


def test_save_load_round_trip(grammar, tmp_path):
    path = tmp_path / "grammar.json"
    grammar.save(path)
    assert json.loads(path.read_text())["format_version"] == 1
    loaded = ActionGrammar.load(path)
    assert loaded.symbols_ == grammar.symbols_ and str(loaded) == str(grammar)
    np.testing.assert_array_equal(loaded.transmat_, grammar.transmat_)
    with pytest.raises(DataExistsError):
        grammar.save(path)
    ints = ActionGrammar(smoothing=0.5).fit([[0, 1, 2]])
    ints.save(path, overwrite=True)
    assert ActionGrammar.load(path).symbols_ == [0, 1, 2]
    assert ActionGrammar.load(path).smoothing == 0.5


def test_load_rejects_bad_files(tmp_path):
    with pytest.raises(DataFileError, match="no ActionGrammar file"):
        ActionGrammar.load(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("[1, 2")
    with pytest.raises(DataFileError, match="JSON"):
        ActionGrammar.load(tmp_path / "bad.json")
    (tmp_path / "old.json").write_text(json.dumps({"kind": "ActionGrammar", "format_version": 0}))
    with pytest.raises(DataFileError, match="format_version"):
        ActionGrammar.load(tmp_path / "old.json")
    (tmp_path / "short.json").write_text(
        json.dumps({"kind": "ActionGrammar", "format_version": 1, "smoothing": 0, "symbols": ["a"], "counts": [[1]]})
    )
    with pytest.raises(DataFileError, match="corrupt"):
        ActionGrammar.load(tmp_path / "short.json")


@pytest.mark.parametrize(
    "sequences, message",
    [
        ([], "empty"),
        ([[]], "empty"),
        ("approach", "string"),
        (["approach push"], "string"),
        ([[0.5, 1]], "int id or a str"),
        ([[True]], "int id or a str"),
        ([["<start>", "push"]], "reserved"),
        (5, "list of class sequences"),
    ],
)
def test_bad_sequences(sequences, message):
    with pytest.raises(InvalidInputError, match=message):
        ActionGrammar().fit(sequences)


def test_bad_smoothing_prefix_and_not_fitted(grammar):
    with pytest.raises(InvalidInputError, match="smoothing"):
        ActionGrammar(smoothing=-1).fit(DEMOS)
    with pytest.raises(InvalidInputError, match="unknown class"):
        grammar.next_distribution(["grasp"])
    for call in (lambda g: g.is_grammatical(["a"]), lambda g: g.sample(0), lambda g: g.to_dot()):
        with pytest.raises(NotFittedError):
            call(ActionGrammar())



PIECES = [["approach", "push-1", "push-2", "push-3", "remove"]] * 3 + [["approach", "move", "remove"]] * 2


def test_decode_agrees_with_brute_force_over_every_sequence():
    grammar = ActionGrammar(smoothing=0.3).fit(PIECES + [["approach", "push-1", "remove"]])
    rng = np.random.default_rng(0)
    for length in (1, 2, 3, 4):
        scores = [dict(zip(grammar.symbols_, rng.normal(0.0, 3.0, len(grammar.symbols_)))) for _ in range(length)]
        best = max(
            (list(seq) for seq in itertools.product(grammar.symbols_, repeat=length)),
            key=lambda seq: grammar.log_probability(seq) + sum(s[c] for s, c in zip(scores, seq)),
        )
        decoded, total = grammar.decode(scores)
        assert decoded == best
        assert total == pytest.approx(grammar.log_probability(best) + sum(s[c] for s, c in zip(scores, best)))


def test_decode_with_pair_scores_agrees_with_brute_force():
    grammar = ActionGrammar(smoothing=0.3).fit(PIECES + [["approach", "push-1", "remove"]])
    rng = np.random.default_rng(1)
    symbols = grammar.symbols_
    for length in (1, 2, 3, 4):
        scores = [dict(zip(symbols, rng.normal(0.0, 3.0, len(symbols)))) for _ in range(length)]
        pairs = [{(a, b): rng.normal(0.0, 3.0) for a in symbols for b in symbols if rng.random() < 0.7}
                 for _ in range(length - 1)]

        def total(seq, scores=scores, pairs=pairs):
            return (grammar.log_probability(seq) + sum(s[c] for s, c in zip(scores, seq))
                    + sum(p.get((a, b), 0.0) for p, a, b in zip(pairs, seq, seq[1:])))

        best = max((list(seq) for seq in itertools.product(symbols, repeat=length)), key=total)
        decoded, score = grammar.decode(scores, pair_scores=pairs)
        assert decoded == best
        assert score == pytest.approx(total(best))


def test_decode_pair_scores_can_overturn_the_segment_scores():
    grammar = ActionGrammar().fit(PIECES + [["approach", "push-1", "push-3", "remove"],
                                            ["approach", "push-1", "push-2", "remove"]])
    # the third segment looks more like push-3 than push-2, by more than the grammar's preference
    scores = [{"approach": 0.0}, {"push-1": 0.0}, {"push-2": -6.0, "push-3": 0.0}, {"remove": 0.0}]
    assert grammar.decode(scores)[0] == ["approach", "push-1", "push-3", "remove"]
    # the effects the two pieces estimate do not join up as push-1 -> push-3: 10 nats against it
    pairs = [{}, {("push-1", "push-3"): -10.0, ("push-1", "push-2"): 0.0}, {}]
    decoded, total = grammar.decode(scores, pair_scores=pairs)
    assert decoded == ["approach", "push-1", "push-2", "remove"]
    assert total == pytest.approx(grammar.log_probability(decoded) - 6.0)


def test_decode_pair_scores_bad_input(grammar):
    scores = [{"approach": 0.0}, {"remove": 0.0}]
    with pytest.raises(InvalidInputError, match="one .* mapping per pair"):
        grammar.decode(scores, pair_scores=[])
    with pytest.raises(InvalidInputError, match="one .* mapping per pair"):
        grammar.decode(scores, pair_scores={("approach", "remove"): 0.0})
    with pytest.raises(InvalidInputError, match="must map"):
        grammar.decode(scores, pair_scores=[[0.0]])
    with pytest.raises(InvalidInputError, match="tuples"):
        grammar.decode(scores, pair_scores=[{"approach": 0.0}])
    with pytest.raises(InvalidInputError, match="finite or -inf"):
        grammar.decode(scores, pair_scores=[{("approach", "remove"): float("nan")}])


def test_decode_lets_the_grammar_separate_look_alike_pieces():
    grammar = ActionGrammar().fit(PIECES)
    pieces = ["push-1", "push-2", "push-3"]
    # every piece of the push looks most like the third piece; the move is far less likely
    look_alike = {"push-1": -10.0, "push-2": -10.0, "push-3": -9.5, "move": -40.0, "approach": -80.0, "remove": -80.0}
    first, last = {"approach": 0.0, "remove": -50.0}, {"remove": 0.0, "approach": -50.0}
    scores = [first, look_alike, look_alike, look_alike, last]
    isolated = [max(s, key=s.get) for s in scores]
    assert isolated[1:4] == ["push-3"] * 3
    decoded, _ = grammar.decode(scores)
    assert decoded == ["approach", *pieces, "remove"]


def test_decode_bad_input(grammar):
    with pytest.raises(InvalidInputError, match="non-empty list"):
        grammar.decode([])
    with pytest.raises(InvalidInputError, match="non-empty list"):
        grammar.decode({"approach": 0.0})
    with pytest.raises(InvalidInputError, match="must map classes"):
        grammar.decode([[0.0, 1.0]])
    with pytest.raises(InvalidInputError, match="finite or -inf"):
        grammar.decode([{"approach": float("nan")}])
    # the strict grammar has no two-class sequence: say so instead of returning a meaningless path
    with pytest.raises(InvalidInputError, match="smoothing > 0"):
        grammar.decode([{"approach": 0.0}, {"remove": 0.0}])
    assert ActionGrammar(smoothing=0.1).fit(DEMOS).decode([{"approach": 0.0}, {"remove": 0.0}])[0] == ["approach",
                                                                                                        "remove"]
    with pytest.raises(NotFittedError):
        ActionGrammar().decode([{"a": 0.0}])


def test_decode_unexplained_penalty_keeps_the_grammatical_path_through_an_unexplainable_segment():
    grammar = ActionGrammar().fit(PIECES + [["approach", "move", "remove"]])
    first, last = {"approach": 0.0}, {"remove": 0.0}
    # the second push piece is too short for its own model (-inf); the move explains it, poorly
    scores = [first, {"push-1": -5.0, "move": -20.0}, {"push-2": -np.inf, "move": -30.0},
              {"push-3": -5.0, "move": -40.0}, last]
    with pytest.raises(InvalidInputError, match="smoothing > 0"):
        grammar.decode(scores)  # no grammatical path has only finite scores: one move covers 3 segments nowhere
    decoded, total = grammar.decode(scores, unexplained_penalty=10.0)
    assert decoded == ["approach", "push-1", "push-2", "push-3", "remove"]
    # push-2 scored the segment's best finite score (-30) minus the penalty
    assert total == pytest.approx(grammar.log_probability(decoded) - 5.0 - 40.0 - 5.0)
    # the penalty enters the score of the path that uses it
    assert grammar.decode(scores, unexplained_penalty=1e4)[1] == pytest.approx(total - (1e4 - 10.0))


def test_decode_bonus_is_added_after_the_unexplained_penalty():
    grammar = ActionGrammar(smoothing=0.1).fit(PIECES + [["approach", "move", "remove"]])
    scores = [{"approach": 0.0}, {"push-1": -5.0, "move": -2.0}, {"remove": 0.0}]
    assert grammar.decode(scores)[0][1] == "move"
    # evidence for push-1 beyond its model's score: 10 nats outweigh the 3 it lost by
    decoded, total = grammar.decode(scores, bonus=[{}, {"push-1": 10.0}, {}])
    assert decoded[1] == "push-1"
    assert total == pytest.approx(grammar.log_probability(decoded) - 5.0 + 10.0)
    # a class whose model cannot explain the segment (-inf) gets the penalty's floor, then the bonus
    short = [{"approach": 0.0}, {"push-1": -np.inf, "move": -2.0}, {"remove": 0.0}]
    decoded, total = grammar.decode(short, unexplained_penalty=20.0, bonus=[{}, {"push-1": 30.0}, {}])
    assert decoded[1] == "push-1"
    assert total == pytest.approx(grammar.log_probability(decoded) - 2.0 - 20.0 + 30.0)
    assert grammar.decode(short, unexplained_penalty=20.0, bonus=[{}, {"push-1": 10.0}, {}])[0][1] == "move"
    for bad in ([{}], [{}, {"move": np.nan}, {}], [{}, {"move": "much"}, {}], {"move": 1.0}):
        with pytest.raises(InvalidInputError, match="bonus"):
            grammar.decode(scores, bonus=bad)


def test_decode_unexplained_penalty_prefers_explained_paths_and_lets_the_grammar_label_blank_segments():
    grammar = ActionGrammar().fit(PIECES)
    # the middle segment is explained by no class at all: the grammar alone labels it
    blank = {"push-1": -np.inf, "push-2": -np.inf, "push-3": -np.inf}
    scores = [{"approach": 0.0}, {"push-1": 0.0}, blank, {"push-3": 0.0}, {"remove": 0.0}]
    assert grammar.decode(scores, unexplained_penalty=50.0)[0] == ["approach", "push-1", "push-2", "push-3", "remove"]
    # scores without -inf are left alone: same path and score as without a penalty
    rng = np.random.default_rng(1)
    finite = [dict(zip(grammar.symbols_, rng.normal(0.0, 3.0, len(grammar.symbols_)))) for _ in range(5)]
    assert grammar.decode(finite, unexplained_penalty=0.0) == grammar.decode(finite)
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(InvalidInputError, match="unexplained_penalty"):
            grammar.decode(finite, unexplained_penalty=bad)
