"""Behaviour cloning: the MLP learns a known mapping, is deterministic, saves and loads exactly, refuses bad files."""

from __future__ import annotations

import io
import json

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.errors import DataExistsError, DataFileError, InvalidInputError, NotFittedError
from hoap_actions.policies.behaviour_cloning import (
    BehaviourCloning,
    BehaviourCloningPolicy,
    minari_transitions,
    state_vector,
)
from hoap_actions.policies.registry import policy_class

torch = pytest.importorskip("torch")

SMALL = {"hidden": (32,), "epochs": 40, "batch_size": 64, "learning_rate": 5e-3}


@pytest.fixture(scope="module")
def linear_data():
    """A known linear mapping from 6 inputs of mixed scales (one constant) to 3 actions."""
    rng = np.random.default_rng(0)
    X = rng.normal(size=(600, 6)) * [1.0, 0.01, 5.0, 0.1, 1.0, 0.0] + [0, 0.3, 0, -2, 0, 0.7]
    W = rng.normal(size=(6, 3))
    Y = (X - X.mean(0)) / np.maximum(X.std(0), 1e-3) @ W / 4
    return X, Y


@pytest.fixture(scope="module")
def fitted(linear_data):
    return BehaviourCloning(**SMALL, random_state=3).fit(*linear_data)


def test_it_learns_a_linear_mapping_to_a_small_error(fitted, linear_data):
    X, Y = linear_data
    rng = np.random.default_rng(1)
    test = X[rng.permutation(len(X))[:100]] + rng.normal(size=(100, 6)) * [0.1, 0.001, 0.5, 0.01, 0.1, 0.0]
    truth = (test - X.mean(0)) / np.maximum(X.std(0), 1e-3) @ np.linalg.lstsq(
        (X - X.mean(0)) / np.maximum(X.std(0), 1e-3), Y, rcond=None)[0]
    error = np.sqrt(np.mean((fitted.predict(test) - truth) ** 2))
    assert error < 0.05 * Y.std()  # relative RMS error under 5 %
    assert fitted.loss_curve_[-1] < 0.01 * fitted.loss_curve_[0]
    assert fitted.n_inputs_ == 6 and fitted.n_outputs_ == 3
    np.testing.assert_allclose(fitted.input_scale_[5], 1e-3)  # the constant input is centred, not blown up


def test_the_same_seed_gives_the_same_weights_bit_for_bit(linear_data, fitted):
    again = BehaviourCloning(**SMALL, random_state=3).fit(*linear_data)
    other = BehaviourCloning(**SMALL, random_state=4).fit(*linear_data)
    for (name, a), b, c in zip(fitted.network_.state_dict().items(), again.network_.state_dict().values(),
                               other.network_.state_dict().values()):
        assert torch.equal(a, b), name
        assert not torch.equal(a, c), name
    assert torch.get_num_threads() >= 1 and not torch.are_deterministic_algorithms_enabled()  # settings restored


def test_save_and_load_give_identical_actions(fitted, linear_data, tmp_path):
    path = tmp_path / "bc.pt"
    fitted.save(path)
    loaded = BehaviourCloning.load(path)
    assert loaded.get_params() == fitted.get_params()
    assert loaded.loss_curve_ == fitted.loss_curve_
    np.testing.assert_array_equal(loaded.predict(linear_data[0]), fitted.predict(linear_data[0]))
    with pytest.raises(DataExistsError):
        fitted.save(path)


def test_an_unfitted_model_says_so():
    model = BehaviourCloning()
    with pytest.raises(NotFittedError, match="not fitted"):
        model.predict(np.zeros((1, 3)))
    with pytest.raises(NotFittedError):
        model.save("never.pt")


@pytest.mark.parametrize("params", [{"hidden": (0,)}, {"hidden": "64"}, {"epochs": 0}, {"learning_rate": 0.0},
                                    {"weight_decay": -1.0}, {"normalise": 1}, {"random_state": -1},
                                    {"random_state": None}])
def test_bad_hyper_parameters_are_named(params):
    with pytest.raises(InvalidInputError, match=next(iter(params))):
        BehaviourCloning(**params).fit(np.zeros((4, 2)), np.zeros((4, 1)))


def test_bad_training_data_is_refused():
    with pytest.raises(InvalidInputError, match="one action per observation"):
        BehaviourCloning().fit(np.zeros((4, 2)), np.zeros((3, 1)))
    with pytest.raises(InvalidInputError, match="NaN"):
        BehaviourCloning().fit(np.full((4, 2), np.nan), np.zeros((4, 1)))
    with pytest.raises(InvalidInputError, match="2-D"):
        BehaviourCloning().fit(np.zeros(4), np.zeros((4, 1)))


def _rewrite(path, target, change):
    document = torch.load(path, weights_only=True)
    header = json.loads(document["header"])
    change(header, document["state_dict"])
    document["header"] = json.dumps(header)
    torch.save(document, target)
    return target


@pytest.mark.parametrize("change, message", [
    (lambda h, t: h.update(kind="ActionModels"), "not a BehaviourCloning file"),
    (lambda h, t: h.update(format_version=99), "format_version 99"),
    (lambda h, t: h.update(n_inputs=7), "do not match"),
    (lambda h, t: h["params"].update(hidden=[16]), "do not match"),
    (lambda h, t: h.pop("loss_curve"), "header"),
    (lambda h, t: t.pop("input_scale"), "do not match"),
    (lambda h, t: t["input_scale"].zero_(), "positive"),
    (lambda h, t: t["network.0.weight"].fill_(float("nan")), "finite"),
])
def test_bad_files_are_refused(fitted, tmp_path, change, message):
    fitted.save(tmp_path / "good.pt")
    bad = _rewrite(tmp_path / "good.pt", tmp_path / "bad.pt", change)
    with pytest.raises(DataFileError, match=message):
        BehaviourCloning.load(bad)


def test_files_that_are_not_models_are_refused(tmp_path):
    (tmp_path / "text.pt").write_text("not a model")
    with pytest.raises(DataFileError, match="not a readable"):
        BehaviourCloning.load(tmp_path / "text.pt")
    buffer = io.BytesIO()
    torch.save({"weights": torch.zeros(2)}, buffer)
    (tmp_path / "other.pt").write_bytes(buffer.getvalue())
    with pytest.raises(DataFileError):
        BehaviourCloning.load(tmp_path / "other.pt")
    with pytest.raises(DataFileError, match="no BehaviourCloning file"):
        BehaviourCloning.load(tmp_path / "missing.pt")


def test_the_policy_acts_in_the_env_with_clipped_actions():
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta", robot="fixed_legs")
    try:
        obs, info = env.reset(seed=0)
        X = np.repeat(state_vector(obs)[None], 8, axis=0) + np.random.default_rng(0).normal(size=(8, len(
            state_vector(obs))))
        model = BehaviourCloning(hidden=(8,), epochs=2).fit(X, np.full((8, 4), 3.0))  # actions beyond the box
        assert policy_class("bc", "hoap_actions/Reach-v1") is BehaviourCloningPolicy
        policy = BehaviourCloningPolicy(env, model)
        policy.reset(obs, info)
        action = policy(obs)
        assert action.dtype == np.float32 and env.action_space.contains(action)
        np.testing.assert_array_equal(action, policy(obs))
        env.step(action)
        with pytest.raises(InvalidInputError, match="inputs"):
            BehaviourCloningPolicy(env, BehaviourCloning(hidden=(8,), epochs=1).fit(X[:, :5], np.zeros((8, 4))))
    finally:
        env.close()


def test_minari_episodes_become_observation_action_pairs(tmp_path, monkeypatch):
    minari = pytest.importorskip("minari")
    from hoap_actions.apps.collect import collect

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    collect("hoap_actions/Reach-v1", "straight", 2, 5, "hoap_actions/Reach/straight-v0", robot="fixed_legs")
    X, Y, lengths = minari_transitions(["hoap_actions/Reach/straight-v0"])
    dataset = minari.load_dataset("hoap_actions/Reach/straight-v0")
    episodes = list(dataset.iterate_episodes())
    assert list(lengths) == [len(e.actions) for e in episodes] and len(X) == len(Y) == sum(lengths)
    np.testing.assert_array_equal(Y[: lengths[0]], episodes[0].actions)
    first = episodes[1].observations
    np.testing.assert_array_equal(X[lengths[0]], np.r_[first["observation"][0], first["desired_goal"][0]])
    assert len(minari_transitions([dataset], episodes=1)[0]) == lengths[0]
    with pytest.raises(InvalidInputError, match="hold 2"):
        minari_transitions([dataset], episodes=3)
