"""The PHMM policy: grasp-and-insert from the camera and the learned models, blind to the simulator's poses."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import compare_policies, run_episode, wilson_interval
from hoap_actions.errors import HoapActionsError, InvalidInputError
from hoap_actions.policies.phmm_policy import PHMMPolicy

LAYOUTS = (1, 2)  # development seeds (0-99); the held-out figure uses 30000-30199


class HiddenPoses(gymnasium.ObservationWrapper):
    """Replaces the task's pose fields (pegs, holes) and both goal vectors by NaN, keeping the robot's own
    state and the target one-hots: what the policy may not read is not there."""

    def __init__(self, env: gymnasium.Env) -> None:
        super().__init__(env)
        robot = env.unwrapped.robot
        n_pegs = env.unwrapped.scene.n_pegs
        self._start = 2 * len(robot.joint_names) + 7 + 3
        self._stop = self._start + 7 * n_pegs + 3 * 3  # peg poses, then hole centres; the one-hots stay

    def observation(self, observation):
        hidden = {key: value.copy() for key, value in observation.items()}
        hidden["observation"][self._start:self._stop] = np.nan
        hidden["achieved_goal"][:] = np.nan
        hidden["desired_goal"][:] = np.nan
        return hidden


@pytest.fixture(scope="module")
def hidden_env():
    env = HiddenPoses(gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta"))
    yield env
    env.close()


def test_the_policy_succeeds_without_the_simulators_poses(hidden_env):
    policy = PHMMPolicy(hidden_env)
    for seed in LAYOUTS:
        obs, _ = hidden_env.reset(seed=seed)
        assert np.isnan(obs["observation"]).any() and np.isnan(obs["achieved_goal"]).all()
        result = run_episode(hidden_env, policy, seed)
        assert result.success, result
        deviations = policy.path_deviations()
        assert set(deviations) >= {"approach", "move"}
        assert all(d < 0.01 for d in deviations.values()), deviations  # the hand followed what was synthesised


def test_a_hand_that_ends_its_carry_off_the_hole_lines_the_peg_up_before_letting_go():
    """Welded legs, validation layout 71026: the carry ended with the held peg's bottom, as the hand's
    measured pose carries it, 4.5 mm off the hole, and the peg fell beside it. The policy now shifts
    the hand by that error before it opens, and never sees the peg to do so."""
    env = HiddenPoses(gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta", robot="fixed_legs"))
    try:
        policy = PHMMPolicy(env)
        obs, info = env.reset(seed=71026)
        policy.reset(obs, info)
        phases, released_at = [], None
        while not (policy.done or policy.failure) and len(phases) < 600:
            action = policy(obs)
            phases.append(policy.phase.name)
            if policy.phase.name == "RELEASE" and released_at is None:
                released_at = policy._held_bottom()[:2] - policy.move_bottom_target()[:2]
            obs, _, terminated, truncated, info = env.step(action)
            if info["is_success"] or terminated or truncated:
                break
        assert "ALIGN" in phases and policy.corrections >= 1
        assert np.linalg.norm(released_at) < 0.0007  # ALIGN_TOLERANCE
        assert info["is_success"]
    finally:
        env.close()


def test_what_it_located_is_where_the_simulator_has_it():
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    try:
        policy = PHMMPolicy(env)
        obs, info = env.reset(seed=LAYOUTS[0])
        policy.reset(obs, info)
        truth = env.get_wrapper_attr("parse_observation")(obs)
        located = policy.located()
        assert np.linalg.norm(located["peg"] - truth["peg_positions"][truth["target_peg"]]) < 0.002
        assert np.linalg.norm(located["hole"] - truth["hole_positions"][truth["target_hole"]]) < 0.002
        figure = policy.figure()
        assert figure.shape == (720, 960, 3) and figure.dtype == np.uint8
    finally:
        env.close()


def test_the_policy_needs_peg_insert_with_ee_delta():
    env = gymnasium.make("hoap_actions/PegInsert-v0")
    with pytest.raises(InvalidInputError, match="ee_delta"):
        PHMMPolicy(env)
    env.close()
    env = gymnasium.make("hoap_actions/Reach-v1", control_mode="ee_delta")
    with pytest.raises(InvalidInputError, match="PegInsert"):
        PHMMPolicy(env)
    env.close()


def test_parallel_comparison_gives_the_serial_results():
    policies = {"scripted": ("scripted", {})}
    serial = compare_policies("hoap_actions/PegInsert-v0", policies, [5, 6], workers=1)["scripted"]
    parallel = compare_policies("hoap_actions/PegInsert-v0", policies, [5, 6], workers=2)["scripted"]
    assert [(r.seed, r.reason, r.steps) for r in serial] == [(r.seed, r.reason, r.steps) for r in parallel]


@pytest.mark.parametrize("successes, n", [(0, 10), (95, 100), (190, 200), (200, 200)])
def test_wilson_interval_matches_scipy(successes, n):
    from scipy.stats import binomtest

    expected = binomtest(successes, n).proportion_ci(confidence_level=0.95, method="wilson")
    np.testing.assert_allclose(wilson_interval(successes, n), (expected.low, expected.high), atol=1e-6)


def _trace(env, policy, seed, steps):
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info)
    observations = []
    for _ in range(steps):
        obs, *_ = env.step(policy(obs))
        observations.append(obs["observation"])
    return np.array(observations)


def test_an_episode_does_not_depend_on_what_the_env_did_before():
    """Seed 25's PHMM episode in a fresh env against the same after another episode: the first
    episode of a fresh env used to differ from step 193 on (the broad phase's first run)."""
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    try:
        policy = PHMMPolicy(env)
        first = _trace(env, policy, 25, 200)
        _trace(env, policy, 24, 20)
        np.testing.assert_array_equal(_trace(env, policy, 25, 200), first)
    finally:
        env.close()


def test_models_come_from_a_directory_too(tmp_path):
    from hoap_actions.models.shipped import default_models_path

    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    try:
        policy = PHMMPolicy(env, models=default_models_path())
        assert policy.paths.move_id in policy.paths.models.actions_
        with pytest.raises(HoapActionsError, match="no-such-models"):
            PHMMPolicy(env, models=tmp_path / "no-such-models")
    finally:
        env.close()


@pytest.mark.slow
def test_the_policy_on_100_unseen_layouts():
    """A regression guard for the held-out figure (benchmarks/policy_comparison.py: 99.0 % on 30000-30199):
    seeds 2000-2099, never used while the policy was developed, at the issue's goal of 95 %."""
    env = gymnasium.make("hoap_actions/PegInsert-v0", control_mode="ee_delta")
    try:
        policy = PHMMPolicy(env)
        results = [run_episode(env, policy, seed) for seed in range(2000, 2100)]
    finally:
        env.close()
    assert not any(r.reason == "fell" for r in results)
    assert np.mean([r.success for r in results]) >= 0.95, [(r.seed, r.reason) for r in results if not r.success]
