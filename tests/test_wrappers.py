"""The RL wrappers: SelectObservation keeps the env's own named fields with the goal API untouched;
ResidualAction adds a (scaled) learner's action to a base policy's; RepeatAction holds a decision for K steps."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.envs.wrappers import SelectObservation
from hoap_actions.errors import InvalidInputError

FIELDS = ["tcp_position", "target", "peg_positions", "hole_positions"]


@pytest.fixture
def reach():
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta")
    yield env
    env.close()


def test_kept_fields_are_the_parsed_fields_in_the_given_order(reach):
    full_obs, _ = reach.reset(seed=3)
    full = reach.unwrapped.parse_observation(full_obs)
    wrapped = SelectObservation(reach, FIELDS)
    obs, _ = wrapped.reset(seed=3)  # same seed, same episode
    expected = np.concatenate([np.ravel(full[name]) for name in FIELDS]).astype(np.float32)
    np.testing.assert_array_equal(obs["observation"], expected)
    assert wrapped.observation_space["observation"].shape == (3 + 3 + 9 + 9,)
    np.testing.assert_array_equal(obs["desired_goal"], full["desired_goal"].astype(np.float32))
    obs, *_ = wrapped.step(np.array([1.0, 0.0, 0.0, 0.0], dtype=np.float32))
    assert wrapped.observation_space.contains(obs)


def test_rewards_and_episodes_are_those_of_the_inner_env():
    actions = np.random.default_rng(0).uniform(-1, 1, (12, 4)).astype(np.float32)
    runs = []
    for wrap in (False, True):
        env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta")
        env = SelectObservation(env, FIELDS) if wrap else env
        obs, _ = env.reset(seed=11)
        trace = [obs["achieved_goal"]]
        for action in actions:
            obs, reward, *_ = env.step(action)
            trace += [obs["achieved_goal"], [reward]]
        runs.append(np.concatenate(trace))
        env.close()
    np.testing.assert_array_equal(runs[0], runs[1])


def test_compute_reward_is_forwarded_for_goal_batches(reach):
    wrapped = SelectObservation(reach, FIELDS)
    achieved = np.zeros((2, 3))
    desired = np.array([[0.0, 0.0, 0.005], [0.0, 0.0, 0.5]])
    np.testing.assert_array_equal(wrapped.compute_reward(achieved, desired, [{}, {}]), [0.0, -1.0])


def test_gymnasium_checker_passes_on_the_wrapper(reach):
    check_env(SelectObservation(reach, FIELDS), skip_render_check=True)


def test_sb3_checker_passes_on_the_wrapper(reach):
    """SB3's checker calls compute_reward on the object it is given: the wrapper itself, not env.unwrapped."""
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3_checker.check_env(SelectObservation(reach, FIELDS), warn=False)


@pytest.mark.parametrize("fields", [[], ["tcp_position", "tcp_position"], ["elbow"], ["desired_goal"]])
def test_bad_fields_name_the_accepted_ones(reach, fields):
    with pytest.raises(InvalidInputError, match="accepted: .*tcp_position"):
        SelectObservation(reach, fields)


# ------------------------------------------------------------------------------------------ residual actions
def test_a_zero_residual_replays_the_base_policy_bit_for_bit():
    from hoap_actions.envs.wrappers import ResidualAction
    from hoap_actions.policies.registry import StraightReach

    traces = []
    for residual in (False, True):
        env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta")
        base = StraightReach(env)
        env = ResidualAction(env, base) if residual else env
        obs, _ = env.reset(seed=5)
        trace = [obs["achieved_goal"]]
        for _ in range(15):
            obs, reward, *_ = env.step(np.zeros(4, np.float32) if residual else base(obs))
            trace += [obs["achieved_goal"], [reward]]
        traces.append(np.concatenate(trace))
        env.close()
    np.testing.assert_array_equal(traces[0], traces[1])


def test_the_sum_is_clipped_and_step_needs_a_reset(reach):
    from hoap_actions.envs.wrappers import ResidualAction

    sent = []

    class Recorder(gymnasium.Wrapper):
        def step(self, action):
            sent.append(np.array(action))
            return self.env.step(action)

    wrapped = ResidualAction(Recorder(reach), lambda obs: np.array([0.75, -0.75, 0.0, -1.0]))
    with pytest.raises(InvalidInputError, match="before reset"):
        wrapped.step(np.zeros(4, np.float32))
    wrapped.reset(seed=0)
    with pytest.raises(InvalidInputError, match=r"action space's shape \(4,\)"):
        wrapped.step(np.zeros(3, np.float32))
    assert not sent  # refused before the env saw it
    wrapped.step(np.array([0.5, -0.5, 0.25, 0.5], np.float32))
    np.testing.assert_allclose(sent[0], [1.0, -1.0, 0.25, -0.5])
    np.testing.assert_array_equal(wrapped.compute_reward(np.zeros(3), np.zeros(3), {}), 0.0)


def test_a_scaled_residual_adds_that_share_of_the_learners_action(reach):
    from hoap_actions.envs.wrappers import ResidualAction

    sent = []

    class Recorder(gymnasium.Wrapper):
        def step(self, action):
            sent.append(np.array(action))
            return self.env.step(action)

    wrapped = ResidualAction(Recorder(reach), lambda obs: np.array([0.5, -0.5, 0.0, 0.0]), scale=0.25)
    wrapped.reset(seed=0)
    wrapped.step(np.array([1.0, 1.0, -1.0, 0.5], np.float32))
    np.testing.assert_allclose(sent[0], [0.75, -0.25, -0.25, 0.125])
    for scale in (0.0, -1.0, float("nan")):
        with pytest.raises(InvalidInputError, match="positive finite"):
            ResidualAction(reach, lambda obs: np.zeros(4), scale=scale)


# ------------------------------------------------------------------------------------------ repeated actions
def test_a_repeated_action_is_the_same_as_stepping_it_repeatedly():
    from hoap_actions.envs.wrappers import RepeatAction

    action = np.array([0.6, -0.3, 0.4, 0.0], np.float32)
    plain = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta")
    repeated = RepeatAction(gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta"), 3)
    plain.reset(seed=4)
    repeated.reset(seed=4)
    for _ in range(2):
        for _ in range(3):
            expected = plain.step(action)
        got = repeated.step(action)
        for key in expected[0]:
            np.testing.assert_array_equal(got[0][key], expected[0][key])
        assert got[1:4] == expected[1:4]
        # the reward returned is the one HER recomputes from the returned achieved goal
        assert got[1] == repeated.compute_reward(got[0]["achieved_goal"], got[0]["desired_goal"], got[4])
    plain.close()
    repeated.close()


def test_a_repeat_stops_when_the_episode_ends():
    from hoap_actions.envs.wrappers import RepeatAction

    env = RepeatAction(gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta", max_episode_steps=5), 3)
    env.reset(seed=0)
    assert not any(env.step(np.zeros(4, np.float32))[2:4])
    *_, terminated, truncated, _ = env.step(np.zeros(4, np.float32))  # steps 4 and 5 of 5, not 6
    assert truncated and not terminated
    for repeat in (0, 1.5, True, -2):
        with pytest.raises(InvalidInputError, match="whole number"):
            RepeatAction(env, repeat)
    env.close()
