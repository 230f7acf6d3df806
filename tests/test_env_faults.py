"""Faults an env meets on a real machine: copies that would share its physics client, and a reset cut
short by Ctrl-C (the interrupt is raised inside the world's rebuild, at several points)."""

from __future__ import annotations

import copy
import pickle

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.errors import EnvCopyError, InvalidInputError, ResetNeededError


@pytest.fixture
def env():
    made = gymnasium.make("hoap_actions/PegInsert-v0")
    yield made
    made.close()


@pytest.mark.parametrize("copier", [copy.deepcopy, pickle.dumps], ids=["deepcopy", "pickle"])
@pytest.mark.parametrize("unwrap", [False, True], ids=["wrapped", "unwrapped"])
def test_a_copy_is_refused_and_the_env_goes_on(env, copier, unwrap):
    env.reset(seed=1)
    with pytest.raises(EnvCopyError, match="gymnasium.make"):
        copier(env.unwrapped if unwrap else env)
    env.step(env.action_space.sample())  # the original still owns a working client


def test_a_shallow_copy_of_a_wrapper_is_the_same_env_and_of_the_env_is_refused(env):
    assert copy.copy(env).unwrapped is env.unwrapped  # a second view of one env, not a second client
    with pytest.raises(EnvCopyError):
        copy.copy(env.unwrapped)


def test_step_before_any_reset_is_refused():
    env = gymnasium.make("hoap_actions/PegInsert-v0", disable_env_checker=True).unwrapped
    try:
        with pytest.raises(ResetNeededError, match="reset"):
            env.step(np.zeros(env.action_space.shape))
    finally:
        env.close()


def _episode(env, seed, steps=5):
    obs, _ = env.reset(seed=seed)
    out = [obs["observation"]]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        obs, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        out.append(obs["observation"])
    return np.array(out)


@pytest.mark.parametrize("calls_before", [0, 3, 9])
def test_an_interrupted_reset_needs_a_reset_and_changes_no_episode(env, calls_before):
    reference = _episode(env, seed=7)
    sim = env.unwrapped.sim
    original = sim.set_color
    count = {"n": 0}

    def interrupted(*args, **kwargs):
        count["n"] += 1
        if count["n"] == calls_before + 1:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    sim.set_color = interrupted
    try:
        with pytest.raises(KeyboardInterrupt):
            for _ in range(calls_before + 1):  # rebuilds call set_color a few times each
                env.reset(seed=3)
    finally:
        del sim.set_color
    with pytest.raises(ResetNeededError):
        env.step(env.action_space.sample())
    np.testing.assert_array_equal(_episode(env, seed=7), reference)


@pytest.mark.parametrize("make_action", [
    lambda n: np.zeros(n, complex),
    lambda n: ["0.1"] * n,
    lambda n: np.zeros(n, bool),
    lambda n: np.ma.masked_array(np.zeros(n), mask=[True] + [False] * (n - 1)),
], ids=["complex", "numeric-strings", "booleans", "masked"])
def test_actions_that_are_not_real_numbers_are_refused(env, make_action):
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match="action"):
        env.step(make_action(env.action_space.shape[0]))


@pytest.mark.parametrize("kwargs, message", [
    ({"seed": 2**63}, "outside 0"), ({"seed": -1}, "outside 0"), ({"options": {"layout": 3}}, "no options"),
])
def test_reset_refuses_what_it_cannot_honour(env, kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        env.reset(**kwargs)


def test_compute_reward_refuses_goals_of_another_width(env):
    env.reset(seed=0)
    with pytest.raises(InvalidInputError, match="goal width 3"):
        env.unwrapped.compute_reward(np.zeros(2), np.zeros(2), None)
    assert env.unwrapped.compute_reward(np.zeros((4, 3)), np.zeros((4, 3)), None).shape == (4,)
