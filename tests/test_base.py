"""The estimator base: parameters from ``__init__``, one fitted check, the shared save/load checks."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest

from hoap_actions.errors import DataFileError, InvalidInputError, NotFittedError
from hoap_actions.primitives.base import Estimator, check_is_fitted, file_params
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM
from hoap_actions.primitives.hmm.posture import PostureModel
from hoap_actions.primitives.models.action_models import ActionModels

ESTIMATORS = [
    PrimitiveDiscovery(spacing=0.02, threshold=2.0, reg_covar=1e-5, rotation_radius=0.1, hand_marker=3,
                       random_state=7),
    ParametricHMM(n_states=3, topology="left-right-skip", covariance_type="diag", n_iter=5, tol=0.1,
                  reg_covar=1e-4, random_state=2, covars_prior=[0.5, 0.5], covars_weight=2.0),
    ActionGrammar(smoothing=0.25),
    PostureModel(degree=2, alpha=0.5),
    ActionModels(max_states=7, progress=True),
]
BAD_VALUE = {"PrimitiveDiscovery": ("spacing", -1.0), "ParametricHMM": ("n_states", 0),
             "ActionGrammar": ("smoothing", -1.0), "PostureModel": ("alpha", -1.0), "ActionModels": ("max_states", 0)}


@pytest.mark.parametrize("estimator", ESTIMATORS, ids=lambda e: type(e).__name__)
def test_get_params_round_trips_through_init(estimator):
    params = estimator.get_params()
    assert list(params) == list(inspect.signature(type(estimator)).parameters)
    copy = type(estimator)(**params)
    assert copy.get_params() == params and copy is not estimator
    assert repr(copy) == repr(estimator)


def test_repr_lists_every_hyper_parameter_in_init_order():
    assert repr(ActionGrammar(smoothing=0.25)) == "ActionGrammar(smoothing=0.25)"
    assert repr(PrimitiveDiscovery()) == ("PrimitiveDiscovery(spacing=0.03, threshold=3.0, reg_covar=None, "
                                          "rotation_radius=0.05, hand_marker=2, merging='agglomerative', "
                                          "random_state=None)")
    assert repr(ParametricHMM(n_states=4)).startswith("ParametricHMM(n_states=4, topology='left-right', ")


def test_file_params_are_json_ready():
    model = PrimitiveDiscovery(hand_marker=np.int64(1), spacing=np.float32(0.5), random_state=np.random.default_rng())
    params = file_params(model)
    assert params["hand_marker"] == 1 and type(params["hand_marker"]) is int
    assert type(params["spacing"]) is float and params["random_state"] is None
    json.dumps(params)
    assert isinstance(model.get_params()["random_state"], np.random.Generator)  # get_params gives what was given


@pytest.mark.parametrize(
    "estimator, use",
    [
        (PrimitiveDiscovery(), lambda m: m.predict(np.zeros((5, 6)), [5])),
        (ParametricHMM(), lambda m: m.estimate_phi(np.zeros((20, 2)))),
        (ActionGrammar(), lambda m: m.next_distribution()),
    ],
    ids=["PrimitiveDiscovery", "ParametricHMM", "ActionGrammar"],
)
def test_an_unfitted_estimator_says_which_it_is_and_what_to_call(estimator, use, tmp_path):
    name = type(estimator).__name__
    expected = f"this {name} is not fitted yet: call fit\\(\\) or {name}.load\\(path\\) first"
    for call in (use, lambda m: m.save(tmp_path / "never"), check_is_fitted):
        with pytest.raises(NotFittedError, match=expected):
            call(estimator)
    assert not (tmp_path / "never").exists()


def test_check_is_fitted_takes_named_attributes():
    grammar = ActionGrammar().fit([["a", "b"]])
    check_is_fitted(grammar)
    check_is_fitted(grammar, "transmat_")
    check_is_fitted(grammar, ["symbols_", "counts_"])
    with pytest.raises(NotFittedError, match="ActionGrammar"):
        check_is_fitted(grammar, ["symbols_", "missing_"])


def test_load_checks_kind_and_format_version_for_every_estimator(tmp_path):
    grammar = ActionGrammar().fit([["a", "b"]])
    grammar.save(tmp_path / "grammar.json")
    with pytest.raises(DataFileError, match="is not a PrimitiveDiscovery file \\(its kind is 'ActionGrammar'\\)"):
        PrimitiveDiscovery.load(tmp_path / "grammar.json")
    document = json.loads((tmp_path / "grammar.json").read_text())
    for version in (2, "1", True, None):
        (tmp_path / "other.json").write_text(json.dumps({**document, "format_version": version}))
        with pytest.raises(DataFileError, match=f"format_version {version!r}; .* reads ActionGrammar format_versions"):
            ActionGrammar.load(tmp_path / "other.json")
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(DataFileError, match="not an object"):
        ActionGrammar.load(tmp_path / "list.json")
    assert ActionGrammar.load(tmp_path / "grammar.json").symbols_ == ["a", "b"]


def test_subclasses_supply_the_format():
    class Partial(Estimator):
        def __init__(self, a: int = 1) -> None:
            self.a = a

    with pytest.raises(TypeError, match="abstract"):
        Partial()


@pytest.mark.parametrize("estimator", ESTIMATORS, ids=lambda e: type(e).__name__)
def test_set_params_checks_every_value_and_changes_nothing_on_an_error(estimator):
    fresh = type(estimator)(**estimator.get_params())
    name, bad = BAD_VALUE[type(fresh).__name__]
    before = fresh.get_params()
    with pytest.raises(InvalidInputError, match=name):
        fresh.set_params(**{name: bad})
    assert fresh.get_params() == before
    with pytest.raises(InvalidInputError, match="no hyper-parameter"):
        fresh.set_params(no_such_parameter=1)
    good = {name: type(fresh)().get_params()[name]}
    assert fresh.set_params(**good) is fresh and fresh.get_params()[name] == good[name]


def test_a_fitted_estimator_takes_only_what_it_reads_after_fit():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(40, 2))
    model = ParametricHMM(n_states=2, n_iter=3, random_state=0).fit(X, [10, 10, 10, 10], np.arange(4.0)[:, None])
    assert model.set_params(random_state=1).random_state == 1
    with pytest.raises(InvalidInputError, match="fit a new one to change \\['n_states'\\]"):
        model.set_params(n_states=3)


def test_fit_takes_one_sequence_when_lengths_is_none():
    X = np.random.default_rng(1).normal(size=(30, 2))
    one = ParametricHMM(n_states=2, n_iter=3, random_state=0).fit(X, None, np.zeros((1, 0)))
    again = ParametricHMM(n_states=2, n_iter=3, random_state=0).fit(X, [30], np.zeros((1, 0)))
    np.testing.assert_array_equal(one.mean_bar_, again.mean_bar_)
    with pytest.raises(InvalidInputError, match="effects phi"):
        ParametricHMM(n_states=2).fit(X)


def test_the_grammar_takes_concatenated_classes_with_lengths():
    a = ActionGrammar().fit([[1, 2, 3], [1, 3]])
    b = ActionGrammar().fit([1, 2, 3, 1, 3], [3, 2])
    np.testing.assert_array_equal(a.transmat_, b.transmat_)
    with pytest.raises(InvalidInputError, match="lengths"):
        ActionGrammar().fit([1, 2, 3], [2, 2])
