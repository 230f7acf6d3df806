"""The hybrid vector env against Gymnasium's own SyncVectorEnv: the same episodes, batched the same way."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs.vector import HybridVectorEnv, make_hybrid
from hoap_actions.errors import EnvClosedError, InvalidInputError

ENV_ID = "hoap_actions/Reach-v1"
EPISODE_STEPS = 4  # short episodes, so that the run crosses autoresets


def _run(envs, seed: int, actions: np.ndarray) -> list:
    out = [envs.reset(seed=seed)]
    out += [envs.step(action) for action in actions]
    envs.close()
    return out


def _same(a, b) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            _same(a[key], b[key])
    elif isinstance(a, tuple | list):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    else:
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("num_envs, spin_s", [(2, None), (2, 0.0), (3, 0.002)])
def test_steps_as_gymnasiums_sync_vector_env(num_envs, spin_s):
    """Every observation, reward, flag and info bit for bit as SyncVectorEnv's, autoresets included,
    whether the two sides busy-wait for each other or sleep."""
    kwargs = {"control_mode": "ee_delta", "max_episode_steps": EPISODE_STEPS}
    actions = np.random.default_rng(3).uniform(-1, 1, (3 * EPISODE_STEPS, num_envs, 4)).astype(np.float32)
    sync = _run(gymnasium.make_vec(ENV_ID, num_envs=num_envs, vectorization_mode="sync", **kwargs), 11, actions)
    hybrid = _run(make_hybrid(ENV_ID, num_envs, vector_kwargs={"spin_s": spin_s}, **kwargs), 11, actions)
    assert any(step[3].any() for step in sync[1:])  # the time limit ended episodes on the way
    _same(hybrid, sync)


def test_attributes_and_calls_reach_every_sub_env():
    envs = make_hybrid(ENV_ID, 2, control_mode="ee_delta")
    envs.reset(seed=[5, 9])
    assert envs.get_attr("control_mode") == ("ee_delta", "ee_delta")
    fields = envs.call("parse_observation", envs.single_observation_space.sample())
    assert len(fields) == 2 and fields[0].keys() == fields[1].keys()
    envs.close()


def test_one_sub_env_or_a_wrong_seed_count_is_refused():
    with pytest.raises(InvalidInputError, match="at least 2 sub-envs"):
        HybridVectorEnv([lambda: gymnasium.make(ENV_ID)])
    for bad in (1, 2.0, True):
        with pytest.raises(InvalidInputError, match="whole number >= 2"):
            make_hybrid(ENV_ID, bad)
    envs = make_hybrid(ENV_ID, 2)
    with pytest.raises(InvalidInputError, match="one seed per sub-env"):
        envs.reset(seed=[1, 2, 3])
    envs.close()


def test_bad_actions_are_refused_before_any_sub_env_steps():
    envs = make_hybrid(ENV_ID, 2, control_mode="ee_delta")
    envs.reset(seed=1)
    good = np.zeros((2, 4), dtype=np.float32)
    bad = good.copy()
    bad[1, 0] = np.nan
    with pytest.raises(InvalidInputError, match="finite numbers, one row per sub-env"):
        envs.step(bad)
    with pytest.raises(InvalidInputError, match="got shape \\(3, 4\\)"):
        envs.step(np.zeros((3, 4)))
    obs, reward, *_ = envs.step(good)  # still usable
    assert reward.shape == (2,)
    envs.close()


def test_a_sub_envs_error_reaches_the_caller_and_the_env_goes_on():
    envs = make_hybrid(ENV_ID, 2, control_mode="ee_delta")
    envs.reset(seed=2)
    with pytest.raises(AttributeError, match="no_such_attribute"):
        envs.get_attr("no_such_attribute")
    obs, reward, *_ = envs.step(np.zeros((2, 4), dtype=np.float32))  # both sides still in step
    assert reward.shape == (2,) and obs["observation"].shape[0] == 2
    worker = envs.remote._links[0].process
    envs.close()
    assert worker.exitcode == 0  # the worker let go of its shared memory and ended cleanly


def test_a_dead_worker_is_reported_not_waited_for():
    envs = make_hybrid(ENV_ID, 2)
    envs.reset(seed=4)
    worker = envs.remote._links[0].process
    worker.kill()
    worker.join()
    with pytest.raises(EnvClosedError, match="worker process ended"):
        envs.step(np.zeros(envs.action_space.shape, dtype=np.float32))
    envs.close()


@pytest.mark.parametrize("spin_s", [-0.001, 1.0, "fast", float("nan")])
def test_a_bad_busy_wait_is_refused(spin_s):
    with pytest.raises(InvalidInputError, match="spin_s"):
        make_hybrid(ENV_ID, 2, vector_kwargs={"spin_s": spin_s})
