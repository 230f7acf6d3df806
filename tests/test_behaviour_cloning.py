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
    _chunks,
    _episode_ends,
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


def test_a_cosine_schedule_comes_to_rest(linear_data, fitted):
    cosine = BehaviourCloning(**SMALL, schedule="cosine", random_state=3).fit(*linear_data)
    assert cosine.loss_curve_[-1] < 0.01 * cosine.loss_curve_[0]
    assert abs(cosine.loss_curve_[-1] - cosine.loss_curve_[-2]) < 1e-3 * cosine.loss_curve_[-1]  # step size near 0
    assert abs(cosine.loss_curve_[-1] - cosine.loss_curve_[-2]) < abs(fitted.loss_curve_[-1] - fitted.loss_curve_[-2])


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


@pytest.mark.parametrize("params", [
    {"hidden": (0,)}, {"hidden": "64"}, {"epochs": 0}, {"learning_rate": 0.0}, {"weight_decay": -1.0},
    {"schedule": "step"}, {"normalise": 1}, {"random_state": -1}, {"random_state": None},
])
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


def _constant(action: list[float], n_inputs: int, chunk: int = 1) -> BehaviourCloning:
    """A fitted model whose output is exactly ``action`` (``chunk`` of them; last layer's weights zeroed)."""
    model = BehaviourCloning(hidden=(4,), epochs=1, chunk=chunk).fit(np.eye(n_inputs)[:2], np.zeros((2, 4)))
    with torch.no_grad():
        model.network_[-1].weight.zero_()
        model.network_[-1].bias.copy_(torch.tensor(action))
    return model


def test_a_policy_whose_robot_stands_still_gives_up():
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta", robot="fixed_legs")
    try:
        n = len(state_vector(env.reset(seed=1)[0]))
        ended = {}
        for name, action in (("still", [0.0, 0.0, 0.0, 0.0]), ("moving", [0.0, 0.0, 1.0, 0.0])):
            policy = BehaviourCloningPolicy(env, _constant(action, n), patience=10)
            obs, info = env.reset(seed=1)
            policy.reset(obs, info)
            steps = 0
            while not policy.failure and steps < 80:
                obs, *_ = env.step(policy(obs))
                steps += 1
            ended[name] = (policy.failure, steps)
        assert ended["still"][0] == "stalled" and ended["still"][1] < 60  # the arm settles in ~35 steps
        assert ended["moving"][0] == "stalled" and ended["moving"][1] > 20  # up 13 steps to the box's top, then still
        with pytest.raises(InvalidInputError, match="patience"):
            BehaviourCloningPolicy(env, _constant([0.0] * 4, n), patience=0)
    finally:
        env.close()


def test_chunks_hold_the_next_actions_of_the_same_episode():
    actions = np.array([[0.0], [1.0], [2.0], [10.0], [11.0]])
    chunks = _chunks(actions, _episode_ends([3, 2], 5), 3)
    np.testing.assert_array_equal(chunks, [[0, 1, 2], [1, 2, 2], [2, 2, 2], [10, 11, 11], [11, 11, 11]])
    np.testing.assert_array_equal(_chunks(actions, _episode_ends(None, 5), 2)[2:], [[2, 10], [10, 11], [11, 11]])
    with pytest.raises(InvalidInputError, match="lengths"):
        BehaviourCloning(chunk=2).fit(np.zeros((5, 2)), actions, lengths=[3, 3])


def test_a_chunked_model_round_trips_and_its_policy_averages_the_predictions_for_each_step(linear_data, tmp_path):
    X, Y = linear_data
    model = BehaviourCloning(**SMALL, chunk=3).fit(X, Y, lengths=[300, 300])
    assert model.n_outputs_ == 3 and model.predict_chunks(X[:5]).shape == (5, 3, 3)
    np.testing.assert_array_equal(model.predict(X[:5]), model.predict_chunks(X[:5])[:, 0])
    model.save(tmp_path / "chunked.pt")
    loaded = BehaviourCloning.load(tmp_path / "chunked.pt")
    np.testing.assert_array_equal(loaded.predict_chunks(X), model.predict_chunks(X))
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta", robot="fixed_legs")
    try:
        obs, info = env.reset(seed=1)
        first, second = [0.2, 0.0, 0.0, 0.0], [0.6, 0.0, -0.4, 0.0]
        policy = BehaviourCloningPolicy(env, _constant(first + second, len(state_vector(obs)), chunk=2))
        policy.reset(obs, info)
        np.testing.assert_allclose(policy(obs), first)  # nothing predicted for this step before
        np.testing.assert_allclose(policy(obs), [0.4, 0.0, -0.2, 0.0], atol=1e-7)  # mean of first and second
        policy.reset(obs, info)
        np.testing.assert_allclose(policy(obs), first)
    finally:
        env.close()
