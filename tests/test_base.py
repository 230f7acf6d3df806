"""The estimator base: parameters from ``__init__``, one fitted check, the shared save/load checks."""

from __future__ import annotations

import inspect
import json

import numpy as np
import pytest

from hoap_actions.errors import DataFileError, NotFittedError
from hoap_actions.primitives.base import Estimator, check_is_fitted, file_params
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.discovery.grammar import ActionGrammar
from hoap_actions.primitives.hmm.parametric_hmm import ParametricHMM

ESTIMATORS = [
    PrimitiveDiscovery(spacing=0.02, threshold=2.0, reg_covar=1e-5, rotation_radius=0.1, hand_marker=3,
                       random_state=7),
    ParametricHMM(n_states=3, topology="left-right-skip", covariance_type="diag", n_iter=5, tol=0.1,
                  reg_covar=1e-4, random_state=2, covars_prior=[0.5, 0.5], covars_weight=2.0),
    ActionGrammar(smoothing=0.25),
]


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
                                          "rotation_radius=0.05, hand_marker=2, merging='agglomerative', random_state=None)")
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
