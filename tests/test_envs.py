"""The Gymnasium contract of every registered environment: API, determinism, vectorisation, bad input."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hoap_actions
from hoap_actions.errors import EnvClosedError


@pytest.fixture(params=hoap_actions.ENV_IDS)
def env_id(request):
    return request.param


def rollout(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    observations = [obs]
    for action in actions:
        obs, *_ = env.step(action)
        observations.append(obs)
    return observations


def same(obs_a, obs_b):
    return all(np.array_equal(a[k], b[k]) for a, b in zip(obs_a, obs_b) for k in a)


def test_ids_are_namespaced_and_registered():
    assert len(hoap_actions.ENV_IDS) >= 2
    for env_id in hoap_actions.ENV_IDS:
        assert env_id.startswith("hoap_actions/")
        assert env_id in gymnasium.registry


def test_check_env_passes(env_id):
    env = gymnasium.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_reset_and_step_follow_the_api(env_id):
    env = gymnasium.make(env_id, render_mode="rgb_array", render_width=96, render_height=64)
    obs, info = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    assert isinstance(info["is_success"], bool)
    for _ in range(5):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        assert isinstance(reward, float) and isinstance(terminated, bool) and isinstance(truncated, bool)
        assert "is_success" in info
    frame = env.render()
    assert frame.shape == (64, 96, 3) and frame.dtype == np.uint8
    assert frame.std() > 0, "the rendered frame is blank"
    assert env.metadata["render_fps"] == 30
    env.close()


def test_same_seed_same_actions_fresh_or_reused(env_id):
    fresh = gymnasium.make(env_id)
    actions = np.random.default_rng(0).uniform(-1, 1, size=(100, *fresh.action_space.shape))
    reference = rollout(fresh, 11, actions)
    reused = gymnasium.make(env_id)
    reused.reset(seed=5)
    for _ in range(200):
        reused.step(reused.action_space.sample())
    assert same(reference, rollout(reused, 11, actions))
    assert not same(reference, rollout(reused, 12, actions)), "a different seed should give a different episode"
    fresh.close()
    reused.close()


def test_envs_in_one_process_are_independent(env_id):
    a, b = gymnasium.make(env_id), gymnasium.make(env_id)
    actions = np.random.default_rng(1).uniform(-1, 1, size=(20, *a.action_space.shape))
    alone = rollout(a, 7, actions)
    a.reset(seed=7)
    b.reset(seed=99)
    interleaved = [a.reset(seed=7)[0]]
    for action in actions:
        b.step(-action)
        interleaved.append(a.step(action)[0])
    assert same(alone, interleaved)
    a.close()
    b.close()


@pytest.mark.parametrize("mode", ["sync", "async"])
def test_make_vec(mode):
    envs = gymnasium.make_vec("hoap_actions/Reach-v1", num_envs=2, vectorization_mode=mode)
    obs, info = envs.reset(seed=[1, 2])
    assert obs["observation"].shape[0] == 2
    assert not np.array_equal(obs["desired_goal"][0], obs["desired_goal"][1])
    obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    assert reward.shape == (2,)
    envs.close()


def test_bad_actions_raise_value_error():
    env = gymnasium.make("hoap_actions/PegInsert-v0")
    env.reset(seed=0)
    shape = env.action_space.shape
    with pytest.raises(ValueError, match=r"has shape \(8,\).*array of 7 finite numbers"):
        env.step(np.zeros(shape[0] + 1))
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.full(shape, np.nan))
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.full(shape, np.inf))
    env.close()


def test_unknown_keyword_names_the_accepted_ones():
    with pytest.raises(TypeError, match="accepted:.*control_mode"):
        gymnasium.make("hoap_actions/PegInsert-v0", colour="red")


def test_bad_constructor_values_are_explained():
    with pytest.raises(ValueError, match="accepted"):
        gymnasium.make("hoap_actions/PegInsert-v0", control_mode="torque")
    with pytest.raises(ValueError, match="accepted"):
        gymnasium.make("hoap_actions/PegInsert-v0", camera="ceiling")


def test_unknown_env_id_is_a_clear_error():
    with pytest.raises(gymnasium.error.Error, match="PegInsrt"):
        gymnasium.make("hoap_actions/PegInsrt-v0")


def test_closed_env_raises_and_close_twice_is_harmless():
    env = gymnasium.make("hoap_actions/Reach-v1")
    env.reset(seed=0)
    env.close()
    env.close()
    with pytest.raises(EnvClosedError):
        env.step(env.action_space.sample())
    with pytest.raises(EnvClosedError):
        env.reset(seed=0)
